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
from .inverse import fit_rotary_travel, inverse_kinematics
from .parts import (write_bowl_program, write_circle_program, write_cone_frustum_program,
                    write_three_sphere_program)

__all__ = ["MotionBlock", "ModalState", "Program", "SegmentChunk", "iter_segment_chunks",
           "read_program", "tokenize", "write_corrected", "fit_rotary_travel", "inverse_kinematics",
           "write_bowl_program", "write_circle_program", "write_cone_frustum_program",
           "write_three_sphere_program"]
