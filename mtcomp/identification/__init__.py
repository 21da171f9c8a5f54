"""Identification: fitting error models to measurements, and standard evaluations (ISO 230-2)."""
