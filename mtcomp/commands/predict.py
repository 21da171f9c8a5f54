"""`mtcomp predict MACHINE MODEL.json DATA.csv -o PRED.csv`: what a model predicts for a file's rows.

PRED.csv repeats every input column verbatim and adds ``pred_<column>`` per measured column of the
file's kind (docs/identification.md): points ``pred_dx_um, pred_dy_um, pred_dz_um`` (always) and
``pred_dn_um`` (when the file has dn_um); laser ``pred_value_um`` / ``pred_value_urad``; ballbar
``pred_length_mm``; thermal ``pred_disp_<name>_um`` (and cmm, velocity as registered). Context
columns (feed, dir, t_s, temperatures, tool_mm) are used, with the context defaults the fit used.
Each ``pred_<column>`` has its standard error ``pred_<column>_sd`` (blank where the data behind the
model do not determine the prediction). A file that was part of the fit (recognised by its name) is
predicted with its fitted set-up (laser zero offsets and optic slopes, tracker frame, ball-bar
length offset), so PRED.csv reproduces the fit's residuals; any other file's set-up is unknown and
taken as zero, and the command says so.
"""
from __future__ import annotations

from . import add_cmm_arguments


def add_arguments(parser):
    parser.add_argument("machine", metavar="MACHINE", help="built-in machine name or machine TOML file")
    parser.add_argument("model", metavar="MODEL.json", help="fitted model (mtcomp identify/diagnose)")
    parser.add_argument("data", metavar="DATA.csv", help="measurement file of any kind")
    parser.add_argument("-o", "--output", metavar="PRED.csv", required=True,
                        help="output: the input columns plus pred_<column>")
    add_cmm_arguments(parser)


def run(args) -> int:
    import sys

    import numpy as np

    from . import attach_cmm_cuts, cmm_programs, note_cmm_gaps, note_outside_travel
    from ..identification.predict import predict_readings
    from ..io.atomic import check_output_path
    from ..measurement.files import read_measurements, write_csv_with_columns
    from ..machine import load_machine
    from ..models.model_file import load_model

    out = check_output_path(args.output, [args.data, args.model] + cmm_programs(args))
    machine = load_machine(args.machine)
    model_notes: list = []
    fitted = load_model(args.model, machine, model_notes)
    for n in model_notes:
        sys.stderr.write(f"note: {n}\n")
    data = read_measurements(args.data)
    attach_cmm_cuts(args, machine, [data])
    note_cmm_gaps(machine, [data])
    from ..thermal.context import has_tip_drift, record_state_note
    if data.kind != "thermal" and has_tip_drift(fitted.model) and not data.context.temperatures \
            and not np.isfinite(data.context.spindle_rpm).any():
        # no thermal state in the file: its drift is not known, and the model's reference (the
        # record's mean temperatures) is no state of this measurement
        fitted = fitted.without_drift()
        print(f"note: {args.data}: no temperatures or spindle speed: predicted without the model's "
              "thermal drift", file=sys.stderr)
    # a sensor the drift reads missing is refused; rows beyond the record's thermal range are noted
    beyond = record_state_note(fitted, data)
    pred = predict_readings(fitted, data, machine)
    note_outside_travel(machine, [data])     # once the file is predicted: a refusal is one line
    columns = pred.columns
    for note in pred.notes + ([beyond] if beyond else []):
        print(f"note: {note}", file=sys.stderr)
    ordered = {}
    for name in list(data.prediction_columns) + [k for k in columns if not k.endswith("_sd")]:
        if name in columns and name not in ordered:
            ordered[name] = columns[name]
            if f"{name}_sd" in columns:
                ordered[f"{name}_sd"] = columns[f"{name}_sd"]
    write_csv_with_columns(out, data, ordered, internal_units=False)
    print(f"wrote {out}: {len(data)} rows, columns {', '.join(ordered)}")
    return 0

