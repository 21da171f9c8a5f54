"""Workpiece error maps and residual plots.

Importing this package does not import pyvista or matplotlib: they are imported by the functions
that draw. Public names:

* :func:`program_error_map` -> :class:`SurfaceMap`: the surface a program cuts and the predicted
  deviation along its normal, before and after compensation (numpy/scipy only).
* :func:`render_error_map`: PNG (pyvista off-screen, matplotlib as fallback) and .vtp for ParaView.
* :func:`write_vtp`: the .vtp alone.
* :func:`render_residuals`: residual versus position before and after a model extension (diagnose).
"""
from .surface import ProgramPoints, SurfaceMap, program_error_map, read_program_points

__all__ = ["ProgramPoints", "SurfaceMap", "program_error_map", "read_program_points",
           "render_error_map", "write_vtp", "render_residuals", "RenderResult"]


def render_error_map(*args, **kwargs):
    from .render import render_error_map as f
    return f(*args, **kwargs)


def write_vtp(*args, **kwargs):
    from .render import write_vtp as f
    return f(*args, **kwargs)


def render_residuals(*args, **kwargs):
    from .residuals import render_residuals as f
    return f(*args, **kwargs)


def __getattr__(name):
    if name == "RenderResult":
        from .render import RenderResult
        return RenderResult
    raise AttributeError(name)
