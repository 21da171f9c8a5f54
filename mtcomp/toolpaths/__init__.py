"""Toolpaths: G-code in and out (docs/toolpaths.md), test-part programs, inverse kinematics.

Public API (see docs/toolpaths.md):

* :func:`iter_segment_chunks`, :class:`SegmentChunk`: a program streamed as straight segments.
* :func:`write_corrected`: the program written back with corrected (or nominal) coordinates.
* :mod:`.offsets`: work offsets and tool lengths (:func:`~.offsets.load_setup`).
* :func:`read_program`, :class:`Program`, :class:`MotionBlock`: a small program in memory.
* :mod:`.parts`: the bowl of Qi and Yang (2016), ISO 230-4 circles, the three-sphere test of Tan et al.
  (2026), a cone frustum.
* :func:`inverse_kinematics`, :func:`fit_rotary_travel`: tool pose -> axis positions.
"""
from .gcode import (MotionBlock, ModalState, Program, SegmentChunk, iter_segment_chunks,
                    read_program, tokenize, write_corrected)

#: names of the test-part programs and of the inverse kinematics, imported on first use (reading
#: and writing a program needs neither)
_LAZY = {"fit_rotary_travel": "inverse", "inverse_kinematics": "inverse",
         "write_bowl_program": "parts", "write_circle_program": "parts",
         "write_cone_frustum_program": "parts", "write_three_sphere_program": "parts"}

__all__ = ["MotionBlock", "ModalState", "Program", "SegmentChunk", "iter_segment_chunks",
           "read_program", "tokenize", "write_corrected", "fit_rotary_travel", "inverse_kinematics",
           "write_bowl_program", "write_circle_program", "write_cone_frustum_program",
           "write_three_sphere_program"]


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
