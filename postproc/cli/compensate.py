"""postproc compensate: rewrite a program with compensated target coordinates."""
from __future__ import annotations

import sys

from .settings import ROBOT_HELP, add, add_settings_file, settings_of

EXAMPLES = """examples:
  postproc compensate samples/krl/cam_pocket.src -o out/cam_pocket.src
  postproc compensate samples/krl/weld_cell.src -o out/weld_cell.src --config 'samples/krl/config/$config.dat'
  postproc compensate samples/krl/backup/KRC/R1 -o out/R1     (a cell: every module, System/$config.dat found)
  postproc compensate samples/rapid/cam_contour.prg --model irb6700 -o out/cam_contour.prg
  postproc compensate YOUR_BACKUP/ --model irb6700 -o out/BACKUP     (an ABB backup: RAPID/TASKn, SYSPAR read)
  postproc compensate Data.mod Main.mod --model irb6700 -o out/task   (RAPID modules given together: one task)
  postproc compensate samples/fanuc/backup --model r2000ic -o out/fanuc   (a Fanuc backup: every .ls, its .va)
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
                   "stdin (with --dialect); or a cell: several files of one robot or a directory (a controller backup: "
                   "KUKA KRC/R1/, ABB with RAPID/TASKn/ and SYSPAR/, Fanuc with its .ls and .va files), compensated as "
                   "one unit: KRL modules with their data lists and $config.dat, the RAPID modules of a task, every "
                   ".ls; each URScript program and pose list on its own. Every file given is read or the run refuses; "
                   "programs of two robot families are refused (P119)")
    p.add_argument("-o", "--output", metavar="OUT", required=True,
                   help="where to write (its .dat goes beside it); - for stdout; for a cell a directory (OUTDIR), "
                   "the input's tree mirrored below it")
    add_settings_file(p)
    add(p, "model", "config", "base", "tool", "robroot", "external", "dialect", "iterations", "max_correction_mm",
        "max_std_mm", "strict", "orientation", "robot", "fill_partial", "force", "registers", "load",
        "payloads", helps={"robot": ROBOT_HELP + ": a model trained on another is refused (its 'robot' metadata), unless "
               "--force; with a description file also the nominal robot's IK reach (P309)"})
    p.add_argument("--in-place", action="store_true", help="allow -o to be the input itself (overwrite it)")
    p.set_defaults(run=run)


def joints_text(model) -> str | None:
    """What ``compensate -v`` says of a model whose ``joints`` input decides the arm configuration
    (model.card.configuration_text) and what compensate feeds it; None for other models."""
    from ..model.card import configuration_text

    text = configuration_text(model)
    if text is None:
        return None
    return (f"model {model.name}: {text}. compensate feeds it each target's joint angles: the program's own where "
            "it writes them (a pose list's q1..q6), else those of the configuration its S/T state, else of the one "
            "the controller keeps there (a KRL LIN/CIRC, a target without S/T: that of the motion before it or of the "
            "axis values a joint motion left; before the program's first, the model's own branch); a target without "
            "any is left as written (P309)")


def run(args) -> int:
    from pathlib import Path

    from ..compensation.api import model_of
    from ..compensation.pipeline import compensate_program
    from ..core.diagnostics import EXIT_FINDINGS, EXIT_OK, P236, P323, P339, P340
    from ..programs.io import check_program_outputs, load_program

    inputs = args.input
    cell = len(inputs) > 1 or Path(inputs[0]).is_dir()
    if not cell:  # (a cell's output directory is checked by compensate_cell)
        check_program_outputs(inputs[0], args.output, in_place=args.in_place)
    settings = settings_of(args)
    reading = settings.reading
    if cell:
        from ..compensation.cell import compensate_cell
        from ..programs.cell import find_cell

        report = compensate_cell(find_cell(inputs, reading.config_list, reading.active), args.output,
                                 model_of(settings.model), settings)
    elif inputs[0] == "-":
        program = load_program("-", reading.config_list, reading.dialect, reading.active)
        report = compensate_program(program, model_of(settings.model), settings)
        if args.output != "-":
            from ..compensation.pipeline import write_outputs

            write_outputs([(Path(args.output), report.outputs[program.files[0]])])
        else:
            sys.stdout.buffer.write(report.outputs[program.files[0]].encode("latin-1"))
            sys.stdout.buffer.flush()
    else:
        from ..compensation.streaming import compensate_file

        report = compensate_file(inputs[0], args.output, settings.model, settings=settings)
    if not args.quiet:
        if args.verbose:  # (the model loaded again: its session from the cache, session.py)
            said = joints_text(model_of(settings.model))
            if said:
                print(f"postproc: {said}", file=sys.stderr)
        for w in report.warnings + [n for n in report.notes if args.verbose or n.code in (P340, P323, P236, P339)]:
            print(w.format(), file=sys.stderr)
        if len(report.written) > 1:  # (several files: what each file written holds; the summary stays last)
            for line in report.files_summary():
                print(f"postproc:   {line}", file=sys.stderr)
        print(f"postproc: {report.summary()}", file=sys.stderr)
    # like `ruff --fix` with findings left: the output is written, but not everything was done
    return EXIT_OK if report.complete else EXIT_FINDINGS
