"""postproc report: Table 2, plots and the model card from measured errors."""
from __future__ import annotations

import sys

from .settings import add, add_settings_file, settings_of

EXAMPLES = """examples:
  postproc report measured.csv --model models/cell7.onnx -o report/
  postproc report before.csv --after after.csv --model models/cell7.onnx -o report/
  postproc report --iso9283 iso_before.csv --after iso_after.csv -o cert/   (ISO 9283 + certificate)

  # on the simulated robot: measure a test plan as written and as compensated
  postproc plan -n 300 --seed 2 -o test.csv
  postproc compensate test.csv -o test_comp.csv --model m.onnx
  postproc measure test.csv -o before.csv && postproc measure test_comp.csv -o after.csv
  postproc report before.csv --after after.csv --model m.onnx -o report/

MEASURED.csv has the header x,y,z,a,b,c,x_meas,y_meas,z_meas (commanded pose, measured
position; E = (x,y,z) - (x_meas,y_meas,z_meas)). "After" is E - Ê(pose), the first-order
residual of compensating with the model, unless --after gives the positions measured when
the compensated program ran (its x_meas,y_meas,z_meas, row by row; or x_after,y_after,z_after
columns in MEASURED.csv): then it is the measured residual.

writes: report.md (Table 2: max/min/mean/std of |E| before and after, mm; the model card),
summary.json, verdict.json (pass/fail against --max-mean/--max-p95/--max-max/--max-orientation-mean,
the figures, the model's sha256; exit 1 where a limit fails; schema postproc/schemas/verdict.schema.json), series.csv + histogram.csv (the plotted numbers), error_histogram.png,
error_vectors.png, predicted_vs_measured.png (needs matplotlib: pip install 'postproc[report]').
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "report",
        parents=[common],
        formatter_class=formatter,
        help="accuracy report: Table 2, error plots, model card",
        description="Write an accuracy report of measured positioning errors before and after "
        "compensation: Table 2 figures, plots (PNG) and the model card, as Markdown + JSON.",
        epilog=EXAMPLES,
    )
    p.add_argument("measured", metavar="MEASURED.csv", help="measurement CSV (x,y,z,a,b,c,x_meas,y_meas,z_meas[,x_after,...])")
    p.add_argument("-o", "--output", metavar="DIR", required=True, help="folder to write the report into (created)")
    add_settings_file(p)
    add(p, "model", helps={"model": "ONNX compensator (default: settings 'model', else the shipped one)"})
    p.add_argument("--after", metavar="AFTER.csv",
                   help="measurement of the compensated program (same rows, same order): the measured 'after'")
    p.add_argument("--title", default="Positioning accuracy", help="heading of report.md")
    add(p, "max_mean", "max_p95", "max_max", "max_orientation_mean")
    p.add_argument("--iso9283", action="store_true",
                   help="ISO 9283 pose test: cluster rows to their poses, AP/RP per pose before (and --after) "
                   "compensation; writes iso9283.json and the certificate (certificate.md/.html/.png)")
    p.set_defaults(run=run)


def run(args) -> int:
    import matplotlib  # noqa: F401  (only to fail early: postproc.cli names the extra to install)

    from ..acceptance.report import read_report_data, write_report
    from ..model.compensator import load_model
    from ..settings import LIMITS

    settings = settings_of(args)
    limits = settings.acceptance
    if args.iso9283 and any(getattr(args, name) is not None for name in LIMITS):  # (a file's: for Table 2 reports)
        from ..core.diagnostics import P308, PostprocError

        raise PostprocError("--max-mean/--max-p95/--max-max/--max-orientation-mean hold the report's Table 2, not the "
                            "ISO 9283 pose test's AP/RP: give them without --iso9283", code=P308)
    if args.iso9283:  # the model only for the certificate's card: never a default that may be another robot's
        from .iso9283 import run_report

        return run_report(args, load_model(args.model) if args.model else None)
    from ..acceptance.verdict import failed_lines, model_entry, verdict

    model = load_model(settings.model)
    data = read_report_data(args.measured, model, args.after)
    files = write_report(data, args.output, args.title)
    from ..acceptance.report import summary as _summary

    numbers = _summary(data)
    angles = numbers["orientation_deg"]
    document = verdict("report", limits, {
        "before": numbers["table2_mm"]["before"], "after": numbers["table2_mm"]["after"],
        "orientation_before": None if angles is None else angles["before"],
        "orientation_after": None if angles is None else angles["after"], "targets": len(data)},
        model_entry(model), {"measured": args.measured, "after": args.after})
    import json
    from pathlib import Path

    from ..core.outputs import write

    files["verdict"] = Path(args.output) / "verdict.json"
    write([(files["verdict"], json.dumps(document, indent=2) + "\n")])
    if not args.quiet:
        from ..acceptance.report import summary

        numbers = summary(data)
        before, after = numbers["table2_mm"]["before"], numbers["table2_mm"]["after"]
        print(f"postproc report: {len(data)} poses, mean |E| {before['mean']:.3f} mm → {after['mean']:.3f} mm "
              f"({data.after_kind}); max {before['max']:.3f} → {after['max']:.3f} mm; wrote {files['markdown']}",
              file=sys.stderr)
        angles = numbers["orientation_deg"]
        if angles is not None:
            b, a = angles["before"], angles["after"]
            after_text = (f"{a['mean']:.4f}° (max {b['max']:.4f} → {a['max']:.4f}°)" if a is not None else
                          "not known (the model has no rotation_error output / the after data no a_meas,b_meas,c_meas)")
            print(f"postproc report: orientation error mean {b['mean']:.4f}° → {after_text}", file=sys.stderr)
        if data.trained_on:
            from ..acceptance.report import TRAINED_ON

            print(f"postproc report: warning: {TRAINED_ON}", file=sys.stderr)
        if data.outside_envelope:
            print(f"postproc report: {data.outside_envelope} poses are outside the model's envelope", file=sys.stderr)
        if args.verbose:
            for role, path in files.items():
                print(f"  {role}: {path}", file=sys.stderr)
    if not document["passed"]:
        print(f"postproc report: FAILED: {'; '.join(failed_lines(document))} (verdict.json)", file=sys.stderr)
        return 1
    return 0
