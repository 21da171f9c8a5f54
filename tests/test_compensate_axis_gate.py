"""compensate corrects the tool axis only where the data determine it: a tool-axis deviation whose
standard error is not known (it moves with a spindle tilt the data leave open) or over the limit is
not corrected (the rotary axes keep their words, in tool centre point mode the tool angles, and the
linear axes alone correct the tip).

Oracles: the model's own deviation at the written positions, evaluated apart from the planner
(:func:`mtcomp.models.deviation`) against the nominal kinematics; a Haas G234 program's words."""
import json

import numpy as np
import pytest

from mtcomp import load_machine
from mtcomp.cli import main
from mtcomp.kinematics import forward
from mtcomp.models import ErrorModel, FittedModel, deviation, save_model
from test_compensate_sd_predict import _plan
from test_toolpaths_tcp_haas import _WORD, G54_FLAG, TCPC


# ------------------------------------------------------------------ the tool axis
def _tilted_b_line(sd_urad, open_spindle):
    """CBFXYZ: C's axis line tilted by A0C = 40 urad (standard error ``sd_urad``); with
    ``open_spindle`` the spindle's tilt B0S is a direction the data left open (held at zero), as
    data taken with one stylus length leave it."""
    m = load_machine("cbfxyz").with_basis("polynomial")
    fitted = FittedModel.zero(ErrorModel(m))
    fitted.params.set_file_value("A0C", 40.0)
    names = ["A0C", "B0S"]
    fitted.uncertainty = {"names": names,
                          "covariance": np.diag([(sd_urad * 1e-6) ** 2, 0.0 if open_spindle else 1e-14]),
                          "undetermined": np.array([[0.0], [1e-5]]) if open_spindle
                          else np.zeros((2, 0))}
    return m, fitted


def _poses():
    b = np.radians([10.0, 20.0, 30.0, 35.0])
    c = np.radians([40.0, 80.0, 120.0, 160.0])
    return np.column_stack([[10.0, 20.0, 30.0, 40.0], [5.0, 0.0, -5.0, -10.0],
                            [-120.0, -121.0, -122.0, -123.0], b, c])


@pytest.mark.parametrize("open_spindle, sd_urad", [(True, 0.5), (False, 8.0)],
                         ids=["undetermined", "over_the_limit"])
def test_a_tool_axis_the_data_do_not_determine_is_not_corrected(open_spindle, sd_urad):
    m, fitted = _tilted_b_line(sd_urad, open_spindle)
    q = _poses()
    res = _plan(fitted, q, datum=np.zeros_like(q))
    p = np.asarray(fitted.params.values, dtype=float)
    before = deviation(fitted.model, q, p)
    # the tilt turns the tool: tens of urad of tool-axis deviation (what main corrected with B, C)
    assert (np.linalg.norm(before[:, 3:], axis=1) * 1e6 > 3.0).all()
    rot = [j for j, a in enumerate(m.axes) if a.is_rotary]
    np.testing.assert_array_equal(res.correction[:, rot], 0.0)     # B and C keep their words
    assert res.axis_left.all() and not res.pinned.any()
    # the tip corrected by X, Y, Z alone: the model at the written positions puts it where the
    # program meant it (to the output grid), the tool axis as it was
    written = deviation(fitted.model, res.corrected, p)
    tip_w, axis_w = forward(m, res.corrected)
    tip_n, axis_n = forward(m, q)
    np.testing.assert_allclose(tip_w + written[:, :3] - tip_n, 0.0, rtol=0, atol=1e-4)
    np.testing.assert_allclose(axis_w + written[:, 3:] - axis_n, before[:, 3:], rtol=0, atol=1e-9)


def test_a_tool_axis_the_data_determine_is_corrected():
    # the control: A0C at 40 +- 0.5 urad, the spindle measured: B and C turn against it
    m, fitted = _tilted_b_line(0.5, open_spindle=False)
    res = _plan(fitted, _poses(), datum=np.zeros((4, 5)))
    assert res.axis_left is None or not res.axis_left.any()
    assert np.abs(res.after_axis).max() * 1e6 < 1.0 < np.abs(res.before_axis).max() * 1e6


def test_a_tool_centre_point_program_keeps_its_tool_angles(tmp_path, capsys):
    # a Haas G234 program on a CAFXYZ trunnion (tests/data/haas), C's line tilted by A0C = 40 +-
    # 0.5 urad and the spindle's tilt B0S left open by the data: the tool angles stay as written,
    # the tip words are corrected, and the summary says so without a figure after for the axis
    fitted = FittedModel.zero(ErrorModel(load_machine("cafxyz").with_basis("polynomial")))
    fitted.params.set_file_value("A0C", 40.0)
    fitted.uncertainty = {"names": ["A0C", "B0S"], "covariance": np.diag([0.5e-6 ** 2, 0.0]),
                          "undetermined": np.array([[0.0], [1e-5]])}
    path, out, js = tmp_path / "M.json", tmp_path / "o.nc", tmp_path / "S.json"
    save_model(path, fitted)
    capsys.readouterr()
    assert main(["compensate", "cafxyz", str(path), str(TCPC), "-o", str(out), "--json", str(js),
                 "--work-offset", G54_FLAG]) == 0
    said = capsys.readouterr().out
    tip_changed = 0
    for a, b in zip(TCPC.read_text().splitlines(), out.read_text().splitlines()):
        wa, wb = dict(_WORD.findall(a)), dict(_WORD.findall(b))
        assert {k: wb[k] for k in wb if k in "AC"} == {k: wa[k] for k in wa if k in "AC"}, (a, b)
        tip_changed += any(wa.get(k) != wb.get(k) for k in "XYZ")
    assert tip_changed >= 8
    summary = json.loads(js.read_text())
    assert summary["tool_axis_not_corrected"]["blocks"] >= 8
    assert summary["max_axis_after_urad"] is None
    assert "predicted tool-axis deviation: max" in said and "not corrected (below)" in said
    assert "with the tool axis not corrected" in said
