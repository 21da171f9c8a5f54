"""toolpaths"""
