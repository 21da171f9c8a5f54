"""render's map of a Haas trunnion program (CAFXYZ: a C table on an A trunnion) with the table
turned: a 3+2 program under G254 (dynamic work offset) and one under G234 (tool centre point
control), each placed by its work offset G54. render placed the blocks by a way of its own: the
work offset added to the axes unturned (G254), or after the tip was turned into axes (G234), so it
evaluated the model 100 mm from where compensate had corrected the blocks: on a new user's
UMC-750 the 3+2 program's "after" map showed 0.42 um rms where compensate predicted 0.049 and the
machine left 0.07 um. It now places every block as compensate does (one placement,
ProgramSetup.apply) and takes the deviation from compensate's evaluator.

Hand-derived oracle. A model with two errors: C's line 10 um off in +X (X0C = e = 10 um) and a
positioning error of X of 100 um/m (EXX_1 = 100: k = 1e-4, dx = k x at machine position x). G54
= X100 Y0 Z0; the table at A0 C90. The tool at machine position m meets the part at
Rz(-C) (m - c) + c with c = (e, 0, 0) (the table turns about the true line), against Rz(-C) m
nominally: the line's offset is the deviation c - Rz(-90) c = (e, e, 0) in the part's frame, X's
error k x_m along machine X, Rz(-90) (k x_m, 0, 0) = (0, -k x_m, 0) there. The part's datum (its
origin as probed, A = C = 0: machine X 100) is off by (k 100, 0, 0) = (10, 0, 0) um, which the
probed G54 holds. So, relative to it:

* G254, words X Y Z: along the machine's axes from the part origin turned with the table,
  Rz(90) (100, 0, 0) = (0, 100, 0): x_m = X, and the deviation is (e - 10, e - k X, 0) =
  (0, 10 - 0.1 X, 0) um (X in mm);
* G234, words X Y Z: the tip in the part frame, at machine Rz(90) (X + 100, Y, Z) = (-Y, X + 100,
  Z): x_m = -Y, and the deviation is (0, 10 + 0.1 Y, 0) um.

After compensation (the corrections within compensate's bounds) nothing is left but the written
words' rounding: render's "after" is compensate's own prediction (BLOCKS.csv's e*_after_um).
Before the fix render gave (0, -0.1 X, 0) and (0, 0.1 Y, 0) before, and about 10 um after.
"""
from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from mtcomp.cli import main
from mtcomp.machine import load_machine
from mtcomp.models import ErrorModel, FittedModel, save_model
from mtcomp.toolpaths.offsets import ProgramSetup
from mtcomp.viz.surface import program_error_map

E_UM, K = 10.0, 1e-4                 # X0C (um), X's positioning error (per unit length)
G54 = np.array([100.0, 0.0, 0.0, 0.0, 0.0])
HEAD = "%\nO01003 (UMC TURNED TABLE)\nG00 G17 G21 G40 G49 G80 G90\nG54\nT1 M06\nG00 A0. C90.\n"
PROGRAMS = {
    "G254": HEAD + ("G254\nG00 X20. Y0.\nG43 Z20. H01\nG01 Z-5. F600.\nG01 X40. F800.\nG01 Y10.\n"
                    "G01 X0.\nG00 Z20.\nG255\nG00 G53 Z0.\nM30\n%\n"),
    "G234": HEAD + ("G00 G234 X20. Y0. Z20. H01\nG00 X20. Y0. Z20. A0. C90.\nG01 Z-5. F600.\n"
                    "G01 X40. Y0. Z-5. A0. C90. F800.\nG01 X40. Y10. Z-5. A0. C90.\n"
                    "G01 X0. Y10. Z-5. A0. C90.\nG00 Z20.\nG49\nG00 G53 Z0.\nM30\n%\n"),
}


def _hand_um(mode: str, words: np.ndarray) -> np.ndarray:
    """(n, 3) um: the deviation before compensation at the words (n, 3) X Y Z (mm), relative to the
    part's datum (the derivation in the module's docstring)."""
    y = 10.0 - 0.1 * words[:, 0] if mode == "G254" else 10.0 + 0.1 * words[:, 1]
    return np.column_stack([np.zeros(len(words)), y, np.zeros(len(words))])


@pytest.fixture(scope="module")
def turned(tmp_path_factory):
    """(machine, fitted, folder): the model (X0C = 10 um, EXX_1 = 100 um/m) written to model.json,
    each program compensated by the command line with G54 = X100 (BLOCKS.csv beside)."""
    folder = tmp_path_factory.mktemp("turned")
    machine = load_machine("cafxyz")
    model = ErrorModel(machine.with_basis("polynomial"), ())
    fitted = FittedModel.zero(model)
    names = [s.name for s in model.param_specs]
    fitted.params.values[names.index("X0C")] = E_UM * 1e-3
    fitted.params.values[names.index("EXX_1")] = K * 1e6 * 1e-3      # um at 1 m
    fitted.support = {ax.name: tuple(ax.travel) for ax in machine.axes}
    save_model(folder / "model.json", fitted)
    for mode, text in PROGRAMS.items():
        (folder / f"{mode}.nc").write_text(text)
        assert main(["compensate", "cafxyz", str(folder / "model.json"), str(folder / f"{mode}.nc"),
                     "-o", str(folder / f"{mode}_c.nc"), "--report", str(folder / f"{mode}.csv"),
                     "--work-offset", "G54=X100,Y0,Z0", "--dialect", "haas", "--quiet"]) == 0
    return machine, fitted, folder


def _words(mode: str, text: str, lines) -> np.ndarray:
    """(n, 3) the modal X Y Z words of the program ``text`` at its ``lines`` (1-based)."""
    pos, at = {}, {}
    for k, raw in enumerate(text.splitlines(), 1):
        code = re.sub(r"\(.*?\)", "", raw)
        if "G53" in code:
            continue
        pos.update({a: float(v) for a, v in re.findall(r"([XYZ])(-?\d+\.?\d*)", code)})
        at[k] = [pos.get(a, np.nan) for a in "XYZ"]
    return np.array([at[int(k)] for k in lines])


@pytest.mark.parametrize("mode", list(PROGRAMS))
def test_the_map_of_a_turned_table_is_the_hand_derived_deviation(turned, mode, tmp_path):
    """Before: the hand-derived deviation at every point of the map (to 1e-6 um: the model's
    first-order errors are exact here up to their products, k e); after (from the report, and
    from the compensated program): compensate's own prediction at each block, and nothing left
    but the words' rounding (0.1 um steps: at most 0.1 um)."""
    machine, fitted, folder = turned
    setup = ProgramSetup(machine, work_offsets={0: G54})
    prog = folder / f"{mode}.nc"
    smap = program_error_map(machine, fitted, prog, report=folder / f"{mode}.csv", normal="path",
                             setup=setup)
    assert smap.line.size >= 4
    hand = _hand_um(mode, _words(mode, PROGRAMS[mode], smap.line))
    np.testing.assert_allclose(smap.dev_before * 1e3, hand, rtol=0, atol=1e-3)
    # compensate's prediction after, block by block (the report's rows, the last of each line)
    rows = {int(r["line"]): r for r in csv.DictReader(open(folder / f"{mode}.csv"))}
    predicted = np.array([[float(rows[int(k)][f"e{a}_after_um"]) for a in "xyz"] for k in smap.line])
    np.testing.assert_allclose(smap.dev_after * 1e3, predicted, rtol=0, atol=1e-4)
    assert np.abs(smap.dev_after * 1e3).max() <= 0.1
    written = program_error_map(machine, fitted, prog, folder / f"{mode}_c.nc", normal="path",
                                setup=setup)
    np.testing.assert_allclose(written.dev_after * 1e3, smap.dev_after * 1e3, rtol=0, atol=1e-6)



def test_a_g254_program_is_drawn_where_its_holes_are_on_the_part(tmp_path):
    """Where the map draws a G254 block: its tip on the part, relative to the part's datum. The
    words are along the machine's axes from the part origin O turned with the table (about C's
    line through c): the tool stands at m = c + Rz(C) (O - c) + w, which on the table (turned back)
    is c + Rz(-C) (m - c) = O + Rz(-C) w: at C 90, (Y, -X, Z) from the datum, wherever C's line
    is. With the lines off the machine origin, the words drawn as axis positions (as render did: a
    new user's second set-up's holes 40 mm from where they were cut) put them c - Rz(-C) c off."""
    from test_kinematics_single import _shifted_machine_file
    machine = load_machine(str(_shifted_machine_file(tmp_path, "cafxyz")))
    prog = tmp_path / "g254.nc"
    prog.write_text(PROGRAMS["G254"])
    fitted = FittedModel.zero(ErrorModel(machine.with_basis("polynomial"), ()))
    smap = program_error_map(machine, fitted, prog, normal="path",
                             setup=ProgramSetup(machine, work_offsets={0: G54}))
    under = (smap.line >= 8) & (smap.line <= 13)               # under G254, before G255 and G53
    words = _words("G254", PROGRAMS["G254"], smap.line[under])
    assert under.sum() >= 4 and not np.isnan(words).any()
    hand = np.column_stack([words[:, 1], -words[:, 0], words[:, 2]])
    np.testing.assert_allclose(smap.tips[under], hand, rtol=0, atol=1e-9)
