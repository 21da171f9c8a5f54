"""Rendering the error map off-screen: image against a stored reference, the .vtp, the CLI, and that
importing mtcomp does not import pyvista."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from oracles.image_compare import image_difference
from viz_reference import REFERENCE_KWARGS, synthetic_surface_map

DATA = Path(__file__).resolve().parent / "data"
REFERENCE = DATA / "viz_error_map_ref.png"
#: at most this fraction of pixels may differ visibly from the reference (anti-aliasing, fonts)
TOLERANCE = 0.01

pv = pytest.importorskip("pyvista")


def render(smap, path, **kw):
    from mtcomp.viz import render_error_map
    return render_error_map(smap, path, **{**REFERENCE_KWARGS, **kw})


def test_importing_mtcomp_does_not_import_pyvista():
    code = ("import sys, mtcomp, mtcomp.models, mtcomp.viz, mtcomp.viz.surface, mtcomp.cli, "
            "mtcomp.commands.render, mtcomp.demo, mtcomp.commands.demo; mtcomp.cli.build_parser(); "
            "bad = [m for m in ('pyvista', 'vtk', 'vtkmodules', 'matplotlib') if m in sys.modules]; "
            "print(bad); sys.exit(1 if bad else 0)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr


def test_map_matches_the_reference_image(tmp_path):
    res = render(synthetic_surface_map(), tmp_path / "map.png")
    assert res.backend == "pyvista"
    # largest |dn|: 5 um along z at (0, 30), times n_z = 1/sqrt(1 + 0.15^2) of the dish there
    assert res.clim[1] == pytest.approx(5.0 / np.sqrt(1 + 0.15 ** 2), rel=0, abs=0.01)
    assert res.clim[0] == -res.clim[1]
    assert REFERENCE.stat().st_size < 100_000
    assert image_difference(res.png, REFERENCE) <= TOLERANCE


def test_comparison_fails_when_the_colour_scale_changes(tmp_path):
    lo, hi = render(synthetic_surface_map(), tmp_path / "a.png").clim
    res = render(synthetic_surface_map(), tmp_path / "map.png", clim=(0.7 * lo, 0.7 * hi))
    # the part fills about a third of the picture (axes, ticks and colour bar around it)
    assert image_difference(res.png, REFERENCE) > 2 * TOLERANCE


def test_comparison_fails_when_the_data_change(tmp_path):
    smap = synthetic_surface_map()
    x, y = smap.tips[:, 0], smap.tips[:, 1]
    bump = 3e-3 * np.exp(-((x - 10) ** 2 + (y + 10) ** 2) / 150.0)  # 3 um bump, ~20 mm wide
    smap.dev_before[:, 2] += bump
    smap.dev_after[:, 2] += bump
    clim = render(synthetic_surface_map(), tmp_path / "a.png").clim  # the reference's scale
    res = render(smap, tmp_path / "map.png", clim=clim)
    assert image_difference(res.png, REFERENCE) > 2 * TOLERANCE


def test_image_difference_hand_cases(tmp_path):
    from PIL import Image
    a = np.full((10, 20, 3), 255, np.uint8)
    b = a.copy()
    b[0:2, 0:5] = (255, 200, 255)  # 10 of 200 pixels, 55 levels off in green
    b[5, 5] = (250, 250, 250)      # 5 levels: below the threshold
    Image.fromarray(a).save(tmp_path / "a.png")
    Image.fromarray(b).save(tmp_path / "b.png")
    Image.fromarray(a[:, :10]).save(tmp_path / "c.png")
    assert image_difference(tmp_path / "a.png", tmp_path / "b.png") == pytest.approx(0.05, abs=1e-12)
    assert image_difference(tmp_path / "a.png", tmp_path / "a.png") == 0.0
    assert image_difference(tmp_path / "a.png", tmp_path / "c.png") == 1.0


def test_vtp_holds_the_map(tmp_path):
    smap = synthetic_surface_map(n=7)
    res = render(smap, tmp_path / "m.png", vtp=True, glyphs=True)
    assert res.vtp == tmp_path / "m.vtp"
    back = pv.read(res.vtp)
    np.testing.assert_allclose(back.points, smap.points, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.point_data["dn_before_um"], smap.dn_before_um, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.point_data["dn_after_um"], smap.dn_after_um, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.point_data["dev_before_um"], 1e3 * smap.dev_before, rtol=0,
                               atol=1e-12)
    faces = back.faces.reshape(-1, 4)
    np.testing.assert_array_equal(faces[:, 0], 3)
    np.testing.assert_array_equal(faces[:, 1:], smap.triangles)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.png", "m.vtp"]  # no temporary files left


def test_matplotlib_fallback_uses_the_same_colour_scale(tmp_path):
    """Top view: the pixel colour at the map's hottest point is the top of the colour map."""
    from matplotlib import colormaps
    from PIL import Image
    smap = synthetic_surface_map()
    res = render(smap, tmp_path / "m.png", backend="matplotlib", window_size=(800, 400))
    assert res.backend == "matplotlib"
    img = np.asarray(Image.open(res.png).convert("RGB"), dtype=float)
    top = np.array(colormaps["coolwarm"](1.0)[:3]) * 255
    bottom = np.array(colormaps["coolwarm"](0.0)[:3]) * 255
    dist_top = np.linalg.norm(img - top, axis=2).min()
    dist_bottom = np.linalg.norm(img - bottom, axis=2).min()
    assert dist_top < 12 and dist_bottom < 12  # both ends of the scale are drawn (map and bar)


def test_residual_plot_before_and_after(tmp_path):
    from PIL import Image

    from mtcomp.viz import render_residuals
    x = np.linspace(-300.0, 300.0, 61)
    d = np.where(np.arange(61) % 2 == 0, 1, -1)
    before = 3.0 * d + 0.1 * np.sin(x / 50.0)        # a backlash step of 6 um, +-3 by direction
    after = 0.1 * np.sin(x / 50.0)
    stats = render_residuals(x, before, after, tmp_path / "res.png", groups=np.where(d > 0, "up", "down"),
                             xlabel="X (mm)")
    assert stats["before"]["max"] == pytest.approx(np.max(np.abs(before)), rel=1e-12)
    assert stats["before"]["rms"] == pytest.approx(np.sqrt(np.mean(before ** 2)), rel=1e-12)
    assert stats["after"]["rms"] == pytest.approx(np.sqrt(np.mean(after ** 2)), rel=1e-12)
    img = np.asarray(Image.open(tmp_path / "res.png").convert("RGB"), dtype=int)
    assert img.shape == (500, 1200, 3)
    # the two groups are drawn in tab10 blue and orange, in both panels
    for colour in ((31, 119, 180), (255, 127, 14)):
        hit = np.all(np.abs(img - np.array(colour)) <= 3, axis=2)
        assert hit[:, :600].sum() > 50 and hit[:, 600:].sum() > 50
    with pytest.raises(ValueError, match="one value per observation"):
        render_residuals(x, before[:-1], after, tmp_path / "bad.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res.png"]


def _plane_case(tmp_path):
    from mtcomp import load_machine
    from mtcomp.models import ErrorModel, FittedModel, save_model
    machine = load_machine("xfyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(machine))
    for name, value in {"EXX_1": 40.0, "EZX_2": -30.0, "C0Y": 50.0}.items():
        fitted.params.set_file_value(name, value)
    save_model(tmp_path / "MODEL.json", fitted)
    lines = ["G21 G90", "G0 Z5", "F800"]
    for i, y in enumerate(np.linspace(0.0, 30.0, 7)):
        xs = np.linspace(0.0, 30.0, 7)[:: 1 if i % 2 == 0 else -1]
        lines += [f"G1 X{x:.4f} Y{y:.4f} Z{-0.05 * x:.4f}" for x in xs]
    (tmp_path / "p.nc").write_text("\n".join(lines) + "\n")
    comp = []                                   # the 'compensated' program: X + 2 um on every cut
    for ln in lines:
        if ln.startswith("G1 X"):
            x = float(ln.split()[1][1:])
            ln = ln.replace(ln.split()[1], f"X{x + 0.002:.4f}")
        comp.append(ln)
    (tmp_path / "c.nc").write_text("\n".join(comp) + "\n")
    return machine, fitted


def test_render_command_writes_both_files_and_prints_the_figures(tmp_path, capsys):
    from mtcomp.cli import main
    from mtcomp.viz.surface import program_error_map
    machine, fitted = _plane_case(tmp_path)
    rc = main(["render", "xfyz", str(tmp_path / "MODEL.json"), str(tmp_path / "p.nc"),
               "--compensated", str(tmp_path / "c.nc"), "-o", str(tmp_path / "map.png"),
               "--size", "500x300"])
    out = capsys.readouterr().out
    assert rc == 0
    smap = program_error_map(machine, fitted, tmp_path / "p.nc", tmp_path / "c.nc")
    st = smap.stats()
    assert f"before: RMS {st['rms_before_um']:.3f} um, max {st['max_before_um']:.3f} um" in out
    assert f"after:  RMS {st['rms_after_um']:.3f} um, max {st['max_after_um']:.3f} um" in out
    assert "surface: 49 points" in out
    back = pv.read(tmp_path / "map.vtp")
    np.testing.assert_allclose(back.point_data["dn_after_um"], smap.dn_after_um, rtol=0, atol=1e-12)
    from PIL import Image
    assert Image.open(tmp_path / "map.png").size == (500, 300)


@pytest.mark.parametrize("program, rc, message", [
    # set-up lines only (it once crashed in pyvista after writing the PNG): refused, nothing written
    ("G21 G90\n(no motion)\nM30\n", 2, "no motion block"),
    # a move beyond the travel, in the program's coordinates (render knows no work offsets): drawn,
    # and the user told
    ("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F500\nG1 X450\nG1 Y20\nM30\n", 0,
     "prog.nc:4: X 450.0000 mm is outside the travel of axis X (-400 .. 400 mm)"),
])
def test_render_a_program_it_cannot_draw_or_the_machine_cannot_run(tmp_path, capsys, program, rc, message):
    from mtcomp.cli import main
    _plane_case(tmp_path)
    (tmp_path / "prog.nc").write_text(program)
    before = sorted(p.name for p in tmp_path.iterdir())
    got = main(["render", "xfyz", str(tmp_path / "MODEL.json"), str(tmp_path / "prog.nc"), "-o",
                str(tmp_path / "map.png"), "--backend", "matplotlib", "--size", "300x150"])
    err = capsys.readouterr().err
    assert got == rc and err.count("\n") == 1 and message in err and "Traceback" not in err
    assert ("note:" in err) == (rc == 0)
    written = sorted(set(p.name for p in tmp_path.iterdir()) - set(before))
    assert written == ([] if rc else ["map.png", "map.vtp"])


@pytest.mark.parametrize("args, message", [
    (["--compensated", "{d}/MODEL.json"], "MODEL.json"),      # not G-code
    (["--size", "10x10"], "--size"),
    (["--tool-radius-mm", "-1"], "--tool-radius-mm"),
    (["--compensated", "{d}/far.nc"], "not a compensated version"),
])
def test_render_command_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, args, message):
    from mtcomp.cli import main
    _plane_case(tmp_path)
    text = (tmp_path / "p.nc").read_text().replace("G1 X", "G1 X1")   # X shifted by >= 10 mm
    (tmp_path / "far.nc").write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    rc = main(["render", "xfyz", str(tmp_path / "MODEL.json"), str(tmp_path / "p.nc"), "-o",
               str(tmp_path / "map.png")] + [a.format(d=tmp_path) for a in args])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
