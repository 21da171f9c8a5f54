"""Value words that no code of their block uses (``G1 Y120. Q5``): refused where the controller
refuses them, named with the word and the line.

A value word (D E H I J K L P Q R) means something only with the codes that take it: Q is G83's
peck, P G4's dwell time. Where none of the block's codes takes it the word is a typo or a leftover,
and the controllers differ (docs/toolpaths.md, "Words no code of the block uses"):

* LinuxCNC refuses the block (LinuxCNC source, ``src/emc/rs274ngc/interp_check.cc``,
  ``check_other_codes``: "Q word with no G5, G10, G64, G73, G71, G76, G83, M19, M66, M67, M68 or
  user M code that uses it", and so for every value word), as the NIST RS274/NGC interpreter does
  (Kramer, Proctor and Messina 2000); mtcomp follows LinuxCNC's table on ``linuxcnc`` and
  ``generic`` (RS274/NGC).
* grbl 1.1 refuses a value word its block does not use (``grbl/gcode.c``, unused value words,
  error 36) and has no D, E, H or Q word at all (unsupported command, error 20).
* Fanuc keeps P, Q and R as modal data on its mills, the canned cycles' data (Fanuc Series
  16/18/21 C Language Executor programming manual, B-62443EN-3, reading modal data: P, Q, R modal
  on the M series; Fanuc Series 15i-MA operator's manual: "Q ... is modal information in a canned
  cycle"): a Q on a G1 is held for a later cycle, not an alarm, and the word stays accepted on
  ``fanuc`` and on ``haas``, whose manual names no alarm for it. RepRapFirmware's G0/G1 take words
  of their own (H, E, S, P: RepRapFirmware G-code dictionary), and Heidenhain and Sinumerik
  programs are read through the G-code mtcomp writes for them: not checked there.

Which block's code takes a word is decided as the RS274/NGC interpreter does it: the motion of the
block is its G0-G3, drilling cycle or G33.1 code, else, where the block names an axis, the motion
mode in force (LinuxCNC source, ``interp_read.cc``/``rs274ngc_pre.cc``, ``enhance_block``:
``motion_to_be``); every other code is the block's own.

The same reading of a block decides which words are dimensions for :func:`check_point_words`: on
Fanuc and Haas a dimension word without a decimal point (``X60``) is read in the least input
increment (0.060 mm) by default, and is refused (docs/toolpaths.md, "Dimension words without a
decimal point"); on ``generic`` (nothing names the controller) a dimension word written with leading
zeros and no point (``X0019685``) is a fixed-format number, whose point the controller places by
its format, and is refused too (docs/toolpaths.md, "Fixed-format numbers").
"""
from __future__ import annotations

import re

from .height_map import check_map_plane

#: the value words checked here (the axis words, F, N, S, T and the codes are not value words)
VALUE_LETTERS = frozenset("DEHIJKLPQR")
#: dialects that refuse a value word no code of its block uses
CHECKED = frozenset({"linuxcnc", "generic", "grbl"})
_CYCLES = (73.0, 74.0) + tuple(float(g) for g in range(81, 90))
#: user M codes M100-M199 take P and Q (LinuxCNC G-code reference, M100 to M199)
_USER_M = (100.0, 199.0)

#: LinuxCNC (interp_check.cc, check_other_codes), letter -> (the motion codes that take it, the
#: other G codes of the block that take it, the M codes of the block that take it, whether a user
#: M code takes it). The splines G5, G5.1, G5.2 are LinuxCNC's motion codes; mtcomp refuses them
#: with coordinates and passes Fanuc's G05 P10000 and G05.1 Q1 (contour control modes) through, so
#: they count as codes of the block. So do the other codes mtcomp reads or passes through on every
#: dialect with a word: G43.4, G44 and Haas' G234 (H), G08 P (look-ahead), G54.1 P (Fanuc's added work
#: systems), Haas' G103 P and G187 P E.
_MODE_P = (5.0, 5.2, 8.0, 54.1, 103.0, 187.0)
_NGC = {
    "D": ((), (41.0, 41.1, 42.0, 42.1, 96.0), (), False),
    "E": ((76.0,), (187.0,), (66.0, 67.0, 68.0), False),
    "H": ((76.0,), (43.0, 43.2, 43.4, 44.0, 234.0), (), False),
    "I": ((2.0, 3.0, 71.0, 76.0, 87.0), (5.0, 5.1, 10.0), (), False),
    "J": ((2.0, 3.0, 71.0, 76.0, 87.0), (5.0, 5.1, 10.0), (), False),
    "K": ((2.0, 3.0, 33.0, 33.1, 71.0, 76.0, 87.0), (), (), False),
    "L": ((71.0, 73.0, 76.0) + tuple(float(g) for g in range(81, 90)),
          (5.2, 10.0, 41.0, 41.1, 42.0, 42.1), (66.0,), False),
    "P": ((2.0, 3.0, 71.0, 74.0, 76.0, 82.0, 84.0, 86.0, 88.0, 89.0), (4.0, 10.0, 64.0) + _MODE_P,
          (19.0, 50.0, 51.0, 52.0, 53.0, 62.0, 63.0, 64.0, 65.0, 66.0), True),
    "Q": ((71.0, 73.0, 76.0, 83.0), (5.0, 5.1, 10.0, 64.0), (19.0, 61.0, 66.0, 67.0, 68.0), True),
    # (LinuxCNC's M19 R, the orientation angle, is refused before this table: mtcomp reads R
    # only on arcs, cycles and the frame codes)
    "R": ((2.0, 3.0, 71.0, 76.0) + _CYCLES, (10.0, 41.1, 42.1), (), False),
}
#: grbl 1.1 (gcode.c): letter -> (motion codes, other G codes of the block) that take it; an arc's
#: I J K only without R (with R they are unused: error 36)
_GRBL = {
    "I": ((2.0, 3.0), ()), "J": ((2.0, 3.0), ()), "K": ((2.0, 3.0), ()),
    "L": ((), (10.0,)), "P": ((), (4.0, 10.0)), "R": ((2.0, 3.0), ()),
}


def block_motion(state, motion, cycle, axes_given, own_axes, letters) -> float | None:
    """The motion code that takes the block's words (RS274/NGC's ``motion_to_be``): its own G0-G3,
    drilling cycle or G33.1, else (where it names an axis its group-0 code does not take) the mode
    in force; an arc's I J K alone continue the arc in force. None: no motion code."""
    if motion is not None:
        return float(motion)
    if cycle is not None:
        return float(cycle)
    if state.tap_line:
        return 33.1
    if axes_given and not own_axes:
        if state.cycle is not None:
            return float(state.cycle)
        if state.tapping:
            return 33.1
        return None if state.motion is None else float(state.motion)
    if state.motion in (2, 3) and letters & set("IJK"):
        return float(state.motion)
    return None


def check_motion_mode(state, values, arc_words, line: int) -> None:
    """On every dialect: a move needs a motion mode, arc words only in G2/G3, and an F on each G93
    feed move."""
    if state.motion is None:
        raise state._err("coordinates without a motion mode (no G0/G1/G2/G3 in force; a "
                         "controller's power-on mode is not assumed: write G0 or G1 in this "
                         "block)", line)
    if state.motion in (2, 3):
        check_map_plane(state, line)
    if state.motion in (0, 1) and arc_words:
        raise state._err(f"{arc_words[0]} word in a G{state.motion} block (only G2/G3 take I J K "
                         "R)", line)
    if state.inverse_time and state.motion != 0 and "F" not in values:
        raise state._err(f"G93 (inverse time feed): the G{state.motion} block has no F word", line)


def check_value_words(state, tokens, gcodes, mcodes, motion, cycle, axes_given, own_axes,
                      line: int) -> None:
    """Refuse (InputError naming the word and the line) a value word that no code of the block
    takes, on the dialects whose controller refuses it (:data:`CHECKED`). ``motion``, ``cycle``:
    the block's own motion and drilling cycle codes (or None); ``own_axes``: a group-0 code of the
    block (G4, G10, G28, G30, G52, G92 ...) takes its axis words."""
    dialect = state.dialect.name
    if dialect not in CHECKED:
        return
    words = [(t[0], float(t[1])) for t in tokens if t[0] in VALUE_LETTERS]
    if 39.0 in gcodes:           # uCNC's height map takes I J R (.height_map)
        words = [w for w in words if w[0] not in "IJR"]
    if not words:
        return
    letters = {letter for letter, _v in words}
    mode = block_motion(state, motion, cycle, axes_given, own_axes, letters)
    where = f"a G{mode:g} block" if mode is not None else "a block without motion"
    for letter, value in words:
        if dialect == "grbl" and mode not in _CYCLES:
            # grbl has no drilling cycles; mtcomp reads them on every dialect, with their words
            why = _grbl_problem(letter, mode, gcodes, letters)
        elif dialect == "generic" and _generic_use(letter, value, mode, gcodes):
            why = ""
        else:
            why = _ngc_problem(letter, mode, gcodes, mcodes, dialect)
        if why:
            raise state._err(f"{letter} word in {where}: no code of the block uses it ({why})",
                             line)


def _generic_use(letter, value, mode, gcodes) -> bool:
    """The words a program that names no controller may hold beyond LinuxCNC's table, because
    mtcomp reads them so on every dialect: I J K on a drilling cycle's line (Fanuc's repeat count
    K, Haas' peck words I J K of G73/G83), and G49 H0 (Centroid's and Fanuc's posts: no offset,
    as G49 says)."""
    if letter in "IJK":
        return mode in _CYCLES
    return letter == "H" and value == 0 and 49.0 in gcodes


def _ngc_problem(letter, mode, gcodes, mcodes, dialect) -> str:
    """'' where a code of the block takes ``letter`` (LinuxCNC's table), else why not."""
    motions, codes, ms, user = _NGC[letter]
    if mode in motions or any(g in codes for g in gcodes) or any(m in ms for m in mcodes):
        return ""
    if user and any(_USER_M[0] <= m <= _USER_M[1] for m in mcodes):
        return ""
    takers = [f"G{g:g}" for g in _followed(letter, motions + codes)] + [f"M{m:g}" for m in ms]
    takers += ["M100-M199"] if user else []
    if dialect == "linuxcnc":
        return f"{letter} goes with {' '.join(takers)}; LinuxCNC refuses such a block"
    # a program that names no controller: a Fanuc or Haas post's words (a G83 dwell P, G40 D0)
    # are theirs to take
    return (f"{letter} goes with {' '.join(takers)}; RS274/NGC controllers (LinuxCNC) refuse such "
            "a block: give --dialect fanuc or haas if one of them runs the program")


def _followed(letter, codes):
    """The codes of a word's table that mtcomp reads with it (the others are refused by name
    anyway, and so is an arc's P, its turns)."""
    refused = {5.0, 5.1, 5.2, 8.0, 33.0, 54.1, 71.0, 74.0, 76.0, 103.0, 187.0} | (
        {2.0, 3.0} if letter == "P" else set())
    return [g for g in codes if g not in refused]


def _grbl_problem(letter, mode, gcodes, letters) -> str:
    """'' where a code of the block takes ``letter`` on grbl 1.1, else why not."""
    if letter not in _GRBL:
        return f"grbl has no {letter} word: error 20, unsupported command"
    motions, codes = _GRBL[letter]
    used = mode in motions or any(g in codes for g in gcodes)
    if used and letter in "IJK" and "R" in letters:
        used = False                    # a radius arc: grbl leaves I J K unused
    if used:
        return ""
    takers = " ".join(f"G{g:g}" for g in motions + codes)
    return f"on grbl {letter} goes with {takers}; grbl refuses it: error 36, unused value word"


#: dialects whose controllers read a dimension word without a decimal point in the least input
#: increment (Fanuc Series 0i-MODEL F operator's manual, "decimal point programming": X1 is 0.001 mm
#: under G21, 0.0001 in under G20, unless calculator-type input is set, parameter 3401#0 DPI; Haas
#: Automation, "Help with the decimal points": likewise unless Setting 162, Default To Float, is on)
POINT_DIALECTS = frozenset({"fanuc", "haas"})
_AXIS_WORDS = frozenset("XYZABCUVW")


def check_point_words(state, tokens, motion, cycle, axes_given, own_axes, line: int) -> None:
    """Refuse, on Fanuc and Haas, a dimension word other than zero written without a decimal point
    (``X60``): the controller reads it in the least input increment (0.060 mm), or as 60 mm where
    calculator-type input is set, a setting of the machine the program does not show. mtcomp would
    read one and write the corrected word with a point, which every controller reads as mm: a move
    of 60 mm where the controller made one of 0.06. Dimension words: the axis words, an arc's
    I J K R, a drilling cycle's R I J, the peck Q of G73/G83 and G68's rotation angle R (a dwell's
    X or P, a cycle's repeat count K, G5.1's Q are not). On ``generic`` only a dimension word with
    leading zeros is refused (:func:`_fixed_problem`): RS274/NGC reads the others in whole units.
    Where the machine file says the control reads whole units (``calculator_input``: Fanuc
    parameter 3401#0 DPI = 1, Haas Setting 162 on) the word is read so, as it is everywhere else,
    and written back with its point, which the control reads alike."""
    fixed_only = state.dialect.name == "generic"
    if state.dialect.name not in POINT_DIALECTS and not fixed_only:
        return
    calculator = state.machine.calculator_input and not fixed_only
    letters = {t[0] for t in tokens}
    mode = block_motion(state, motion, cycle, axes_given, own_axes, letters)
    gcodes = [float(t[1]) for t in tokens if t[0] == "G"]
    dwell, rotation = 4.0 in gcodes, 68.0 in gcodes
    for t in tokens:
        letter, number = t[0], t[1]
        try:
            if "." in number or float(number) == 0:
                continue
        except ValueError:              # a word whose value is not a plain number
            continue
        if fixed_only and not _LEADING_ZERO.match(number):
            continue
        if letter == "F" and fixed_only:
            continue
        if letter == "F":
            _integer_feed(state, number, line)
            continue
        if letter in _AXIS_WORDS:
            dimension = not (dwell and letter in "XU")
        elif rotation and letter == "R":          # the angle of G68, in 0.001 deg without a point
            dimension = True
        elif mode in (2.0, 3.0):
            dimension = letter in "IJKR"
        elif mode in _CYCLES:
            dimension = letter in "RIJ" or (letter == "Q" and mode in (73.0, 83.0))
        else:
            dimension = False
        if dimension and calculator:
            _calculator_input_note(state, f"{letter}{number}", line)
        elif dimension:
            angle = letter in "ABC" or (rotation and letter == "R")
            word = f"{letter}{number}"
            raise state._err(_fixed_problem(word) if fixed_only
                             else _point_problem(state, word, angle), line)


def _calculator_input_note(state, word: str, line: int) -> None:
    """Say once, in the program's notes, that its words without a point are read in whole units
    because the machine file says so (the one place a reader of the summary learns it)."""
    notes = getattr(state._source, "notes", None)
    if notes is None or any(n.startswith("note: dimension words without") for n in notes):
        return
    _path, at, _suffix = state._where(line)
    notes.append(f"note: dimension words without a decimal point (first {word}, line {at}) read "
                 f"in whole units, as a {state.dialect.name.capitalize()} reads them where "
                 f"{_WHOLE_UNITS[state.dialect.name]} (the machine file's calculator_input = "
                 "true); the corrected words are written with a point")


def _integer_feed(state, number: str, line: int) -> None:
    """An F word without a decimal point on Fanuc or Haas. Fanuc reads a feed per minute in whole
    mm/min (F300: 300 mm/min) whatever parameter 3401#0 says, but an inverse time (G93) in
    thousandths (F1: 0.001 1/min) unless it is set (``calculator_input`` of the machine: whole
    units then; Fanuc Series 16/18-MC operator's manual,
    B-62764EN/01, "Feed functions", inverse time feed); a Haas reads every F without a point as its
    Setting 77 (Scale Integer F) says: in 0.001 mm/min (0.0001 in/min) at its default, whole units
    at INTEGER (Haas mill operator's manual, Settings). Refused under G93, whose F mtcomp writes
    anew for each piece of a block it splits, and on a Haas where the corrections depend on the
    feed (``feed_use`` of the program: a model's feed terms, temperatures looked up at each
    block's time); otherwise read in whole units, a Haas program's said once in its notes."""
    name, word = state.dialect.name, f"F{number}"
    value = float(number)
    if state.inverse_time and not (name == "fanuc" and state.machine.calculator_input):
        setting = ("parameter 3401#0 (DPI) is set" if name == "fanuc"
                   else "Setting 77 (Scale Integer F) is INTEGER")
        raise state._err(f"{word} has no decimal point under G93 (inverse time): a "
                         f"{name.capitalize()} reads it as {value * 1e-3:g} 1/min unless {setting}, "
                         "which the program does not show, and mtcomp writes each split block's F "
                         f"from it: write {word}. for {value:g} 1/min", line)
    if name != "haas":
        return
    unit, default = ("in/min", value * 1e-4) if state.inch else ("mm/min", value * 1e-3)
    use = getattr(state._source, "feed_use", "")
    said = (f"a Haas reads {word} as Setting 77 (Scale Integer F) says: {default:g} {unit} at its "
            f"default, {value:g} {unit} at INTEGER")
    if use:
        raise state._err(f"{word} has no decimal point: {said}, which the program does not show, "
                         f"and {use} make the corrections depend on the feed: write {word}. for "
                         f"{value:g} {unit}", line)
    notes = getattr(state._source, "notes", None)
    if notes is not None and not any(n.startswith("note: F words without") for n in notes):
        path, at, _suffix = state._where(line)
        notes.append(f"note: F words without a decimal point (first {word}, line {at}) read in "
                     f"whole {unit}: {said}; nothing the corrections depend on uses the feed")


#: a number written with a leading zero before another digit and no point (``0019685``)
_LEADING_ZERO = re.compile(r"\s*[-+]?\s*0+[1-9]")


def _fixed_problem(word: str) -> str:
    """A fixed-format number (EIA RS-274-D, "Interchangeable variable block data format for
    positioning, contouring, and contouring/positioning numerically controlled machines", 1979:
    a word without a decimal point is read by the format detail of the controller, `X+24` placing
    the point before the last four digits): nothing says where its point lies."""
    return (f"{word} is a fixed-format number (leading zeros, no decimal point): its controller "
            "places the decimal point by its format (in a 3.4 format X0019685 is 1.9685), which "
            "the program does not show; say the format in the machine file (fixed_format = "
            "\"3.4\") where the controller reads one, or give --dialect linuxcnc or grbl if it "
            "reads whole units")


#: the machine setting under which a word without a point is read in whole units
_WHOLE_UNITS = {"fanuc": "calculator-type input is set (parameter 3401#0 DPI)",
                "haas": "Setting 162 (Default To Float) is on"}


def _point_problem(state, word: str, angle: bool) -> str:
    unit = "0.001 deg" if angle else "0.0001 in" if state.inch else "0.001 mm"
    name = state.dialect.name
    return (f"{word} has no decimal point: a {name.capitalize()} reads it in the least input "
            f"increment ({unit}) unless {_WHOLE_UNITS[name]}, which the program does not show; "
            f"write {word}. for whole units, or say calculator_input = true in the machine file "
            "where the control is set so")
