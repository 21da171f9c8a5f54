import math

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.cli import main
from mtcomp.kinematics import forward
from mtcomp.machine import machine_from_dict, parse_topology


def test_topology_chains():
    assert parse_topology("XFYZ") == (("X",), ("Y", "Z"))
    assert parse_topology("CAFXYZ") == (("A", "C"), ("X", "Y", "Z"))
    assert parse_topology("cbfxyz") == (("B", "C"), ("X", "Y", "Z"))


@pytest.mark.parametrize("bad, msg", [
    ("XYZ", "exactly one 'F'"), ("QFYZ", "unknown letter 'Q'"), ("XFXZ", "names an axis twice"),
])
def test_bad_topology(bad, msg):
    with pytest.raises(InputError, match=msg):
        parse_topology(bad)


def test_builtins_load():
    m = load_machine("cafxyz")
    assert m.axis_names == ("X", "Y", "Z", "A", "C")
    assert m.axis("C").axis_point == (0.0, 0.0, 0.0)
    assert m.axis("A").travel == pytest.approx((math.radians(-120), math.radians(120)), rel=1e-15, abs=0)


def _write(tmp_path, text):
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, msg", [
    ('topology = "XFYZ"\n[axes.X]\ntravel_mm=[0,1]\n[axes.Y]\ntravel_mm=[0,1]\n', "axis Z .* has no"),
    ('topology = "XFYZ"\n[axes.X]\n[axes.Y]\ntravel_mm=[0,1]\n[axes.Z]\ntravel_mm=[0,1]\n', "without travel_mm"),
    ('topology = "CFXYZ"\n[axes.X]\ntravel_mm=[0,1]\n[axes.Y]\ntravel_mm=[0,1]\n[axes.Z]\ntravel_mm=[0,1]\n'
     '[axes.C]\ntravel_deg=[0,360]\n', "without axis_point_mm"),
    ('topology = "XFYZ"\n[axes.X]\ntravel_mm=[1,0]\n[axes.Y]\ntravel_mm=[0,1]\n[axes.Z]\ntravel_mm=[0,1]\n', "below upper"),
    ('topology = "XFYW"\n', "unknown letter 'W'"),
    ('topology = "XFYZ"\n[axes', "not valid TOML"),
])
def test_bad_machine_files(tmp_path, capsys, text, msg):
    p = _write(tmp_path, text)
    with pytest.raises(InputError, match=msg):
        load_machine(p)


def test_cli_machines_and_bad_machine(tmp_path, capsys):
    assert main(["machines"]) == 0
    out = capsys.readouterr().out
    assert "xfyz" in out and "CAFXYZ" in out and "CBFXYZ" in out
    # a bad machine file on any command: exit 2, one line naming the file and the problem, no output
    bad = _write(tmp_path, 'topology = "XFYQ"\n')
    data = tmp_path / "d.csv"
    data.write_text("x_mm,y_mm,z_mm,dx_um\n1,2,3,0.5\n")
    out_model = tmp_path / "m.json"
    assert main(["identify", str(bad), str(data), "-o", str(out_model)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "m.toml" in err and "unknown letter 'Q'" in err
    assert not out_model.exists()


def test_output_path_refuses_the_input_itself_a_symlink_or_a_hard_link(tmp_path):
    import os

    from mtcomp.io.atomic import check_output_path
    inp = tmp_path / "in.nc"
    inp.write_text("G1 X1\n")
    (tmp_path / "sym.nc").symlink_to(inp)
    os.link(inp, tmp_path / "hard.nc")
    for out in (inp, tmp_path / "sym.nc", tmp_path / "hard.nc"):
        with pytest.raises(InputError, match="overwrite an input"):
            check_output_path(out, [inp])
    assert check_output_path(tmp_path / "new.nc", [inp]) == tmp_path / "new.nc"
    with pytest.raises(InputError, match="does not exist"):
        check_output_path(tmp_path / "nofolder" / "x.nc", [inp])


def test_nominal_forward_three_axis():
    m = load_machine("xfyz")
    q = np.array([[10.0, -20.0, 30.0], [0.0, 0.0, 0.0]])
    tip, axis = forward(m, q)
    np.testing.assert_allclose(tip, q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(axis, [[0, 0, 1], [0, 0, 1]], rtol=0, atol=1e-15)


def test_nominal_forward_cafxyz_hand_case():
    # A = 90 deg about X through (0,0,-100); C = 90 deg about Z through the origin. The tool tip
    # at machine (0, 0, 0): in the A-rotated table frame the point is R_A^T (p - a) + a.
    m = load_machine("cafxyz")
    q = np.array([[0.0, 0.0, 0.0, math.pi / 2, math.pi / 2]])
    tip, axis = forward(m, q)
    a = np.array([0, 0, -100.0])
    RA = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0.0]])  # Rx(90)
    p_a = RA.T @ (np.zeros(3) - a) + a  # = (0, 100, -100)
    RC = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])  # Rz(90)
    np.testing.assert_allclose(tip[0], RC.T @ p_a, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tip[0], [100.0, 0.0, -100.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(axis[0], RC.T @ RA.T @ [0, 0, 1.0], rtol=0, atol=1e-15)


def test_the_machine_file_example_in_the_docs_loads(tmp_path):
    """docs/machines.md shows a whole machine file: it must be one mtcomp accepts, with the values
    the page says."""
    import re
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "docs" / "machines.md").read_text()
    block = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    (tmp_path / "m.toml").write_text(block)
    m = load_machine(str(tmp_path / "m.toml"))
    assert m.topology == "CAFXYZ" and m.tool_length == 100.0 and m.units == "mm"
    assert m.axis("C").error_motion_order == 5 and m.axis("A").error_motion_order == 0
    assert m.compensation["max_step_um"] == 5.0


def test_rigid_inverse_is_the_inverse_of_the_nominal_table_chain():
    from mtcomp.kinematics import rigid_inverse, wp2bed
    machine = load_machine("cafxyz")
    rng = np.random.default_rng(3)
    lo, hi = machine.travel_bounds()
    q = rng.uniform(np.maximum(lo, -7.0), np.minimum(hi, 7.0), (200, machine.n_axes))
    T = wp2bed(machine, q)
    np.testing.assert_allclose(rigid_inverse(T) @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)
    np.testing.assert_allclose(rigid_inverse(T), np.linalg.inv(T), atol=1e-10)
