"""postproc compensate: rewrite a program with compensated target coordinates."""
from __future__ import annotations

import sys

EXAMPLES = """examples:
  postproc compensate samples/krl/cam_pocket.src -o out/cam_pocket.src
  postproc compensate samples/krl/weld_cell.src -o out/weld_cell.src --config 'samples/krl/config/$config.dat'
  postproc compensate samples/krl/backup/KRC/R1 -o out/R1     (a cell: every module, System/$config.dat found)
  postproc compensate samples/rapid/cam_contour.prg --model irb6700 -o out/cam_contour.prg
  postproc compensate samples/poses/drill_plate.csv -o out/drill_plate.csv --model models/default.onnx --strict
  YOUR_CAM_POST | postproc compensate - -o - > YOUR_PROGRAM.src   (filter: stdin → stdout)
  postproc compensate YOUR_PROGRAM.src -o out/YOUR_PROGRAM.src --robroot 0,0,2900,0,0,180   (a ceiling robot's $ROBROOT)
(samples/ and models/ are shipped, YOUR_… are your own files; quote '$config.dat': unquoted, the shell
expands $config)
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "compensate",
        parents=[common],
        formatter_class=formatter,
        help="rewrite a program with compensated target coordinates",
        description="Send every Cartesian target of a KRL (.src + .dat), ABB RAPID, URScript, Fanuc LS or "
        "pose-list program through the "
        "error model and write the program back with corrected X/Y/Z; every other byte stays as it was "
        "(partial aggregates get the X/Y/Z their correction needs written in). Exit 0: every target "
        "compensated; 1: written, but some targets left as written (the summary line says which codes); "
        "2: refused, nothing written.",
        epilog=EXAMPLES,
    )
    p.add_argument("input", metavar="IN", nargs="+",
                   help="program (.src with its .dat beside it, .mod/.prg/.sys, .script, .ls, .csv/.txt pose list) or - for "
                   "stdin (with --dialect); or a cell: "
                   "several KRL files or a directory (a controller backup KRC/R1/), compensated as one unit")
    p.add_argument("-o", "--output", metavar="OUT", required=True,
                   help="where to write (its .dat goes beside it); - for stdout; for a cell a directory (OUTDIR), "
                   "the input's tree mirrored below it")
    p.add_argument("--model", metavar="M", help="ONNX compensator (default: the shipped models/default.onnx)")
    p.add_argument("--config", "--frames", metavar="CONFIG_DAT", help="$config.dat with BASE_DATA / TOOL_DATA (for a cell "
                   "directory, default: its System/$config.dat); for a Fanuc .ls: the frame file (TOML, UF/UT)")
    add_frame_arguments(p)
    p.add_argument("--dialect", choices=["krl", "poses", "rapid", "urscript", "fanuc"],
                   help="program type for stdin (default: detected; RAPID must be named)")
    p.add_argument("--iterations", type=int, metavar="K", help="fixed-point iterations c ← P + Ê(c) (default: the model's)")
    p.add_argument("--max-correction", type=float, metavar="MM", default=None,
                   help="refuse corrections larger than this (default 5 mm)")
    p.add_argument("--max-std", type=float, metavar="MM", default=None,
                   help="warn (P336) where the model's own std (output error_std) exceeds this (default: the model "
                   "card's uncertainty.max_std_mm; models without error_std: no check)")
    p.add_argument("--strict", action="store_true", help="treat warnings as errors")
    p.add_argument("--orientation", action="store_true",
                   help="correct the orientation too: A/B/C, RAPID's quaternion, URScript's rotation vector (a model "
                   "with output rotation_error)")
    p.add_argument("--robot", metavar="NAME", help="the robot the program is for: refuse a model trained on another "
                   "(its 'robot' metadata), unless --force")
    p.add_argument("--settings", metavar="TOML", help="pyproject.toml or postproc.toml to read (default: searched "
                   "upwards from the current directory); options override its [tool.postproc] values")
    p.add_argument("--no-fill-partial", dest="fill_partial", action="store_false",
                   help="refuse (P216) partial aggregates like LIN {Z 1250} instead of writing into them the X/Y/Z "
                   "their correction needs (the controller takes missing components from the previous compensated "
                   "command)")
    p.add_argument("--in-place", action="store_true", help="allow -o to be the input itself (overwrite it)")
    p.add_argument("--force", action="store_true",
                   help="compensate anyway: an already compensated program (P401), a robot whose backup switches on "
                   "the controller's own absolute-accuracy model ($ABS_ACCUR: P408/P409; its correction and this one "
                   "then add up), another tool's or robot's program (P304/P310)")
    p.set_defaults(run=run)


def add_frame_arguments(p, settings: bool = True) -> None:
    """``--base`` / ``--tool`` / ``--robroot`` (compensate, check, verify): the frames a KRL program
    runs in where it does not set them itself (``programs.ActiveFrames``); ``settings``: their
    default is the settings' ``base`` / ``tool`` / ``robroot``."""
    default = "; default: settings '{}'" if settings else ""
    p.add_argument("--base", metavar="N|X,Y,Z,A,B,C",
                   help="the $BASE active where a KRL program has not set it: BASE_DATA[N] of $config.dat (0 = "
                   "$NULLFRAME) or the frame itself (mm, deg)" + default.format("base") + ". Without it such targets "
                   "are left as written (P220)")
    p.add_argument("--tool", metavar="N|X,Y,Z,A,B,C|model",
                   help="the $TOOL active where a KRL program has not set it (and a URScript program's TCP before its "
                   "first set_tcp): TOOL_DATA[N] of $config.dat, the frame itself, or 'model' (the model's own tool)" + default.format("tool") + ". Without it such targets "
                   "are left as written (P221)")
    p.add_argument("--robroot", metavar="X,Y,Z,A,B,C|MACHINE.DAT",
                   help="the $ROBROOT (the robot's base in $WORLD) where a KRL program has not set it: the frame (mm, "
                   "deg) or the backup's Mada/$machine.dat ($ROBROOT_C)" + default.format("robroot") + "; else the "
                   "machine data beside the System/$config.dat given, or in a backup directory; else robot base = "
                   "world is assumed and said once (P224)")
    p.add_argument("--external", metavar="UNITS.toml",
                   help="the nominal kinematics of the external units — a track that carries the robot, a turntable "
                   "or positioner that carries the part — as [[external]] tables (docs/EXTERNAL.md)"
                   + default.format("external") + "; a KRL backup's machine data give a KUKA track's. Without them, "
                   "targets that move with such a unit are left as written (P225)")


def stated_frames(args, settings=None):
    """``ActiveFrames`` of ``--base`` / ``--tool`` / ``--robroot`` over the settings' (P222 / P226)."""
    from ..core.diagnostics import P226, PostprocError
    from ..programs import ActiveFrames

    robroot = None
    if args.robroot is not None:  # (the KRL machine data's module only then)
        from ..programs.krl.machine import robroot_option

        try:
            robroot = robroot_option(args.robroot)
        except ValueError as exc:
            raise PostprocError(str(exc), "--robroot", 0, 0, P226) from None
    external = ()
    if getattr(args, "external", None):
        from ..robot.external import read_external

        external = read_external(args.external)
    return ActiveFrames.stated(args.base, args.tool, settings, robroot=robroot, external=external)


def run(args) -> int:
    from pathlib import Path

    from ..compensation.findings import DEFAULT_MAX_CORRECTION_MM
    from ..compensation.pipeline import compensate_program
    from ..core.diagnostics import EXIT_FINDINGS, EXIT_OK
    from ..programs.io import check_program_outputs, load_program
    from ..settings.file import load_config

    inputs = args.input
    cell = len(inputs) > 1 or Path(inputs[0]).is_dir()
    if not cell:  # (a cell's output directory is checked by compensate_cell)
        check_program_outputs(inputs[0], args.output, in_place=args.in_place)
    cfg = load_config(args.settings)  # [tool.postproc]: the options given here win
    args.model = args.model or cfg.model
    args.config = args.config or (list(cfg.config) if cfg.config else None)
    active = stated_frames(args, cfg.active)
    max_correction = args.max_correction if args.max_correction is not None else cfg.max_correction_mm
    kwargs = dict(
        iterations=args.iterations if args.iterations is not None else cfg.iterations,
        strict=args.strict or cfg.strict,
        force=args.force,
        max_correction_mm=DEFAULT_MAX_CORRECTION_MM if max_correction is None else max_correction,
        max_std_mm=args.max_std,
        robot=args.robot or cfg.robot,
        orientation=args.orientation,
        fill_partial=args.fill_partial,
    )
    if cell:
        from ..compensation.cell import compensate_cell
        from ..model.compensator import load_model
        from ..programs.cell import find_cell

        config = [args.config] if isinstance(args.config, str) else args.config
        report = compensate_cell(find_cell(inputs, config, active), args.output, load_model(args.model), **kwargs)
    elif inputs[0] == "-":
        from ..model.compensator import load_model

        program = load_program("-", args.config, args.dialect, active=active)
        report = compensate_program(program, load_model(args.model), **kwargs)
        if args.output != "-":
            from ..compensation.pipeline import write_outputs

            write_outputs([(Path(args.output), report.outputs[program.files[0]])])
        else:
            sys.stdout.buffer.write(report.outputs[program.files[0]].encode("latin-1"))
            sys.stdout.buffer.flush()
    else:
        from ..compensation.streaming import compensate_file

        report = compensate_file(inputs[0], args.output, args.model, config=args.config, active=active, **kwargs)
    if not args.quiet:
        from ..core.diagnostics import P340

        for w in report.warnings + [n for n in report.notes if args.verbose or n.code == P340]:
            print(w.format(), file=sys.stderr)
        print(f"postproc: {report.summary()}", file=sys.stderr)
    # like `ruff --fix` with findings left: the output is written, but not everything was done
    return EXIT_OK if report.complete else EXIT_FINDINGS
