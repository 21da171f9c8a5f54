"""`mtcomp predict MACHINE MODEL.json DATA.csv -o PRED.csv`: what a model predicts for a file's rows.

PRED.csv repeats every input column verbatim and adds ``pred_<column>`` per measured column of the
file's kind (SPEC section 5): points ``pred_dx_um, pred_dy_um, pred_dz_um`` (always) and
``pred_dn_um`` (when the file has dn_um); laser ``pred_value_um`` / ``pred_value_urad``; ballbar
``pred_length_mm``; thermal ``pred_disp_<name>_um`` (and cmm, velocity as registered). Context
columns (feed, dir, t_s, temperatures, tool_mm) are used. Nuisance parameters of the file's set-up
(laser zero offsets and optic slopes, ball-bar length offsets) are taken as zero: predicted laser
readings are the model's deviations, so compare them with readings up to the set-up's zero offset.
"""
from __future__ import annotations


def add_arguments(parser):
    parser.add_argument("machine", metavar="MACHINE", help="built-in machine name or machine TOML file")
    parser.add_argument("model", metavar="MODEL.json", help="fitted model (mtcomp identify/diagnose)")
    parser.add_argument("data", metavar="DATA.csv", help="measurement file of any kind")
    parser.add_argument("-o", "--output", metavar="PRED.csv", required=True,
                        help="output: the input columns plus pred_<column>")


def run(args) -> int:
    from ..measurement.readings import model_class_for
    from ..io.atomic import check_output_path
    from ..measurement.files import read_measurements, write_csv_with_columns
    from ..machine import load_machine
    from ..models.model_file import load_model

    out = check_output_path(args.output, [args.data, args.model])
    machine = load_machine(args.machine)
    fitted = load_model(args.model, machine)
    data = read_measurements(args.data)
    cls = model_class_for(data.kind, args.data)
    mm = cls(fitted.model, data, fitted.context_defaults, machine=machine)
    columns = mm.predict_columns(fitted.params.values, mm.zero_nuisance())
    ordered = {name: columns[name] for name in data.prediction_columns if name in columns}
    ordered.update({k: v for k, v in columns.items() if k not in ordered})
    write_csv_with_columns(out, data, ordered, internal_units=False)
    print(f"wrote {out}: {len(data)} rows, columns {', '.join(ordered)}")
    return 0
