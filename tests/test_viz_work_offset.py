"""render with the program's work offset: the map of a program written about its own zero and
placed on the table by --work-offset is the map of the same program written in machine coordinates
(before and after compensation, each compensated by compensate with the same placement). It was
drawn with the model evaluated at the program's coordinates: a drilling program compensated with
its offset showed an 'after' map worse than before."""
import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.toolpaths.parts import write_bowl_program
from test_compensate_cli import _model

pv = pytest.importorskip("pyvista")
ORIGIN = (120.0, 60.0, -80.0)


def test_a_work_offset_maps_as_the_same_program_in_machine_coordinates(tmp_path, capsys):
    _, _, model = _model(tmp_path, "xfyz", seed=5, scale=3.0)
    local, placed = tmp_path / "local.nc", tmp_path / "placed.nc"
    write_bowl_program(local, stepover_mm=4.0, step_mm=4.0, origin_mm=(0.0, 0.0, 0.0))
    write_bowl_program(placed, stepover_mm=4.0, step_mm=4.0, origin_mm=ORIGIN)
    offset = "G54=X{},Y{},Z{}".format(*ORIGIN)
    maps = {}
    for name, prog, extra in (("local", local, ["--work-offset", offset]), ("placed", placed, [])):
        rep = tmp_path / f"{name}.csv"
        assert main(["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / f"{name}_c.nc"),
                     "--report", str(rep), "--quiet"] + extra) == 0
        assert main(["render", "xfyz", str(model), str(prog), "--report", str(rep), "-o",
                     str(tmp_path / f"{name}.png"), "--backend", "matplotlib"] + extra) == 0
        maps[name] = pv.read(tmp_path / f"{name}.vtp")
    capsys.readouterr()
    # the same deviation vectors at every point, up to one constant: the deviation at each map's
    # datum (the bowl's origin on the table, and the machine zero of the program in machine
    # coordinates), which is all a placement may change
    # (after compensation up to the output's rounding too: 0.1 um steps of the written words)
    for arr, tol in (("dev_before_um", 2e-3), ("dev_after_um", 0.12)):
        a = np.asarray(maps["local"].point_data[arr])
        b = np.asarray(maps["placed"].point_data[arr])
        assert a.shape == b.shape and a.shape[1] == 3
        diff = a - b
        np.testing.assert_allclose(diff, np.broadcast_to(diff.mean(axis=0), diff.shape), rtol=0,
                                   atol=tol, err_msg=arr)
    after = np.asarray(maps["local"].point_data["dn_after_um"])
    before = np.asarray(maps["local"].point_data["dn_before_um"])
    assert np.sqrt(np.mean(after ** 2)) < 0.2 * np.sqrt(np.mean(before ** 2))
