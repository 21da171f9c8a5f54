"""`mtcomp diagnose` end to end: REPORT.json has the keys of SPEC 6, MODEL.json is the extended model
(checked by evaluating it independently, through load_model and the measurement models, on the
same files), bad input gives exit 2, one line, and no output file."""
import json

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.diagnose.hidden import hidden_case
from mtcomp.measurement.readings import measurement_model
from mtcomp.measurement.readings_extra import drift_context
from mtcomp.measurement.files import read_measurements
from mtcomp.machine import load_machine
from mtcomp.models import load_model


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    folder = tmp_path_factory.mktemp("campaign")
    case = hidden_case(41, ["backlash"], machine="xfyz")
    return case, [str(p) for p in case.write(folder)]


def test_report_and_extended_model(campaign, tmp_path, capsys):
    case, files = campaign
    report, model = tmp_path / "report.json", tmp_path / "model.json"
    assert main(["diagnose", "xfyz", *files, "--json", str(report), "-o", str(model), "-q"]) == 0
    out = capsys.readouterr().out
    assert "verdict: explained" in out and "evidence:" in out
    def no_nan(token):
        raise AssertionError(f"REPORT.json holds {token}")
    rep = json.loads(report.read_text(), parse_constant=no_nan)
    assert rep["verdict"] == "explained"
    for key in ("verdict", "noise_um", "base", "findings", "final"):
        assert key in rep
    for key in ("n_params", "rms_um", "heldout_rms_um"):
        assert key in rep["base"] and key in rep["final"]
    (f,) = rep["findings"]
    assert set(f) >= {"effect", "axis", "params", "evidence", "heldout_rms_before_um",
                      "heldout_rms_after_um"}
    h = case.effects[0]
    assert (f["effect"], f["axis"]) == (h["effect"], h["axis"])
    assert f["params"]["magnitude_um"] == pytest.approx(h["params"][f"BL_{h['axis']}"] * 1e3, rel=0.05)
    assert rep["noise_um"] == pytest.approx(case.noise_um, rel=0.1)
    assert rep["final"]["n_params"] == rep["base"]["n_params"] + 1

    # MODEL.json: the base model plus the backlash term, evaluated independently on every file;
    # its residual is the final rms of the report (the report's fit is linearised: tiny difference)
    fitted = load_model(model, load_machine("xfyz"))
    assert [t.to_dict()["kind"] for t in fitted.model.terms] == ["backlash"]
    nuisance = fitted.info["nuisance"]
    resid = []
    for path in files:
        data = read_measurements(path)
        mm = measurement_model(fitted.model, data, fitted.context_defaults,
                               extra_context=drift_context(fitted.model, data))
        nu = np.array([nuisance[n] for n in mm.nuisance_names])
        r = (mm.observed - mm.predict(fitted.params.values, nu)) * mm.obs_unit_scale
        resid.append(r[np.asarray(mm.obs_column).astype(str) != "value_urad"])
    rms = float(np.sqrt(np.mean(np.concatenate(resid) ** 2)))
    assert rms == pytest.approx(rep["final"]["rms_um"], rel=1e-3)


def test_bad_inputs_exit_2_and_write_nothing(campaign, tmp_path, capsys):
    _, files = campaign
    report = tmp_path / "r.json"
    cases = [
        ["diagnose", "xfyz", str(tmp_path / "missing.csv"), "--json", str(report)],
        ["diagnose", "xfyz", *files[:2], "--json", str(tmp_path / "no" / "r.json")],
        ["diagnose", "xfyz", files[0], "--json", files[0]],
        ["diagnose", "nosuchmachine", files[0], "--json", str(report)],
        ["diagnose", "xfyz", files[0], "--json", str(report), "-o", str(report)],
    ]
    rotary = tmp_path / "rotary.csv"
    rotary.write_text("x_mm,y_mm,z_mm,c_deg,dx_um\n0,0,0,10,1.0\n1,0,0,20,1.5\n")
    cases.append(["diagnose", "xfyz", str(rotary), "--json", str(report)])
    for argv in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert not report.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rotary.csv"]
