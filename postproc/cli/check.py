"""postproc check: lint robot programs (and compensated outputs) as a pre-commit hook would."""
from __future__ import annotations

import sys

from .settings import ROBOT_HELP, add, add_settings_file, settings_of

EXAMPLES = """examples:
  postproc check src/*.src out/*.src             syntax, reach, envelope, stamps of these programs
  postproc check KRC/R1                          a cell: every module, with its System/$config.dat
  postproc check part.csv --model models/cell7.onnx --strict --ignore P301
  postproc check --fresh                         outputs of [tool.postproc] fresh pairs up to date?
  postproc check --fresh --fix                   ... and re-compensate the stale ones
  postproc check --list-codes                    every diagnostic code, its severity and meaning
  postproc check weld.src --robot models/kr500.toml   the model is for this robot? its IK reaches? (postproc[sim])

settings: [tool.postproc] in pyproject.toml or postproc.toml, found from the current directory
upwards (model, config, robot, base, tool, robroot, strict, max_correction, iterations, ignore, fresh); options
override them.
output: one `path:line:col: CODE message` line per finding on stdout.
exit: 0 clean (warnings only, unless --strict), 1 findings, 2 usage or internal error.
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "check",
        parents=[common],
        formatter_class=formatter,
        help="check programs: syntax, reach, envelope, model stamps, stale outputs",
        description="Report what would make `postproc compensate` refuse or warn (syntax errors, targets "
        "beyond reach or outside the model's envelope, NaN), programs compensated with another model or "
        "twice, and (--fresh) compensated outputs that no longer match their sources.",
        epilog=EXAMPLES,
    )
    p.add_argument("files", nargs="*", metavar="FILE", help="programs (.src/.dat, .mod/.prg/.sys, .script, .ls, .csv/.txt) or directories (searched for every "
                   "dialect's programs but pose lists), checked as one cell: a .dat is checked with its .src, a $config.dat among them configures the others, a data list "
                   "without DEF is checked for syntax")
    add_settings_file(p)
    p.add_argument("--fresh", action="store_true", help="check the configured source → output pairs")
    p.add_argument("--fix", action="store_true", help="with --fresh: rewrite stale or missing outputs")
    add(p, "model", "config", "strict", "ignore", "max_correction_mm", "max_std_mm", "iterations", "base", "tool",
        "robroot", "external", "robot", "registers", "load", "payloads",
        helps={"model": "the configured ONNX model (default: settings, else models/default.onnx)",
               "strict": "warnings are findings too (exit 1)",
               "max_correction_mm": "corrections above this are findings (default 5 mm)",
               "robot": ROBOT_HELP + " (default: settings 'robot'): a model trained on another is a finding; with a "
               "description file also the nominal robot's IK reachability (P309)"})
    p.add_argument("--list-codes", action="store_true", help="print every diagnostic code (code, severity, meaning) and exit")
    p.add_argument("--markdown", action="store_true", help="with --list-codes: as a Markdown table (the README's)")
    p.set_defaults(run=run)


def _paint(line: str, severity: str, color: bool) -> str:
    if not color:
        return line
    # bold location, red errors / yellow warnings, as ruff and compilers do
    head, sep, rest = line.partition(": ")
    code, _, message = rest.partition(" ")
    tint = "\033[31m" if severity == "error" else "\033[33m"
    return f"\033[1m{head}\033[0m{sep}{tint}{code}\033[0m {message}"


def _summary(findings, strict: bool) -> str:
    notes = sum(d.severity == "note" for d in findings)
    said = f" ({notes} note{'s' * (notes != 1)})" if notes else ""
    findings = [d for d in findings if d.severity != "note"]
    if not findings:
        return "postproc check: clean" + said
    errors = sum(d.severity == "error" for d in findings)
    warnings = len(findings) - errors
    programs = len({d.path for d in findings})
    return (f"postproc check: {errors} error{'s' * (errors != 1)}, {warnings} warning{'s' * (warnings != 1)} "
            f"in {programs} file{'s' * (programs != 1)}" + (" (--strict: warnings count)" if strict and warnings else "")
            + said)


def run(args) -> int:
    from ..compensation.api import model_of
    from ..compensation.check import check_files, check_fresh, failed
    from ..core.diagnostics import EXIT_ERROR, EXIT_FINDINGS, EXIT_OK, codes_table
    from . import use_color

    if args.list_codes:
        sys.stdout.write(codes_table(markdown=args.markdown))
        return EXIT_OK
    if not args.files and not args.fresh:
        print("postproc check: give programs to check, or --fresh (see postproc check --help)", file=sys.stderr)
        return EXIT_ERROR
    if args.fix and not args.fresh:
        print("postproc check: --fix works with --fresh only", file=sys.stderr)
        return EXIT_ERROR
    settings = settings_of(args)
    model = model_of(settings.model)
    if args.verbose:
        print(f"postproc check: model {model.name} {model.sha256[:12]} ({model.path}); settings "
              f"{settings.path or 'none'}", file=sys.stderr)

    findings = []
    if args.files:
        findings += check_files(args.files, model, settings)
    written = []
    if args.fresh:
        if not settings.check.fresh and not args.quiet:
            print(f"postproc check: no fresh pairs configured ({settings.path or 'no postproc.toml / pyproject.toml'}): "
                  "no compensated outputs to compare (add fresh = [{ source = \"src/*.src\", output = \"out/*.src\" }] "
                  "under [tool.postproc])", file=sys.stderr)
        fresh, written = check_fresh(settings, model, fix=args.fix)
        findings += fresh
    findings = list(dict.fromkeys(findings))  # (a note of the model, P340, said once for every program)

    strict = settings.rules.strict
    color = use_color(sys.stdout)
    for d in findings:
        if args.quiet and d.severity != "error" and (not strict or d.severity == "note"):
            continue
        print(_paint(d.format(), d.severity, color))
    for path in written:
        print(f"postproc check: rewrote {path}", file=sys.stderr)
    if not args.quiet:
        print(_summary(findings, strict), file=sys.stderr)
    return EXIT_FINDINGS if failed(findings, strict) else EXIT_OK
