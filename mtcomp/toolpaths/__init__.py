"""Toolpaths: G-code in and out (SPEC section 4), test-part programs, inverse kinematics.

Public API (see docs/toolpaths.md):

* :func:`iter_segment_chunks`, :class:`SegmentChunk`: a program streamed as straight segments.
* :func:`write_corrected`: the program written back with corrected (or nominal) coordinates.
* :func:`read_program`, :class:`Program`, :class:`MotionBlock`: a small program in memory.
"""
from .gcode import (MotionBlock, ModalState, Program, SegmentChunk, iter_segment_chunks,
                    read_program, tokenize, write_corrected)

__all__ = ["MotionBlock", "ModalState", "Program", "SegmentChunk", "iter_segment_chunks",
           "read_program", "tokenize", "write_corrected"]
