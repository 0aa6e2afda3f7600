"""The ``postproc`` command: subcommands, common options, exit codes.

Each subcommand lives in its own module here with ``add_parser(subparsers)`` and
``run(args) -> int``; modules import their heavy dependencies inside ``run`` so that
``postproc compensate`` starts without torch, Pinocchio or matplotlib.

Exit codes: 0 done / clean, 1 findings (``check``) or a gate exceeded (``verify
--max-mean``), 2 bad input, usage or internal error (nothing written).
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from .. import __version__
from ..diagnostics import EXIT_ERROR, PostprocError

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
]


class Formatter(argparse.RawDescriptionHelpFormatter):
    pass


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="postproc",
        description="Compensate industrial-robot positioning error in robot programs (KUKA KRL, pose lists).",
        epilog="Exit codes: 0 ok, 1 findings (check) or gate exceeded (verify --max-mean), 2 error (nothing written).",
        formatter_class=Formatter,
    )
    parser.add_argument("--version", action="version", version=f"postproc {__version__}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-q", "--quiet", action="store_true", help="print errors only")
    common.add_argument("-v", "--verbose", action="store_true", help="print more (and tracebacks of internal errors)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"{__name__}.{name}":
                continue  # subcommand not built yet
            raise
        module.add_parser(sub, common, Formatter)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help(sys.stderr)
        return EXIT_ERROR
    try:
        return int(args.run(args) or 0)
    except PostprocError as exc:
        print(str(exc), file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("postproc: interrupted", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:
        # the reader of stdout went away (e.g. `| head`): not our error
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_ERROR
    except Exception as exc:  # last resort: never a bare traceback for users
        if getattr(args, "verbose", False):
            raise
        print(f"postproc: internal error: {type(exc).__name__}: {exc} (run with -v for details)", file=sys.stderr)
        return EXIT_ERROR


def use_color(stream=sys.stderr) -> bool:
    """Colour only on a terminal and never when NO_COLOR is set (https://no-color.org)."""
    return stream.isatty() and not os.environ.get("NO_COLOR")


def show_progress(args=None) -> bool:
    """Progress bars only on an interactive stderr and not with -q."""
    return sys.stderr.isatty() and not getattr(args, "quiet", False)
