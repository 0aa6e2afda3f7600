"""Arguments → Settings: the flags of every setting, declared once, and the one function that
turns a subcommand's arguments into its :class:`~postproc.settings.Settings`.

A subcommand adds the settings it takes with :func:`add` (their flags and help come from
:data:`ARGUMENTS`; a subcommand may say its own help); :func:`settings_of` reads the settings
file (where the subcommand takes ``--settings``: the file given, else the one found upwards
from the current directory) and applies the flags given over it (a flag not given is None:
the file's value, else the default, stands). The option names, sections and checks are
``postproc.settings.OPTIONS``'; the argparse destination of each flag is its option's name.
"""
from __future__ import annotations

__all__ = ["ARGUMENTS", "add", "add_settings_file", "settings_of"]

_FRAME = "; default: settings '{}'"
ROBOT_HELP = ("the robot: its name as a model card says it (e.g. KR500-sim), a shipped robot (kr500, irb6700, "
              "r2000ic, ur10) or its description file (FILE.toml)")

# option name → (flags, argparse keywords); every dest is the option's name
ARGUMENTS: dict[str, tuple[tuple[str, ...], dict]] = {
    "model": (("--model",), dict(metavar="M", help="ONNX compensator, or a shipped model's name (default: settings "
                                 "'model', else the shipped models/default.onnx)")),
    "robot": (("--robot",), dict(metavar="NAME|FILE.toml", help=ROBOT_HELP)),
    "config": (("--config", "--frames"), dict(metavar="CONFIG_DAT", action="append", help=(
        "$config.dat with BASE_DATA / TOOL_DATA (repeatable; for a cell directory, default: its "
        "System/$config.dat); for a Fanuc .ls: the frame file (TOML, UF/UT)"))),
    "dialect": (("--dialect",), dict(choices=["krl", "poses", "rapid", "urscript", "fanuc"],
                                     help="program type for stdin (default: detected; RAPID must be named)")),
    "base": (("--base",), dict(metavar="N|X,Y,Z,A,B,C", help=(
        "the $BASE active where a KRL program has not set it: BASE_DATA[N] of $config.dat (0 = $NULLFRAME) or the "
        "frame itself (mm, deg){default}. Without it such targets are left as written (P220)"))),
    "tool": (("--tool",), dict(metavar="N|X,Y,Z,A,B,C|model", help=(
        "the $TOOL active where a KRL program has not set it (and a URScript program's TCP before its first "
        "set_tcp): TOOL_DATA[N] of $config.dat, the frame itself, or 'model' (the model's own tool){default}. "
        "Without it such targets are left as written (P221)"))),
    "robroot": (("--robroot",), dict(metavar="X,Y,Z,A,B,C|MACHINE.DAT", help=(
        "the $ROBROOT (the robot's base in $WORLD) where a KRL program has not set it: the frame (mm, deg) or the "
        "backup's Mada/$machine.dat ($ROBROOT_C){default}; else the machine data beside the System/$config.dat "
        "given, or in a backup directory; else robot base = world is assumed and said once (P224)"))),
    "external": (("--external",), dict(metavar="UNITS.toml", help=(
        "the nominal kinematics of the external units — a track that carries the robot, a turntable or positioner "
        "that carries the part — as [[external]] tables (docs/EXTERNAL.md){default}; a KRL backup's machine data "
        "give a KUKA track's. Without them, targets that move with such a unit are left as written (P225)"))),
    "registers": (("--registers",), dict(choices=["backup", "runtime"], help=(
        "a controller backup's registers (Fanuc posreg.va / numreg.va): 'backup' uses the values the backup holds "
        "where no program read writes the register, and says so (P234); 'runtime' makes them run-time values "
        "(a PLC, vision or KAREL writes them){default}"))),
    "load": (("--load",), dict(metavar="MASS[,CX,CY,CZ]", help=(
        "the payload in force where the program sets none (kg; centre of mass in mm in the flange frame, default "
        "0,0,0){default}; only a model that takes the load uses it (without it: the load the model was measured "
        "with, said once: P339)"))),
    "payloads": (("--payload",), dict(metavar="N=MASS[,CX,CY,CZ]", action="append", help=(
        "payload schedule N of the controller, which a Fanuc program selects with PAYLOAD[N] (repeatable){default}; "
        "without it such targets are left as written where the model takes the load (P235)"))),
    "iterations": (("--iterations",), dict(metavar="K", help=(
        "fixed-point iterations c ← P + Ê(c) (default: the model's)"))),
    "max_correction_mm": (("--max-correction",), dict(metavar="MM", help=(
        "refuse corrections larger than this (default 5 mm)"))),
    "max_std_mm": (("--max-std",), dict(metavar="MM", help=(
        "warn (P336) where the model's own std (output error_std) exceeds this (default: the model card's "
        "uncertainty.max_std_mm; models without error_std: no check)"))),
    "strict": (("--strict",), dict(help="treat warnings as errors")),
    "force": (("--force",), dict(help=(
        "compensate anyway: an already compensated program (P401), a robot whose backup switches on the "
        "controller's own absolute-accuracy model ($ABS_ACCUR: P408/P409; its correction and this one then add "
        "up), another tool's or robot's program (P304/P310)"))),
    "orientation": (("--orientation",), dict(help=(
        "correct the orientation too: A/B/C, RAPID's quaternion, URScript's rotation vector (a model with output "
        "rotation_error)"))),
    "fill_partial": (("--no-fill-partial",), dict(help=(
        "refuse (P216) partial aggregates like LIN {Z 1250} instead of writing into them the X/Y/Z their "
        "correction needs (the controller takes missing components from the previous compensated command)"))),
    "ignore": (("--ignore",), dict(metavar="CODES", help="comma-separated codes not to report, e.g. P301,P213")),
    "method": (("--method",), dict(help="the model (default hybrid; see below)")),
    "hidden": (("--hidden",), dict(metavar="W,W,...", help=(
        "hidden layer widths (default 20,10,5; hybrid's residual networks 32,32)"))),
    "optimizer": (("--optimizer",), dict(help="backprop optimiser (default lm)")),
    "search": (("--search",), dict(help=(
        "search the hidden layers first (1-6 layers of 3-16 nodes; minutes)"))),
    "scheduler": (("--scheduler",), dict(metavar="ADDRESS", help=(
        "--search: fit the candidates as tasks on this Dask scheduler (postproc[fleet]; in a fleet: its own)"))),
    "seed": (("--seed",), dict(metavar="S", help="seed of the training's random draws (default 0)")),
    "split_seed": (("--split-seed",), dict(metavar="S", help="seed of the validation draw (default 0)")),
    "val_fraction": (("--val-fraction",), dict(metavar="F", help=(
        "rows held out for validation (default 0.05; none below 100 rows: each row counts in a small fit)"))),
    "epochs": (("--epochs",), dict(metavar="N", help=(
        "backprop epochs at most (default 500; hybrid's residual networks 1500)"))),
    "name": (("--name",), dict(help="model name for the metadata (default: the output file's stem)")),
    "tcp": (("--tool",), dict(metavar="X,Y,Z,A,B,C", help=(
        "the TCP on the flange the data were measured with (default: the CSV's '# tool:' line or tool_x..tool_c "
        "columns, else the robot description's tool)"))),
    "pose_only": (("--pose-only",), dict(help=(
        "hybrid/kinematic: ignore the visiting order (no backlash; the model takes the pose only)"))),
    "update": (("--update",), dict(metavar="OLD.onnx", help=(
        "re-calibrate: re-fit OLD's base, joint zero offsets and tool on these rows (from as few as 30), with OLD's "
        "values as prior; everything else is OLD's (its structure: --hidden, --epochs, --pose-only do not apply); "
        "prints what moved"))),
    "register": (("--register",), dict(help=(
        "measured columns are in a tracker's frame: fit the rigid tracker → base transform on the training rows"))),
    "max_mean": (("--max-mean",), dict(metavar="MM", help=(
        "fail (exit 1) if the mean error after exceeds MM{default}"))),
    "max_p95": (("--max-p95",), dict(metavar="MM", help=(
        "fail if the error's 95th percentile after exceeds MM{default}"))),
    "max_max": (("--max-max",), dict(metavar="MM", help="fail if the largest error after exceeds MM{default}")),
    "max_orientation_mean": (("--max-orientation-mean",), dict(metavar="DEG", help=(
        "fail if the mean orientation error after exceeds DEG{default}"))),
}


def add(p, *names: str, helps: dict | None = None, choices: dict | None = None) -> None:
    """Add the flags of the settings ``names`` to the parser ``p`` (``helps``: this subcommand's
    own help of some; ``choices``: the values some take, where the subcommand knows them);
    :func:`settings_of` then reads them."""
    from argparse import SUPPRESS

    from ..settings import OPTIONS

    reads_file = any(a.dest == "settings" for a in p._actions)
    for name in names:
        flags, keywords = ARGUMENTS[name]
        keywords = dict(keywords, dest=name)
        option = OPTIONS[name]
        if option.text is None:  # a switch: given or not (None: the settings' value stands)
            keywords.update(action="store_true" if option.on else "store_false", default=None)
        elif option.text is not str:
            keywords["type"] = option.text
        if choices and name in choices:
            keywords["choices"] = choices[name]
        text = (helps or {}).get(name, keywords.get("help", ""))
        keywords["help"] = SUPPRESS if text is None else text.replace(
            "{default}", _FRAME.format(name) if reads_file else "")
        p.add_argument(*flags, **keywords)
    taken = p.get_default("settings_options") or ()
    p.set_defaults(settings_options=tuple(taken) + names)


def add_settings_file(p) -> None:
    """``--settings TOML``: the subcommand reads a settings file (the given one, else the one
    found upwards); add it before the settings' flags (their help then names the file's keys)."""
    p.add_argument("--settings", metavar="TOML", help="pyproject.toml or postproc.toml to read (default: searched "
                   "upwards from the current directory); options override its [tool.postproc] values")


def settings_of(args, **fixed):
    """The subcommand's Settings: its settings file (if it takes ``--settings``), then the flags
    given (``args``' settings options that are not None), then ``fixed`` (values the subcommand
    itself decides)."""
    from ..settings import Settings, load_settings

    base = load_settings(args.settings) if hasattr(args, "settings") else Settings()
    given = {name: getattr(args, name) for name in getattr(args, "settings_options", ())}
    return base.override(**given).override(**fixed)
