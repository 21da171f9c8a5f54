"""What a measurement file says beyond what the readers take (docs/measurements.md, "Columns mtcomp
does not read"): a tool length under another name is refused ("did you mean tool_mm"), so is a
column a letter or two off one its kind reads and lacks; the commands note the columns they do not
read, a points file without tool_mm (every row at the machine's tool length) and deviations that
look like mm under ``*_um`` columns. The thresholds are checked against hand-computed limits:
over positions spanning 700 mm, max(0.05 um, 0.5 ppm x 700 mm) = 0.35 um."""
from __future__ import annotations

import numpy as np
import pytest

from mtcomp import InputError, load_machine
from mtcomp.cli import main
from mtcomp.commands import note_outside_travel
from mtcomp.measurement.files import read_measurements

#: a small grid of points over 700 mm of X: deviations in um, largest 2.5 um
POSITIONS = [(-350.0, -100.0, -50.0), (0.0, 0.0, 0.0), (350.0, 100.0, 50.0), (175.0, -50.0, 20.0)]
DEVIATIONS_UM = [(1.5, -0.8, 0.2), (0.0, 0.3, -0.4), (-2.5, 1.1, 0.9), (0.7, -0.2, 0.05)]


def _points(path, tool_column="tool_mm", extra="", scale=1.0, tool=50.0):
    head = "x_mm,y_mm,z_mm," + (f"{tool_column}," if tool_column else "") + "dx_um,dy_um,dz_um" + \
        (f",{extra}" if extra else "")
    rows = [head]
    for (x, y, z), d in zip(POSITIONS, DEVIATIONS_UM):
        cells = [f"{x}", f"{y}", f"{z}"] + ([f"{tool}"] if tool_column else []) + \
            [f"{v * scale:.6g}" for v in d] + (["a"] if extra else [])
        rows.append(",".join(cells))
    path.write_text("\n".join(rows) + "\n")
    return path


def _notes(path, capsys, machine="xfyz") -> list[str]:
    capsys.readouterr()
    note_outside_travel(load_machine(machine), [read_measurements(path)])
    return [ln for ln in capsys.readouterr().err.splitlines() if ln]


@pytest.mark.parametrize("column", ["stylus_mm", "tool_length_mm", "probe_length_mm", "toollength_mm"])
def test_a_tool_length_under_another_name_is_refused(tmp_path, capsys, column):
    src = _points(tmp_path / "grid.csv", tool_column=column)
    out = tmp_path / "M.json"
    assert main(["identify", "xfyz", str(src), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"grid.csv: row 0: column {column}: did you mean tool_mm" in err
    assert not out.exists()


def test_a_column_a_letter_off_one_its_kind_lacks_is_refused(tmp_path):
    p = tmp_path / "typo.csv"
    p.write_text("x_mm,y_mm,z_mmm,dx_um\n1,2,3,0.5\n")
    with pytest.raises(InputError, match=r"typo.csv: row 0: column z_mmm: did you mean z_mm\?"):
        read_measurements(p)
    # the same name beside the column it resembles is no misspelling: an extra column, kept
    p.write_text("x_mm,y_mm,z_mm,z_mmm,dx_um\n1,2,3,4,0.5\n")
    assert read_measurements(p).header[3] == "z_mmm"


def test_a_file_mtcomp_reads_whole_gets_no_note(tmp_path, capsys):
    assert _notes(_points(tmp_path / "ok.csv"), capsys) == []


def test_columns_not_read_and_the_machines_tool_length_are_noted(tmp_path, capsys):
    notes = _notes(_points(tmp_path / "g.csv", tool_column=None, extra="operator"), capsys)
    assert len(notes) == 2, notes
    assert "g.csv: column(s) operator not read by mtcomp" in notes[0]
    tool = load_machine("xfyz").tool_length
    assert (f"g.csv: no column tool_mm: every row is taken at the machine's tool length, {tool:g} mm"
            in notes[1])
    # tool_mm beside another name of the tool length: read, and the other one noted, not refused
    p = tmp_path / "both.csv"
    p.write_text("x_mm,y_mm,z_mm,tool_mm,stylus_mm,dx_um\n-350,0,0,50,50,1\n350,0,0,50,50,-1\n")
    notes = _notes(p, capsys)
    assert len(notes) == 1 and "column(s) stylus_mm not read by mtcomp" in notes[0]


def test_deviations_in_mm_under_um_columns_are_noted(tmp_path, capsys):
    # the same grid written in mm: largest 0.0025 "um" over 700 mm, below 0.35 um
    notes = _notes(_points(tmp_path / "mm.csv", scale=1e-3), capsys)
    assert len(notes) == 1, notes
    assert ("mm.csv: every deviation (dx_um, dy_um, dz_um) is below 0.35 um in magnitude (largest "
            "0.0025 um) over positions spanning 700 mm") in notes[0]
    assert "multiply them by 1000" in notes[0]
    # the limit, by hand: a largest deviation of 0.34 um is noted, 0.36 um is not
    for largest, noted in ((0.34, True), (0.36, False)):
        notes = _notes(_points(tmp_path / "edge.csv", scale=largest / 2.5), capsys)
        assert (len(notes) == 1) is noted, (largest, notes)
    # a span under 100 mm says nothing: tiny errors are possible there
    p = tmp_path / "short.csv"
    p.write_text("x_mm,y_mm,z_mm,tool_mm,dx_um\n0,0,0,50,0.001\n90,0,0,50,-0.002\n")
    assert _notes(p, capsys) == []
    assert np.isclose(max(abs(v) for d in DEVIATIONS_UM for v in d), 2.5, rtol=0, atol=0)


def test_a_whole_file_in_inches_is_noted(tmp_path, capsys):
    """A CMM file written in inches (positions spanning 19.7 'mm' for a 500 mm plate, deviations of
    a few 1e-5 in) spans less than the laser rule's 100 mm, but no CMM reads ten points of a part
    all within 0.05 um: noted (a job shop's file was fitted without a word, to 3.5e-5 um). A
    largest deviation of 0.06 um, or fewer than ten values, says nothing."""
    def write(name, largest, n=12):
        p = tmp_path / name
        rows = [f"{-15 + 19.685 * k / (n - 1):.4f},{-8 + 0.5 * k:.4f},0,100,"
                f"{largest * (-1) ** k * (k + 1) / n:.6g},0" for k in range(n)]
        p.write_text("x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um\n" + "\n".join(rows) + "\n")
        return p
    notes = _notes(write("inch.csv", 0.0019), capsys)
    assert len(notes) == 1, notes
    assert ("inch.csv: every deviation (dx_um, dy_um) is below 0.05 um in magnitude (largest "
            "0.0019 um), less than a CMM's or a tracker's noise, over positions spanning 19.685 mm: "
            "were the file's values written in inches or mm?") in notes[0]
    assert _notes(write("fine.csv", 0.06), capsys) == []
    assert _notes(write("few.csv", 0.0019, n=4), capsys) == []


@pytest.mark.parametrize("header, column, meant", [
    ("x_mm,y_mm,z_mm,c_rad,dx_um", "c_rad", "c_deg"),
    ("x_in,y_mm,z_mm,b_deg,dx_um", "x_in", "x_mm"),
    ("x_mm,y_mm,z_mm,b_mrad,dx_um", "b_mrad", "b_deg")])
def test_an_axis_column_in_another_unit_is_refused(tmp_path, header, column, meant):
    """Read as a column mtcomp does not read, the axis would be taken at 0 in every row (a C
    column named c_rad in a three-sphere ball-bar file was, and the fit went ahead)."""
    p = tmp_path / "grid.csv"
    p.write_text(f"{header}\n100,0,0,0.5,1.5\n0,100,0,1.0,2.5\n")
    with pytest.raises(InputError, match=f"column {column}: mtcomp reads the .* as {meant}") as info:
        read_measurements(p)
    assert info.value.row == 0 and "\n" not in info.value.one_line()


def test_an_axis_column_in_mtcomps_unit_beside_another_is_only_noted(tmp_path, capsys):
    """c_rad beside c_deg is a copy in other units (kept, noted), not the axis under a wrong name."""
    p = tmp_path / "bar.csv"
    p.write_text("x_mm,y_mm,z_mm,c_deg,c_rad,dx_um\n100,0,0,90,1.5708,1.5\n0,100,0,180,3.1416,2.5\n")
    data = read_measurements(p)
    assert data.kind == "points" and "c_rad" in data.header


def test_rotary_data_beyond_a_travel_of_less_than_a_turn_is_noted(tmp_path, capsys):
    """A tilting axis's travel typed in radians under travel_deg (+-1.745 for +-100 deg): ball-bar
    rows at B +-60 deg are noted, with the likely cause; a C of a whole turn is never noted."""
    machine = tmp_path / "m.toml"
    machine.write_text('name = "t"\ntopology = "CBFXYZ"\n[axes.X]\ntravel_mm = [-300, 300]\n'
                       '[axes.Y]\ntravel_mm = [-300, 300]\n[axes.Z]\ntravel_mm = [-300, 300]\n'
                       '[axes.B]\ntravel_deg = [-1.745, 1.745]\naxis_point_mm = [0, 0, 0]\n'
                       '[axes.C]\ntravel_deg = [0, 360]\naxis_point_mm = [0, 0, 0]\n')
    p = tmp_path / "grid.csv"
    p.write_text("x_mm,y_mm,z_mm,b_deg,c_deg,dx_um\n0,0,0,-60,0,1\n0,0,0,1.5,350,2\n"
                 "0,0,0,60,720,1\n0,0,0,-1.7450000005,0,1\n0,0,0,1.7450000005,0,1\n")
    note_outside_travel(load_machine(machine), [read_measurements(p)])
    err = capsys.readouterr().err
    assert "2 row(s) take B to -60..60 deg, outside the machine's travel -1.745..1.745 deg " \
           "(a travel_deg written in radians?)" in err
    assert "take C" not in err


def test_a_ball_bar_file_in_inches_is_noted(tmp_path, capsys):
    """A 100 mm bar's circle written in inches (3.937 'mm', positions in inches too, so the
    lengths agree with the balls' distance): fitted without a word before. No bar is under an inch
    long; a 50 mm one says nothing."""
    def write(name, r):
        p = tmp_path / name
        rows = [f"{r * np.cos(t):.6f},{r * np.sin(t):.6f},0,0,0,0,0,0,0,{r + 1e-5:.6f}"
                for t in np.linspace(0.0, 2 * np.pi, 12, endpoint=False)]
        p.write_text("x_mm,y_mm,z_mm,table_ball_x_mm,table_ball_y_mm,table_ball_z_mm,tool_ball_x_mm,"
                     "tool_ball_y_mm,tool_ball_z_mm,length_mm\n" + "\n".join(rows) + "\n")
        return p
    notes = _notes(write("bb_inch.csv", 3.937008), capsys)
    assert len(notes) == 1 and "bb_inch.csv: every length_mm is below 25.4 mm (largest 3.937): no " \
        "ball bar is that short; a file in inches?" in notes[0], notes
    assert _notes(write("bb_50.csv", 50.0), capsys) == []


def _laser_y(path, static=True, component="EYY", unit="value_um"):
    """A laser run of Y at X = -200, Z = -150 (or without those columns)."""
    head = "axis,component,target_mm,dir,run," + unit + (",x_mm,z_mm" if static else "")
    rows = [head] + [f"Y,{component},{t},{d},1,{0.01 * t:.3g}" + (",-200,-150" if static else "")
                     for t in (-300, -200, -100, 0) for d in (1, -1)]
    path.write_text("\n".join(rows) + "\n")
    return path


def _static_notes(capsys, *paths) -> list[str]:
    capsys.readouterr()
    note_outside_travel(load_machine("xfyz"), [read_measurements(p) for p in paths])
    return [ln for ln in capsys.readouterr().err.splitlines() if "Abbe arms" in ln]


def test_a_laser_run_without_its_static_axes_beside_volumetric_data_is_noted(tmp_path, capsys):
    # the points grid places X at -350..350 and Z at -50..50; the run of Y names no x_mm, z_mm
    grid = _points(tmp_path / "grid.csv")
    bare = _laser_y(tmp_path / "ly.csv", static=False)
    notes = _static_notes(capsys, grid, bare)
    assert len(notes) == 1
    assert ("ly.csv: no column x_mm, z_mm: the run is taken at X = 0, Z = 0 in every row, where the "
            "other files place them (X -350 to 350 mm, Z -50 to 50 mm)") in notes[0]
    assert "angular errors of Y" in notes[0]
    # with the columns: nothing to say
    assert _static_notes(capsys, grid, _laser_y(tmp_path / "ly2.csv")) == []


def test_positioning_runs_alone_without_static_axes_get_no_note(tmp_path, capsys):
    # ISO 230-2 positioning runs of X and Y: no angular error enters their fit, the arms act on
    # nothing (the real ISO 230-2 files have no static columns)
    bare = _laser_y(tmp_path / "ly.csv", static=False)
    lx = tmp_path / "lx.csv"
    lx.write_text("axis,component,target_mm,dir,run,value_um,y_mm,z_mm\n"
                  + "".join(f"X,EXX,{t},1,1,0.1,-150,-200\n" for t in (-300, -200, -100, 0)))
    assert _static_notes(capsys, lx, bare) == []
    assert _static_notes(capsys, bare) == []
    # a run of Y's pitch beside them: the arms act through it
    pitch = _laser_y(tmp_path / "pitch.csv", static=False, component="EAY", unit="value_urad")
    notes = _static_notes(capsys, lx, pitch)
    assert len(notes) == 1 and "pitch.csv: no column x_mm, z_mm" in notes[0]
    assert "(X -300 to 0 mm, Z -200 mm)" in notes[0]


#: a laser positioning run of X at two feeds (mm/min as mtcomp reads them)
_LASER = ("axis,component,target_mm,dir,run,value_um,{feed},t_s\n"
          "X,EXX,-100,1,1,1.0,{f1},0\nX,EXX,100,1,1,2.0,{f1},5\n"
          "X,EXX,-100,1,2,1.1,{f2},10\nX,EXX,100,1,2,2.1,{f2},15\n")


_BALLS = "x_mm,y_mm,z_mm," + ",".join(f"{b}_ball_{a}_mm" for b in ("table", "tool") for a in "xyz")


@pytest.mark.parametrize("header, column, meant, unit", [
    ("axis,component,target_mm,dir,run,value_um,feed_mm_s", "feed_mm_s", "feed_mm_min", "mm/min"),
    ("axis,component,target_mm,dir,run,value_um,feed_m_min", "feed_m_min", "feed_mm_min", "mm/min"),
    ("axis,component,target_mm,dir,run,value_um,t_min", "t_min", "t_s", "seconds"),
    ("axis,component,target_mm,dir,run,value_nm,t_s", "value_nm", "value_um", "um"),
    ("axis,component,target_in,dir,run,value_um,t_s", "target_in", "target_mm", "mm"),
    (_BALLS + ",Length_IN", "Length_IN", "length_mm", "mm"),
    ("x_mm,y_mm,z_mm,dx_mm,dy_um", "dx_mm", "dx_um", "um")])
def test_a_quantity_mtcomp_reads_in_another_unit_is_refused(tmp_path, capsys, header, column, meant, unit):
    """A feed in mm/s under feed_mm_s was only noted "not read": every run was taken at an unknown
    feed, and diagnose named a thermal drift of X that was the feed's effect. Any quantity mtcomp
    reads, in another unit, is refused in one line as an axis in c_rad is (exit 2, nothing written)."""
    p = tmp_path / "run.csv"
    p.write_text(f"{header}\n" + "\n".join(",".join(_row(header, k)) for k in range(4)) + "\n")
    out = tmp_path / "R.json"
    assert main(["diagnose", "xfyz", str(p), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert (f"run.csv: row 0: column {column}: mtcomp reads " in err
            and f" as {meant}, in {unit}, and does not read {column}; convert the values to {unit} "
            "and rename the column" in err), err
    assert not out.exists()


def _row(header: str, k: int) -> list[str]:
    """Row ``k`` of a small file with the columns of ``header``: a laser run or a ball-bar circle."""
    cells = {"axis": "X", "component": "EXX", "target_mm": f"{-100 + 50 * k}", "target_in": f"{-4 + 2 * k}",
             "dir": "1", "run": "1", "value_um": f"{0.1 * k}", "value_nm": f"{100 * k}", "t_s": f"{5 * k}",
             "t_min": f"{k / 12:.4f}", "feed_mm_s": "16.7", "feed_m_min": "1", "x_mm": f"{100 - 10 * k}",
             "y_mm": f"{10 * k}", "z_mm": "0", "length_in": "3.937", "dx_mm": "0.001", "dy_um": "1"}
    return [cells.get(c.lower(), "0") for c in header.split(",")]


def test_a_quantity_in_another_unit_beside_mtcomps_column_is_only_noted(tmp_path, capsys):
    """feed_mm_s beside feed_mm_min is a copy in other units: kept and noted, as c_rad beside c_deg."""
    p = tmp_path / "run.csv"
    p.write_text(_LASER.format(feed="feed_mm_min,feed_mm_s", f1="1000,16.67", f2="3000,50"))
    notes = _notes(p, capsys)
    assert len(notes) == 1 and "column(s) feed_mm_s not read by mtcomp" in notes[0], notes


def test_feeds_that_look_like_mm_s_under_feed_mm_min_are_noted(tmp_path, capsys):
    """Feeds of 1000 and 5000 mm/min written in mm/s (16.67, 83.33) under feed_mm_min were taken
    without a word: a note names the file and the range; plausible feeds get none, and nothing is
    refused."""
    p = tmp_path / "slow.csv"
    p.write_text(_LASER.format(feed="feed_mm_min", f1="16.67", f2="83.33"))
    notes = _notes(p, capsys)
    assert notes == ["note: " + str(p) + ": every feed_mm_min is below 100 mm/min (16.67 to 83.33), "
                     "slower than laser and ball-bar runs are made: feeds in mm/s? mtcomp reads "
                     "feed_mm_min in mm/min (mm/s times 60)"], notes
    p.write_text(_LASER.format(feed="feed_mm_min", f1="100", f2="5000"))
    assert _notes(p, capsys) == []


def test_points_positions_in_inches_are_noted(tmp_path):
    """A grid read at -300 .. 300 mm by 100 mm written in inches under x_mm and y_mm (-11.8110 ..
    11.8110, each 100/25.4 in apart, 4 decimals as an inch file writes them) is fitted as errors
    changing 25.4 times as fast as they do: noted, naming the columns and spans as read (23.622 and
    15.748 mm, by hand), as is the grid with only X in inches (a quality engineer's CMM file). The
    same grid in mm, and a grid whose positions are tenths of a mm, are not."""
    from mtcomp.measurement.columns import file_notes
    machine = load_machine("xfyz")

    def notes(name, xs, ys):
        p = tmp_path / name
        rows = [f"{x:.4f},{y:.4f},-50,100,0.5,-0.5" for x in xs for y in ys]
        p.write_text("x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um\n" + "\n".join(rows) + "\n")
        return [n for n in file_notes(machine, [read_measurements(p)]) if "inches" in n]
    mm_x, mm_y = np.arange(-300, 301, 100.0), np.arange(-200, 201, 100.0)
    found = notes("inch.csv", mm_x / 25.4, mm_y / 25.4)
    assert len(found) == 1, found
    assert "inch.csv: the positions (x_mm, y_mm) are whole mm only times 25.4 (spans 23.62, 15.75 mm" \
        in found[0]
    one = notes("x_only.csv", mm_x / 25.4, mm_y)            # one column converted, not the other
    assert len(one) == 1 and "x_only.csv: the positions (x_mm) are whole mm only times 25.4 " \
        "(spans 23.62 mm" in one[0], one
    assert notes("mm.csv", mm_x, mm_y) == []
    assert notes("tenths.csv", mm_x / 10.0, mm_y / 10.0) == []


def test_angles_in_radians_and_a_missing_rotary_column_are_noted(tmp_path):
    """An R-test on a B-C table read at B -30, 0, 30, 60, 90 deg and C every 45 deg, written in
    radians under b_deg and c_deg (-0.52360 .. 1.57080, 0 .. 5.49779, 5 decimals): whole degrees
    only as radians (-30.0001 deg, by hand), so noted naming both columns; the same angles in
    degrees, and tenths of a degree (a tilt read -0.5 .. 1.5 deg), are not. A file without c_deg
    on that machine is noted: C taken at 0 in every row; a file without any rotary column (a
    linear-axis campaign with the table at 0) is not."""
    from mtcomp.measurement.columns import file_notes
    machine = load_machine("cbfxyz")
    b_deg, c_deg = np.arange(-30.0, 91.0, 30.0), np.arange(0.0, 360.0, 45.0)

    def notes(name, head, rows, says):
        p = tmp_path / name
        p.write_text(head + "\n" + "\n".join(rows) + "\n")
        return [n for n in file_notes(machine, [read_measurements(p)]) if says in n]
    head = "x_mm,y_mm,z_mm,tool_mm,b_deg,c_deg,dx_um,dy_um,dz_um"
    rad = [f"50,0,20,100,{np.radians(b):.5f},{np.radians(c):.5f},1,2,3" for b in b_deg for c in c_deg]
    found = notes("rad.csv", head, rad, "radians")
    assert len(found) == 1 and "rad.csv: the angles of b_deg (-0.5236 to 1.5708), c_deg (0 to " \
        "5.4978) are whole degrees only if read as radians" in found[0], found
    deg = [f"50,0,20,100,{b:g},{c:g},1,2,3" for b in b_deg for c in c_deg]
    assert notes("deg.csv", head, deg, "radians") == []
    tenths = [f"50,0,20,100,{b:g},0,1,2,3" for b in (-0.5, 0.0, 0.5, 1.0, 1.5)]
    assert notes("tenths.csv", head, tenths, "radians") == []
    no_c = [f"50,0,20,100,{b:g},1,2,3" for b in b_deg]
    found = notes("no_c.csv", "x_mm,y_mm,z_mm,tool_mm,b_deg,dx_um,dy_um,dz_um", no_c, "taken at 0")
    assert len(found) == 1 and "no_c.csv: no column c_deg: C taken at 0 in every row" in found[0]
    linear = ["50,0,20,100,1,2,3", "0,50,20,100,1,2,3"]
    assert notes("linear.csv", "x_mm,y_mm,z_mm,tool_mm,dx_um,dy_um,dz_um", linear,
                 "taken at 0") == []


def test_a_laser_run_whose_own_axis_column_disagrees_with_its_target_is_noted(tmp_path):
    """A Y run at X -400 written as axis X (a new user's mislabelled file: fitted as a 116 urad yaw
    of X, 17 of 29 blocks worse): its x_mm column says X stood at -400 while the rows' targets say
    X moved: noted, naming the row and column. The same column equal to the targets, or blank, is
    not."""
    from mtcomp.measurement.columns import file_notes
    machine = load_machine("xfyz")

    def notes(name, x_cells):
        p = tmp_path / name
        p.write_text("axis,component,target_mm,dir,run,value_um,x_mm,z_mm\n"
                     + "".join(f"X,EXX,{t},1,1,0.5,{c},-350.0\n"
                               for t, c in zip((-491.204, -455.348), x_cells)))
        return [n for n in file_notes(machine, [read_measurements(p)]) if "moving axis" in n]
    found = notes("y_as_x.csv", ("-400.0", "-400.0"))
    assert len(found) == 1 and ("y_as_x.csv: row 1: column x_mm gives -400 for the moving axis X, "
                                "which stands at its target -491.204 (2 such row(s)") in found[0]
    assert notes("same.csv", ("-491.204", "")) == []
