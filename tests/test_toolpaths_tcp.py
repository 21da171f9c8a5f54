"""Tool centre point programs: the axes the controller reaches for a tip and angles, and back.

Checked against the independent virtual machine (tests/truth, which shares no code with mtcomp):
its nominal tool tip at the axes :func:`axes_of_tcp` finds is the tip the words asked for, and the
words :func:`tcp_of_axes` writes are its nominal tip at those axes."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.errors import InputError
from mtcomp.machine import load_machine
from mtcomp.toolpaths.tcp import axes_of_tcp, tcp_of_axes
from test_kinematics_single import TOPOLOGIES, _random_q, machine_pair  # noqa: F401
import replay_heidenhain
from replay import _runs, replay
from truth.machine import TruthMachine


def _tcp_words(truth: TruthMachine, m, q):
    """The TCP words of axes q by the truth's own nominal kinematics: its tip, the angles kept."""
    words = np.array(q, dtype=float)
    tip, _ = truth.nominal_pose(q)
    for k, a in enumerate("XYZ"):
        words[:, m.axis_names.index(a)] = tip[:, k]
    return words


def test_the_words_are_the_truths_nominal_tip(machine_pair):
    m, truth = machine_pair
    q = _random_q(m, 5)
    np.testing.assert_allclose(tcp_of_axes(m, q), _tcp_words(truth, m, q), rtol=0, atol=1e-9)


def test_the_axes_reach_the_tip_the_words_ask_for(machine_pair):
    m, truth = machine_pair
    q = _random_q(m, 6)
    words = _tcp_words(truth, m, q)
    axes = axes_of_tcp(m, words)
    np.testing.assert_allclose(axes, q, rtol=0, atol=1e-9)
    tip, _ = truth.nominal_pose(axes)
    np.testing.assert_allclose(tip, words[:, [m.axis_names.index(a) for a in "XYZ"]], rtol=0,
                               atol=1e-9)


def test_a_machine_without_z_is_refused():
    import dataclasses
    m = load_machine("xfyz")
    flat = dataclasses.replace(m, axes=tuple(a for a in m.axes if a.name != "Z"))
    with pytest.raises(InputError, match="need the axes X, Y and Z"):
        axes_of_tcp(flat, np.zeros((1, 2)))


# ------------------------------------------------------------- a TCP program on an independent machine
BOAT = Path(__file__).parent / "data" / "gcode_corpus" / "linuxcnc_boat-xyzac.ngc"


def _paired_ends(src: bytes, out: bytes) -> tuple[list[dict], list[dict]]:
    """(source move ends, their output counterparts) in word space (mm, deg), replayed as a controller
    reads the words (tests/replay.py, no mtcomp): within each run of moves between the same two
    motionless lines, the moves in order where the run has as many in both; else (an arc split into
    pieces) each source move's end and the output move ending nearest to it (an arc ends where its
    last piece does). Nearest alone mispairs where the program's moves lie closer than a correction
    (the boat demo near A = 0, where C's correction reaches 0.07 deg): there the after figure was
    another move's. Moves with an axis the program has not given are left out."""
    a, b = replay(src), replay(out)
    ends_src, ends_out = [], []
    given = lambda e: all(e.get(k) is not None for k in "XYZAC")          # noqa: E731
    for run_a, run_b in zip(_runs(a), _runs(b)):
        if len(run_a) == len(run_b):
            pairs = [(m.end, n.end) for m, n in zip(run_a, run_b) if given(m.end) and given(n.end)]
        else:
            ends = [m.end for m in run_b if given(m.end)]
            pairs = [(m.end, min(ends, key=lambda e: sum((e[k] - m.end[k]) ** 2 for k in "XYZAC")))
                     for m in run_a if ends and given(m.end)]
        ends_src += [p[0] for p in pairs]
        ends_out += [p[1] for p in pairs]
    return ends_src, ends_out


def _truth_axes(truth: TruthMachine, moves: list[dict]) -> np.ndarray:
    """The axes the truth machine's nominal kinematics puts the tip at each move's X Y Z with its
    A and C (its own inverse: for fixed angles the tip is affine in X Y Z)."""
    q = np.array([[m["X"], m["Y"], m["Z"], np.radians(m["A"]), np.radians(m["C"])] for m in moves])
    base = q.copy()
    base[:, :3] = 0.0
    b = truth.nominal_pose(base)[0]
    M = np.stack([truth.nominal_pose(base + np.eye(5)[k])[0] - b for k in range(3)], axis=2)
    out = q.copy()
    out[:, :3] = np.linalg.solve(M, (q[:, :3] - b)[:, :, None])[:, :, 0]
    return out


def _first_pass_only(points_csv):
    """Keep the rows of run 1 of a points file (CSV with a ``run`` column)."""
    lines = points_csv.read_text().splitlines(keepends=True)
    run = lines[0].strip().split(",").index("run")
    kept = [line for line in lines[1:] if float(line.split(",")[run]) == 1]
    assert 0 < len(kept) < len(lines) - 1
    points_csv.write_text(lines[0] + "".join(kept))


def test_a_tcp_program_is_compensated_on_an_independent_machine(tmp_path, capsys):
    """LinuxCNC's 5-axis TCP demo (M428: X Y Z the tip on the table, A C the table's angles),
    compensated with a model identified from a campaign on the truth machine, then 'cut' on it:
    the tip error (relative to the part's datum, the workpiece origin) drops to a third or less, at
    compensate's default limit on a correction's standard error (5 um).

    The campaign is what a 5-axis user measures for such programs (independent_cases.tcp_campaign):
    clean_campaign's laser runs, points, circles and three-sphere set-up, and the tool tip read at
    two tool lengths where the part sits, at the program's tilts. Without that last file the part
    lies between the laser's targets and the points' lattice, where X's roll and its straightness in
    Y (and Y's roll and its straightness in X) trade at the untilted tool tip: combinations held with
    standard errors of 6.7 and 3.1 um, which a correction's standard error counts (up to 9.4 um; a Monte
    Carlo over the noise, benchmarks/bench_tcp_sd.py, finds the corrections off the truth by 3.8 to
    5.5 um there: the standard error is right), so 211 of the 1906 blocks were left uncorrected and
    the tip error went 49.8 -> 19.6 um only."""
    from independent_cases import tcp_campaign
    truth, paths = tcp_campaign("CAFXYZ", 11, tmp_path / "campaign")
    _first_pass_only(paths[0])          # the points file's second pass doubles the fit's time
    model = tmp_path / "model.json"
    assert main(["identify", "cafxyz", *map(str, paths), "-o", str(model)]) == 0
    out = tmp_path / "boat.ngc"
    # bounds wide enough for this machine's errors (up to 70 um at the largest tilts)
    assert main(["compensate", "cafxyz", str(model), str(BOAT), "-o", str(out), "--units", "mm",
                 "--max-correction-um", "200", "--max-step-um", "200",
                 "--max-correction-urad", "2000"]) == 0
    told = capsys.readouterr()
    assert "the model is unsure there" not in told.out + told.err
    src, dst = _paired_ends(BOAT.read_bytes(), out.read_bytes())
    assert len(src) > 1800
    before, after = _tip_rms(truth, src, dst)
    assert before > 5.0                             # the machine's error is material here
    assert after <= before / 3
    # 0.885 um: the model's corrections miss the truth by 0.88 um rms over the program (benchmarks/
    # bench_tcp_sd.py --campaign tcp); main's campaign with the limit raised to 10 um gave 2.31 um
    assert after <= 1.5
    # its tilted finishing pass as a Heidenhain conversational program in M128, on the same model
    # (here, not in a test of its own: the model's identification is most of this test's time)
    twin, out = tmp_path / "boat.h", tmp_path / "boat_out.h"
    twin.write_text(_heidenhain_twin(320, 660))
    assert main(["compensate", "cafxyz", str(model), str(twin), "-o", str(out), "--units", "mm",
                 "--max-correction-um", "200", "--max-step-um", "200",
                 "--max-correction-urad", "2000"]) == 0
    capsys.readouterr()
    ends = [{m.line: m.end for m in replay_heidenhain.replay(p.read_bytes()).moves}
            for p in (twin, out)]
    lines = [k for k, e in ends[0].items() if all(e[a] is not None for a in "XYZAC")]
    assert len(lines) > 300 and all(k in ends[1] for k in lines)
    twin_before, twin_after = _tip_rms(truth, [ends[0][k] for k in lines],
                                       [ends[1][k] for k in lines])
    print(f"TCP demo on the truth machine: tip error rms {before:.3f} -> {after:.3f} um; its "
          f"Heidenhain twin (M128): {twin_before:.3f} -> {twin_after:.3f} um")
    assert twin_before > 5.0
    assert twin_after <= twin_before / 3
    # Haas programs on the same model: G234 (tool centre point control) and a G254 (dynamic work
    # offset) 3+2 program, turned into axes by a hand-written trunnion kinematics
    from test_toolpaths_tcp_haas import tip_errors_um
    for name, (haas_before, haas_after) in tip_errors_um(truth, model, tmp_path).items():
        print(f"Haas {name} on the truth machine: tip error rms {haas_before:.3f} -> "
              f"{haas_after:.3f} um")
        assert haas_before > 5.0
        assert haas_after <= haas_before / 3


def _tip_rms(truth: TruthMachine, src: list[dict], dst: list[dict]) -> tuple[float, float]:
    """The rms tip error (um) on the truth machine, relative to the part's datum (the workpiece
    origin), of the moves' ends ``src`` (the program's words) cut at their words ``src`` (before)
    and at the compensated words ``dst`` (after)."""
    q_src, q_out = _truth_axes(truth, src), _truth_axes(truth, dst)
    datum = _truth_axes(truth, [dict.fromkeys("XYZAC", 0.0)])
    err_datum = truth.true_pose(datum)[0] - truth.nominal_pose(datum)[0]
    aim = truth.nominal_pose(q_src)[0]
    before = truth.true_pose(q_src)[0] - aim - err_datum
    after = truth.true_pose(q_out)[0] - aim - err_datum
    rms = lambda e: 1e3 * float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))   # noqa: E731 (um)
    return rms(before), rms(after)


def _heidenhain_twin(first: int, last: int) -> str:
    """BOAT's lines first .. last (1-based) as a TNC conversational program in tool centre point
    mode: each line with axis words an L block with those words (signed), FMAX where G0 is in
    force, else a feed (the demo's G93 inverse-time feeds mean nothing here; the path is the
    same); M128 on the first, M129 after the last."""
    import re
    out, rapid = ["0 BEGIN PGM BOAT MM"], True
    for raw in BOAT.read_text().splitlines()[first - 1:last]:
        code = re.sub(r"\(.*?\)|;.*", "", raw).upper()
        words = re.findall(r"([A-Z])\s*([-+]?\d*\.?\d*)", code)
        gs = {float(v) for a, v in words if a == "G"}
        rapid = True if gs & {0.0} else False if gs & {1.0} else rapid
        axes = [f"{a}{v if v[0] in '+-' else '+' + v}" for a, v in words if a in "XYZAC"]
        if axes:
            tail = "FMAX" if rapid else "F500"
            m128 = " M128" if len(out) == 1 else ""
            out.append(f"{len(out)} L {' '.join(axes)} {tail}{m128}")
    out += [f"{len(out)} M129", f"{len(out) + 1} END PGM BOAT MM"]
    return "\n".join(out) + "\n"


def test_render_of_a_tcp_program_maps_its_report_as_its_compensated_program(tmp_path, capsys):
    """BLOCKS.csv holds a TCP block's words (tip and angles); render pairs them with the program
    at the axes the controller reaches, so --report and --compensated give one 'after' map."""
    from test_gcode_corpus import _machine_file, _model_file
    machine = _machine_file(tmp_path, "CAFXYZ")
    model = _model_file(tmp_path, machine)
    out, report = tmp_path / "boat.ngc", tmp_path / "blocks.csv"
    assert main(["compensate", str(machine), str(model), str(BOAT), "-o", str(out), "--report",
                 str(report), "--units", "mm", "--quiet"]) == 0
    after = []
    for extra in (["--compensated", str(out)], ["--report", str(report)]):
        assert main(["render", str(machine), str(model), str(BOAT), *extra, "-o",
                     str(tmp_path / "map.png"), "--backend", "matplotlib", "--size", "300x150"]) == 0
        line = next(x for x in capsys.readouterr().out.splitlines() if "prediction after" in x)
        after.append(float(line.split("RMS")[1].split()[0]))
    assert after[0] < 1.0
    np.testing.assert_allclose(after[1], after[0], rtol=0.05, atol=0.01)
