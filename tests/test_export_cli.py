"""`mtcomp export` on the command line: the region of the tables, and bad input (exit 2, one line)."""
import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import Backlash, ErrorModel, FittedModel, save_model
from test_export_formats import parse_fanuc_tape, random_model


def _model(tmp_path, support):
    p = tmp_path / "model.json"
    save_model(p, random_model("xfyz", (Backlash("X"),), 3, 20.0, support))
    return p


def _nominals(path):
    return np.array([float(line.split()[0]) for line in path.read_text().splitlines()])


def test_axis_without_data_gets_no_table_and_a_reason(tmp_path, capsys):
    p = _model(tmp_path, {"X": (-20.0, 20.0), "Y": (0.0, 10.0)})
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(tmp_path / "lc")]) == 0
    err = capsys.readouterr().err
    assert (tmp_path / "lc" / "x.comp").exists() and (tmp_path / "lc" / "y.comp").exists()
    assert not (tmp_path / "lc" / "z.comp").exists()
    assert "axis Z: no table: the axis did not move in the data" in err
    nom = _nominals(tmp_path / "lc" / "x.comp")
    # the data's span and one step beyond each end, where the table is zero (X travels -400 .. 400)
    assert nom[1] == -20 and nom[-2] == 20 and np.allclose(np.diff(nom), 1.0)
    assert "axis Z: no table" in (tmp_path / "lc" / "README.txt").read_text()


def test_model_without_support_uses_the_travel_loudly_or_the_range(tmp_path, capsys):
    p = _model(tmp_path, None)
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(tmp_path / "a"),
                 "--range", "Y=-5:5"]) == 0
    err = capsys.readouterr().err
    assert "WARNING" in err and "support" in err
    x = _nominals(tmp_path / "a" / "x.comp")
    y = _nominals(tmp_path / "a" / "y.comp")
    assert (x[0], x[-1]) == (-400, 400) and len(x) <= 256
    assert (y[1], y[-2]) == (-5, 5) and (y[0], y[-1]) == (-6, 6)


def test_range_clips_the_support_and_grid_step_is_honoured(tmp_path, capsys):
    p = _model(tmp_path, {"X": (-20.0, 20.0)})
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(tmp_path / "lc"),
                 "--range", "X=0:50", "--grid-mm", "3"]) == 0
    nom = _nominals(tmp_path / "lc" / "x.comp")
    # equidistant from the start, the last point at the end of the region (LinuxCNC takes any nominal)
    # one step beyond each end the table is zero
    np.testing.assert_allclose(nom, [-3, 0, 3, 6, 9, 12, 15, 18, 20, 23], rtol=0, atol=1e-9)


@pytest.mark.parametrize("args,expected", [
    (["--range", "X=5"], "expected AXIS=LO:HI"),
    (["--range", "Q=0:1"], "no axis Q"),
    (["--range", "X=3:1"], "LO < HI"),
    (["--grid-mm", "0.01"], "holds at most 256"),
    (["--max-points", "1"], "at least 2"),
    (["--fanuc-max-value", "-1"], "--fanuc-max-value must be a positive whole number"),
])
def test_bad_options_exit_2_with_one_line_and_write_nothing(tmp_path, capsys, args, expected):
    p = _model(tmp_path, {"X": (-20.0, 20.0)})
    out = tmp_path / "lc"
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err and "Traceback" not in err
    assert not out.exists()


def test_output_never_overwrites_the_model_and_kind_of_output_is_checked(tmp_path, capsys):
    p = _model(tmp_path, {"X": (-20.0, 20.0), "Y": (-20.0, 20.0)})
    before = p.read_text()
    assert main(["export", "xfyz", str(p), "--format", "klipper", "-o", str(p)]) == 2
    assert "overwrite an input" in capsys.readouterr().err
    assert p.read_text() == before
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(p)]) == 2
    assert "is a file" in capsys.readouterr().err
    assert list(tmp_path.glob(".*part")) == []


def test_a_model_without_errors_has_nothing_to_export(tmp_path, capsys):
    zero = FittedModel.zero(ErrorModel(load_machine("xfyz")))
    zero.support = {"X": (0.0, 10.0)}
    p = tmp_path / "zero.json"
    save_model(p, zero)
    assert main(["export", "xfyz", str(p), "--format", "siemens", "-o", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "nothing to export: " in err and "axis X: no table: the model predicts no error" in err
    assert "axis Y: no table: the axis did not move" in err and err.count("\n") == 1
    assert not (tmp_path / "s").exists()


def test_region_shorter_than_a_grid_step_gets_no_table(tmp_path, capsys):
    p = _model(tmp_path, {"X": (-20.0, 20.0), "Y": (0.0, 0.5)})
    assert main(["export", "xfyz", str(p), "--format", "fanuc", "-o", str(tmp_path / "f")]) == 0
    assert "axis Y: no table: its region is shorter than one grid step" in capsys.readouterr().err
    par, _ = parse_fanuc_tape((tmp_path / "f" / "pitch_error.txt").read_text())
    assert (3620, 1) in par and (3620, 2) not in par


def test_single_file_format_into_a_directory(tmp_path, capsys):
    """klipper writes one file: given a directory it goes inside it as skew.cfg; a path written as a
    directory that does not exist is refused in one line."""
    model = _model(tmp_path, {"X": (-20.0, 20.0), "Y": (-20.0, 20.0)})
    (tmp_path / "out").mkdir()
    assert main(["export", "xfyz", str(model), "--format", "klipper", "-o", str(tmp_path / "out")]) == 0
    assert (tmp_path / "out" / "skew.cfg").is_file()
    capsys.readouterr()
    assert main(["export", "xfyz", str(model), "--format", "klipper", "-o",
                 str(tmp_path / "nodir") + "/"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such directory" in err[0]
    assert not (tmp_path / "nodir").exists()


@pytest.mark.parametrize("terms, said", [((Backlash("X"),), False), ((Backlash("X"), "feed"), True)])
def test_terms_a_table_cannot_hold_are_named(tmp_path, capsys, terms, said):
    """A controller's table has no feed: a model's feed offset is left out of it, and export says so;
    a backlash is in the tables (forward and reverse), and nothing is said."""
    from mtcomp.models import FeedOffset
    terms = tuple(FeedOffset("X") if t == "feed" else t for t in terms)
    p = tmp_path / "model.json"
    save_model(p, random_model("xfyz", terms, 3, 20.0, {"X": (-20.0, 20.0)}))
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(tmp_path / "lc")]) == 0
    err = capsys.readouterr().err
    assert ("the tables leave out what depends on feed (feed_dependent_offset:X)" in err) == said, err


@pytest.mark.parametrize("command", ["identify", "diagnose", "predict", "compensate", "export", "render",
                                     "iso230-2", "machines", "demo"])
def test_every_command_prints_its_help(command, capsys):
    """--help prints and exits 0 (export's Siemens file names hold a '%', which argparse's help
    formatting took for a placeholder and crashed on)."""
    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    assert "usage: mtcomp " + command in capsys.readouterr().out


@pytest.mark.parametrize("work_offset", [None, "G54=X100,Y50,Z-40"])
def test_compensate_and_export_correct_alike_up_to_the_datum(tmp_path, work_offset, capsys):
    """One laser model of X, two routes: the deviation compensate corrects at each block (BLOCKS.csv
    ex_before_um) and the trim of the LinuxCNC table export writes (its forward column, comp type 1)
    at the same machine position differ by one constant, the reference (compensate: the part's
    datum, the program's work-offset origin; export: the machine zero), to 0.01 um. The datum's own
    deviation is not corrected: the block at the program's origin has none."""
    from truth import TruthMachine
    from truth import campaigns as tc
    rng = np.random.default_rng(4)
    truth = TruthMachine.random("xfyz", rng, error_motions=False)
    laser = tc.laser(truth, tmp_path / "laser_x.csv", rng, "X", components=["EXX"], n_runs=3,
                     static={"Y": 50.0, "Z": -40.0}, noise_um=0.3).path
    model = tmp_path / "m.json"
    assert main(["identify", "xfyz", str(laser), "-o", str(model)]) == 0
    shift = np.array([100.0, 50.0, -40.0]) if work_offset else np.array([0.0, 50.0, -40.0])
    xs = np.arange(-200.0, 201.0, 25.0)                      # machine X, on the table's 1 mm grid
    prog = tmp_path / "x.nc"
    prog.write_text("G21 G90 G54\nG0 X0 Y0 Z0\n" + f"G0 X{xs[0] - shift[0] - 5:g} Y{50 - shift[1]:g} "
                    f"Z{-40 - shift[2]:g}\n" + "".join(f"G1 X{x - shift[0]:g} F1000\n" for x in xs)
                    + "M30\n")
    rep = tmp_path / "b.csv"
    args = ["compensate", "xfyz", str(model), str(prog), "-o", str(tmp_path / "o.nc"), "--report",
            str(rep), "--subdivide-tol-um", "0", "--max-step-um", "50"]
    assert main(args + (["--work-offset", work_offset] if work_offset else [])) == 0
    assert main(["export", "xfyz", str(model), "--format", "linuxcnc", "-o", str(tmp_path / "lc")]) == 0
    capsys.readouterr()
    rows = {int(r["line"]): r for r in __import__("csv").DictReader(open(rep, newline=""))}
    before = np.array([float(rows[4 + k]["ex_before_um"]) for k in range(xs.size)])
    table = np.loadtxt(tmp_path / "lc" / "x.comp")
    trim = np.interp(xs, table[:, 0], table[:, 1]) * 1e3    # forward: -(error) um, at machine X
    diff = before + trim
    np.testing.assert_allclose(diff, diff.mean(), rtol=0, atol=0.01)
    # the program's origin (the first block, at the datum) has nothing to correct
    assert float(rows[2]["ex_before_um"]) == pytest.approx(0.0, abs=1e-4)
    assert np.ptp(before) > 5.0                              # um: there was an error to correct


def test_data_outside_the_machines_travel_get_no_table_and_another_machine_is_named(tmp_path, capsys):
    """A model made on another machine of the same topology: its data's region (X -20:20 mm) lies
    outside the given machine's X travel (30:600 mm): no X table, and a note naming both machines;
    Y's region (0:10) reaches beyond the travel (5:300): the table stops at the travel."""
    p = _model(tmp_path, {"X": (-20.0, 20.0), "Y": (0.0, 10.0)})
    mill = tmp_path / "mill2.toml"
    mill.write_text('name = "mill2"\ntopology = "XFYZ"\ntool_length_mm = 150.0\n'
                    "[axes.X]\ntravel_mm = [30.0, 600.0]\n[axes.Y]\ntravel_mm = [5.0, 300.0]\n"
                    "[axes.Z]\ntravel_mm = [-250.0, 150.0]\n")
    assert main(["export", str(mill), str(p), "--format", "linuxcnc", "-o", str(tmp_path / "lc")]) == 0
    err = capsys.readouterr().err
    assert "was made for the machine 'carver800t-like'" in err and "'mill2'" in err
    assert "axis X: the region of the data -20:20 mm lies outside the machine's travel 30:600 mm" in err
    assert not (tmp_path / "lc" / "x.comp").exists()
    nom = _nominals(tmp_path / "lc" / "y.comp")
    assert (nom[0], nom[-2], nom[-1]) == (5.0, 10.0, 11.0)     # at the travel's end no step beyond
    # the machine the model was made for: no such note
    assert main(["export", "xfyz", str(p), "--format", "linuxcnc", "-o", str(tmp_path / "lc2")]) == 0
    assert "was made for the machine" not in capsys.readouterr().err
