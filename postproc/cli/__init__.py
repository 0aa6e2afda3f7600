"""The ``postproc`` command: subcommands, common options, exit codes.

Each subcommand lives in its own module here with ``add_parser(subparsers)`` and
``run(args) -> int``; modules import their heavy dependencies inside ``run`` so that
``postproc compensate`` starts without torch, Pinocchio or matplotlib.

Exit codes: 0 done / clean, 1 findings (``check``) or a gate exceeded (``verify
--max-mean``), 2 bad input, usage or internal error (nothing written).

The CLI maps arguments and exit codes only: ``settings`` turns a subcommand's flags (and the
settings file) into the one :class:`~postproc.settings.Settings` (every flag of a setting is
declared there once); each subcommand module (``compensate``, ``check``, ``plan``, ``measure``,
``verify``, ``train``, ``import_data``, ``report``, ``fleet``, ``model``, ``export``, and
``iso9283``'s routes of plan and report) calls a use case of the packages below and prints.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from ..core.diagnostics import EXIT_ERROR, EXIT_INTERRUPTED, PostprocError
from ..core.extras import missing_extra
from ..core.version import __version__

# (module, one-line help) in the order `postproc --help` lists them
SUBCOMMANDS = [
    "compensate",
    "check",
    "plan",
    "measure",
    "verify",
    "train",
    "import_data",
    "report",
    "fleet",
    "model",
    "export",
]


class Formatter(argparse.RawDescriptionHelpFormatter):
    pass


def _module_of(command: str) -> str | None:
    """The module of subcommand ``command`` (None: not a subcommand)."""
    name = "import_data" if command == "import" else command
    return name if name in SUBCOMMANDS else None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every subcommand, or with ``command`` of that one only (a run imports and
    builds only what it uses: `postproc compensate` starts faster)."""
    parser = argparse.ArgumentParser(
        prog="postproc",
        description="Compensate industrial-robot positioning error in robot programs (KUKA KRL, ABB RAPID, "
        "Universal Robots URScript, FANUC LS, pose lists).",
        epilog="Exit codes: 0 ok, 1 findings (check) or a limit exceeded (verify/report --max-mean ...), 2 error (nothing written).",
        formatter_class=Formatter,
    )
    parser.add_argument("--version", action="version", version=f"postproc {__version__}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print errors only")
    common.add_argument("-v", "--verbose", action="store_true", help="print more (and tracebacks of internal errors)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    only = _module_of(command) if command is not None else None
    for name in [only] if only is not None else SUBCOMMANDS:
        try:
            module = importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{name}":
                continue  # subcommand not built yet
            raise
        module.add_parser(sub, common, Formatter)
    return parser


def main(argv: list[str] | None = None) -> int:
    words = sys.argv[1:] if argv is None else argv
    parser = build_parser(words[0] if words and not words[0].startswith("-") else None)
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return EXIT_ERROR
    from ..core.progress import reporting

    try:
        with reporting(show_progress(args)):
            return int(args.run(args) or 0)
    except PostprocError as exc:
        print(str(exc), file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:  # (every output is written whole or not at all: nothing half-written)
        print("postproc: interrupted; no file half-written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except ModuleNotFoundError as exc:
        hint = missing_extra(exc, args.command)
        if hint is None:  # not an optional part: a bug, reported as one below
            return _internal_error(exc, args)
        print(f"postproc {args.command}: {hint}", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:
        # the reader of stdout went away (e.g. `| head`): not our error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_ERROR
    except Exception as exc:  # last resort: never a bare traceback for users
        return _internal_error(exc, args)


def _internal_error(exc: Exception, args) -> int:
    if getattr(args, "verbose", False):
        raise exc
    print(f"postproc: internal error: {type(exc).__name__}: {exc} (run with -v for details)", file=sys.stderr)
    return EXIT_ERROR


def use_color(stream=sys.stderr) -> bool:
    """Colour only on a terminal and never when NO_COLOR is set (https://no-color.org)."""
    return stream.isatty() and not os.environ.get("NO_COLOR")


def show_progress(args=None) -> bool:
    """Progress bars only on an interactive stderr and not with -q."""
    return sys.stderr.isatty() and not getattr(args, "quiet", False)
