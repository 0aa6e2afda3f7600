"""postproc check: lint robot programs (and compensated outputs) as a pre-commit hook would."""
from __future__ import annotations

import sys

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
    from .compensate import add_frame_arguments

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
    p.add_argument("--model", metavar="M", help="the configured ONNX model (default: settings, else models/default.onnx)")
    p.add_argument("--config", "--frames", metavar="CONFIG_DAT", action="append",
                   help="$config.dat with BASE_DATA / TOOL_DATA (repeatable); for a Fanuc .ls: the frame file (TOML, UF/UT)")
    p.add_argument("--settings", metavar="TOML", help="pyproject.toml or postproc.toml to read (default: searched upwards)")
    p.add_argument("--fresh", action="store_true", help="check the configured source → output pairs")
    p.add_argument("--fix", action="store_true", help="with --fresh: rewrite stale or missing outputs")
    p.add_argument("--strict", action="store_true", default=None, help="warnings are findings too (exit 1)")
    p.add_argument("--ignore", metavar="CODES", default="", help="comma-separated codes not to report, e.g. P301,P213")
    p.add_argument("--max-correction", type=float, metavar="MM", help="corrections above this are findings (default 5 mm)")
    p.add_argument("--max-std", type=float, metavar="MM", help="warn (P336) where the model's own std (output "
                   "error_std) exceeds this (default: the model card's; models without error_std: no check)")
    p.add_argument("--iterations", type=int, metavar="K", help="fixed-point iterations (default: the model's)")
    add_frame_arguments(p)
    p.add_argument("--list-codes", action="store_true", help="print every diagnostic code (code, severity, meaning) and exit")
    p.add_argument("--markdown", action="store_true", help="with --list-codes: as a Markdown table (the README's)")
    p.add_argument("--robot", metavar="NAME|FILE.toml",
                   help="the robot the programs are for (default: settings 'robot'): a model trained on another is "
                   "a finding; with a description file also the nominal robot's IK reachability (needs Pinocchio)")
    p.set_defaults(run=run)


def _robot(value: str):
    """(robot name, reachability test or None) for --robot NAME or --robot FILE.toml."""
    from pathlib import Path

    if not (value.lower().endswith(".toml") or Path(value).is_file()):
        return value, None
    from ..core.diagnostics import PostprocError

    try:
        from ..robot.arm import Robot
        from ..robot.description import load_description

        robot = Robot(load_description(value))
    except ImportError as exc:
        raise PostprocError(f"--robot FILE.toml needs Pinocchio (pip install 'postproc[sim]'): {exc}", value) from None
    return robot.name, lambda poses: robot.ik(poses)[1]


def _paint(line: str, severity: str, color: bool) -> str:
    if not color:
        return line
    # bold location, red errors / yellow warnings, as ruff and compilers do
    head, sep, rest = line.partition(": ")
    code, _, message = rest.partition(" ")
    tint = "\033[31m" if severity == "error" else "\033[33m"
    return f"\033[1m{head}\033[0m{sep}{tint}{code}\033[0m {message}"


def _settings(args):
    """The settings file with the options over it: (config, codes to ignore)."""
    from ..settings.file import load_config
    from .compensate import stated_frames

    cfg = load_config(args.settings)
    if args.model:
        cfg.model = args.model
    if args.config:
        cfg.config = tuple(args.config)
    if args.strict is not None:
        cfg.strict = True
    if args.max_correction is not None:
        cfg.max_correction_mm = args.max_correction
    if args.iterations is not None:
        cfg.iterations = args.iterations
    cfg.active = stated_frames(args, cfg.active)  # (--fresh compensates with them too)
    ignore = set(cfg.ignore) | {c.strip().upper() for c in args.ignore.split(",") if c.strip()}
    return cfg, ignore


def _options(args, cfg) -> dict:
    """The options of check_files from the settings (and --robot: a name or a description)."""
    from ..compensation.findings import DEFAULT_MAX_CORRECTION_MM

    options = dict(iterations=cfg.iterations, max_correction_mm=cfg.max_correction_mm or DEFAULT_MAX_CORRECTION_MM,
                   max_std_mm=args.max_std)
    if args.robot:  # (into the settings too: --fresh compensates for the same robot)
        cfg.robot, options["reachable"] = _robot(args.robot)
    options["robot"] = cfg.robot
    return options


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
    from ..compensation.check import check_files, check_fresh, failed
    from ..core.diagnostics import EXIT_ERROR, EXIT_FINDINGS, EXIT_OK, codes_table
    from ..model.compensator import load_model
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
    cfg, ignore = _settings(args)
    model = load_model(cfg.model)
    if args.verbose:
        print(f"postproc check: model {model.name} {model.sha256[:12]} ({model.path}); settings "
              f"{cfg.path or 'none'}", file=sys.stderr)
    options = _options(args, cfg)

    findings = []
    if args.files:
        findings += check_files(args.files, model, config=list(cfg.config) if cfg.config else None, ignore=ignore,
                                active=cfg.active, **options)
    written = []
    if args.fresh:
        if not cfg.fresh and not args.quiet:
            print(f"postproc check: no fresh pairs configured ({cfg.path or 'no postproc.toml / pyproject.toml'}): "
                  "no compensated outputs to compare (add fresh = [{ source = \"src/*.src\", output = \"out/*.src\" }] "
                  "under [tool.postproc])", file=sys.stderr)
        fresh, written = check_fresh(cfg, model, fix=args.fix, ignore=ignore)
        findings += fresh
    findings = list(dict.fromkeys(findings))  # (a note of the model, P340, said once for every program)

    color = use_color(sys.stdout)
    for d in findings:
        if args.quiet and d.severity != "error" and (not cfg.strict or d.severity == "note"):
            continue
        print(_paint(d.format(), d.severity, color))
    for path in written:
        print(f"postproc check: rewrote {path}", file=sys.stderr)
    if not args.quiet:
        print(_summary(findings, cfg.strict), file=sys.stderr)
    return EXIT_FINDINGS if failed(findings, cfg.strict) else EXIT_OK
