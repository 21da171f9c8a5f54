"""Hand-written NC programs for the error-map tests: a 2.5-D pocket and a part with walls.

``python tests/viz_parts.py pocket|walls OUT.nc [LEVELS]`` writes one (for profiling and looking at
the map by hand).
"""
from __future__ import annotations

import sys

import numpy as np


def pocket_program(levels: int = 6, step_down_mm: float = 1.0, width_mm: float = 60.0,
                   height_mm: float = 40.0, stepover_mm: float = 2.0, helix_radius_mm: float = 3.0,
                   origin=(100.0, 50.0)) -> str:
    """A rectangular pocket cut in ``levels`` step-downs: at each level a helical entry (G3 with a Z
    word: two turns per step-down, so the reader's chords put many cutting points between the
    levels), a zig-zag clearing along X and a finishing pass along the wall, corners as G3 arcs.
    The pocket is centred on ``origin`` (mm); its floor is at -levels * step_down_mm."""
    x0, y0 = origin
    hx, hy = 0.5 * width_mm, 0.5 * height_mm
    r = 2.0                                       # corner radius of the finishing pass
    out = ["%", "(2.5-D POCKET TEST PART)", "G21 G90 G17", "G0 Z5",
           f"G0 X{x0 + helix_radius_mm:.4f} Y{y0:.4f}", "G1 Z0 F300"]
    for k in range(1, levels + 1):
        z = -k * step_down_mm
        z_half = z + 0.5 * step_down_mm
        out.append(f"G3 X{x0 + helix_radius_mm:.4f} Y{y0:.4f} Z{z_half:.4f} I{-helix_radius_mm:.4f} J0 F300")
        out.append(f"G3 X{x0 + helix_radius_mm:.4f} Y{y0:.4f} Z{z:.4f} I{-helix_radius_mm:.4f} J0")
        ys = np.arange(-hy + r + stepover_mm, hy - r - stepover_mm + 1e-9, stepover_mm)
        out.append(f"G1 X{x0 - hx + r + stepover_mm:.4f} Y{y0 + ys[0]:.4f} F800")
        for i, y in enumerate(ys):
            xa, xb = x0 - hx + r + stepover_mm, x0 + hx - r - stepover_mm
            if i % 2:
                xa, xb = xb, xa
            out.append(f"G1 X{xa:.4f} Y{y0 + y:.4f}")
            out.append(f"X{xb:.4f}")
        # finishing pass, counter-clockwise along the wall (climb milling in a pocket)
        out += [f"G1 X{x0 - hx + r:.4f} Y{y0 - hy + r:.4f}",
                f"G1 Y{y0 - hy:.4f}",
                f"G1 X{x0 + hx - r:.4f}",
                f"G3 X{x0 + hx:.4f} Y{y0 - hy + r:.4f} I0 J{r:.4f}",
                f"G1 Y{y0 + hy - r:.4f}",
                f"G3 X{x0 + hx - r:.4f} Y{y0 + hy:.4f} I{-r:.4f} J0",
                f"G1 X{x0 - hx + r:.4f}",
                f"G3 X{x0 - hx:.4f} Y{y0 + hy - r:.4f} I0 J{-r:.4f}",
                f"G1 Y{y0 - hy + r:.4f}",
                f"G3 X{x0 - hx + r:.4f} Y{y0 - hy:.4f} I{r:.4f} J0",
                f"G1 X{x0 + helix_radius_mm:.4f} Y{y0:.4f}"]
    out += ["G0 Z5", "M30", "%"]
    return "\n".join(out) + "\n"


def walls_program(levels: int = 8, step_down_mm: float = 0.5, side_mm: float = 30.0,
                  raster_mm: float = 1.0, origin=(100.0, 50.0)) -> str:
    """A square boss with vertical walls on a floor, cut as a 3-D finishing program would: the top
    face and the floor raster-cut along X (the floor a ring around the boss), the walls by
    waterline passes every ``step_down_mm`` with points every ``raster_mm`` along them. Every
    cutting point lies on one of levels + 1 heights; the walls are vertical."""
    x0, y0 = origin
    h = 0.5 * side_mm
    floor = -levels * step_down_mm
    out = ["%", "(BOSS WITH WALLS TEST PART)", "G21 G90 G17", "G0 Z5", f"G0 X{x0 - h:.4f} Y{y0 - h:.4f}",
           "G1 Z0 F300"]
    ys = np.arange(-h, h + 1e-9, raster_mm)
    for i, y in enumerate(ys):                                # top face
        xs = np.arange(-h, h + 1e-9, raster_mm)[:: 1 if i % 2 == 0 else -1]
        out += [f"G1 X{x0 + x:.4f} Y{y0 + y:.4f} F800" for x in xs]
    for k in range(1, levels + 1):                            # waterline walls
        z = -k * step_down_mm
        # the wall contour, closed; its points shifted along it from level to level, as a CAM's
        # are (they never line up with those of the level above)
        t = np.concatenate([[-h], np.arange(-h + (0.37 * k) % raster_mm + 0.05, h, raster_mm)])
        square = []
        for xs, ys_ in ((t, np.full_like(t, -h)), (np.full_like(t, h), t),
                        (-t, np.full_like(t, h)), (np.full_like(t, -h), -t)):
            square += list(zip(xs, ys_))
        square.append(square[0])
        out.append(f"G1 X{x0 + square[0][0]:.4f} Y{y0 + square[0][1]:.4f} Z{z:.4f}")
        out += [f"G1 X{x0 + x:.4f} Y{y0 + y:.4f}" for x, y in square[1:]]
    out.append("G0 Z5")
    big = h + 10.0
    xs = np.arange(-big, big + 1e-9, raster_mm)
    for i, y in enumerate(np.arange(-big, big + 1e-9, raster_mm)):   # floor around the boss
        # a row beside the boss is cut in two runs, with a retract over it
        runs = [xs] if abs(y) > h + 1e-9 else [xs[xs < -h - 1e-9], xs[xs > h + 1e-9]]
        for run in runs[:: 1 if i % 2 == 0 else -1]:
            run = run[:: 1 if i % 2 == 0 else -1]
            out += ["G0 Z5", f"G0 X{x0 + run[0]:.4f} Y{y0 + y:.4f}", f"G1 Z{floor:.4f} F300"]
            out += [f"G1 X{x0 + x:.4f} Y{y0 + y:.4f} F800" for x in run[1:]]
    out += ["G0 Z5", "M30", "%"]
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    kind, path = sys.argv[1], sys.argv[2]
    levels = int(sys.argv[3]) if len(sys.argv) > 3 else None
    make = {"pocket": pocket_program, "walls": walls_program}[kind]
    with open(path, "w") as f:
        f.write(make() if levels is None else make(levels=levels))
