"""Helpers for image tests of the error map: a deterministic synthetic map and a reference image.

``python tests/viz_reference.py OUT.png`` renders the reference image that tests/test_viz_render.py
compares against (run it after an intended change of the picture, then look at the PNG and commit it).
"""
from __future__ import annotations

import sys

import numpy as np

from mtcomp.viz.surface import SurfaceMap, triangulate_xy, vertex_normals

#: how the reference image is rendered (small, so the PNG stays well under 100 kB)
REFERENCE_KWARGS = {"window_size": (600, 320), "vtp": False, "backend": "pyvista"}


def synthetic_surface_map(n: int = 25) -> SurfaceMap:
    """A 60 x 60 mm dish (z = r^2/400 mm) on an n x n grid with an analytic deviation field (mm):
    before = (0, 0, 4 um * cos(pi x/60) * y/30 + 1 um), after = 0.25 * before, no random numbers."""
    x, y = np.meshgrid(np.linspace(-30.0, 30.0, n), np.linspace(-30.0, 30.0, n))
    x, y = x.ravel(), y.ravel()
    tips = np.column_stack([x, y, (x ** 2 + y ** 2) / 400.0])
    tri = triangulate_xy(tips)
    normals = vertex_normals(tips, tri, np.tile([0.0, 0.0, 1.0], (tips.shape[0], 1)))
    dz = 4e-3 * np.cos(np.pi * x / 60.0) * y / 30.0 + 1e-3
    before = np.column_stack([np.zeros_like(dz), np.zeros_like(dz), dz])
    return SurfaceMap(tips.copy(), tips, normals, tri, np.arange(tips.shape[0]) + 1, before,
                      0.25 * before, "synthetic", "synthetic")


def main(argv=None) -> int:
    from mtcomp.viz.render import render_error_map
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        sys.stderr.write("usage: python tests/viz_reference.py OUT.png\n")
        return 2
    res = render_error_map(synthetic_surface_map(), argv[0], **REFERENCE_KWARGS)
    print(f"wrote {res.png} ({res.backend})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
