"""Fanuc's G60, single-direction positioning (FANUC Series 0i-MODEL C / 0i Mate-MODEL C Operator's
Manual B-64124EN, "Single direction positioning (G60)"; FANUC Series 0-MB Operator's Manual,
section 4.2): ``G60 IP_`` positions the axes at the end point IP_, approaching it always from
one direction, with an overrun, both set by the control's parameter No. 5440 (the tool stops once
before the end point even when it already moves in that direction). G60 is a one-shot code of
group 00, or, with parameter No. 5431#0 (MDL) set, a modal code of group 01.

So the block's end point is the one written, but the direction each axis last moves in (the one
the error model's backlash and reversal terms depend on) is a parameter's, not the program's:
mtcomp passes the line through as written, uncorrected, the axes it names at their written values
after it (in the program and in the output alike) and their approach direction unknown for the
blocks after it. Which motion mode holds after the line is known only where a G00 follows the
G60 on the line (of two codes of one group on a line the last holds: with MDL G00 replaces G60,
without it G60 holds for its block only); otherwise none is taken, and axis words without a
motion code are refused until the program gives one.
"""
from __future__ import annotations

from .passed import passed_end

__all__ = ["single_direction"]


def single_direction(state, values, axes_given, gcodes, codes, line: int) -> None:
    """The G60 line (``state`` the reader's :class:`~.modal.ModalState`; codes : (motion, cycle,
    home move, axis words that are no motion) of the line): passed through uncorrected, its end
    known, the named axes' last approach parameter No. 5440's (:func:`.passed.passed_end`).
    Refused where its path or end would not be the written point's: with G01-G03, a drilling
    cycle, a home move, a dwell, G10 or a frame code on the line or a drilling cycle in force,
    under cutter radius compensation or a frame change (G68, mirror image, scaling), or an
    incremental word of an axis not known."""
    motion, cycle, home_move, nonmotion = codes
    problem = (f"with motion G{motion}" if motion not in (None, 0) else
               f"with G{cycle or home_move}" if cycle is not None or home_move is not None else
               "with a dwell, G10 or a frame code" if nonmotion else
               "in a drilling cycle (G80 first)" if state.cycle is not None and axes_given else
               "under cutter radius compensation" if state.cutter_comp else
               "under a frame change (G68, mirror image, scaling)" if state.local.kind else "")
    if problem:
        raise state._err(f"G60 (single-direction positioning) {problem}", line)
    blind = [c for c in axes_given if state.incremental and not state.known[state.names.index(c)]]
    if blind:
        raise state._err(f"incremental (G91) move of axis {blind[0]}, whose position the program "
                         "has not given (at the start, or after a home move, tool change or "
                         "offset change)", line)
    # G00 after G60 on the line holds after it; else G60 may hold (parameter MDL): no mode taken
    state.motion = 0 if motion == 0 and gcodes.index(0.0) > gcodes.index(60.0) else None
    state.cycle = None
    state.had_g = True                  # the writer follows the mode it leaves
    if axes_given:
        passed_end(state, values, axes_given, "single", line)
