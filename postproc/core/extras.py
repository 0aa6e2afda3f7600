"""Optional dependencies: which extra installs a missing module, and the command that does it."""
from __future__ import annotations

# optional dependencies: the module a subcommand imports -> the extra that installs it
EXTRA_OF_MODULE = {"pinocchio": "sim", "torch": "train", "onnx": "train", "matplotlib": "report", "jsonschema": "report",
                   "dask": "fleet",
                   "distributed": "fleet"}


# modules in more than one extra: the subcommand says which one
EXTRA_OF_COMMAND = {"plan": "sim", "measure": "sim", "verify": "sim", "train": "train", "import": "train",
                    "report": "report", "export": "train", "model": "train"}


OPTIONAL_MODULES = set(EXTRA_OF_MODULE) | {"scipy", "tqdm"}


def install_command(extra: str) -> str:
    """The command that installs ``extra`` (postproc is on no package index: from its checkout)."""
    pip = f"pip install -e '.[{extra}]'"
    if extra in ("train", "all"):  # the CPU build first, or the extra pulls a multi-GB CUDA one
        pip = f"pip install torch==2.13.0 && {pip}"
    return pip


def missing_extra(exc: ModuleNotFoundError, command: str | None) -> str | None:
    """What to install when an optional dependency is missing, or None (not an optional one: a bug)."""
    root = (exc.name or "").split(".")[0]
    if root not in OPTIONAL_MODULES:
        return None
    extra = EXTRA_OF_MODULE.get(root) or EXTRA_OF_COMMAND.get(command or "")
    if extra is None:
        return None
    return (f"needs the '{extra}' extra (module '{root}' is not installed); in the postproc checkout run: "
            f"{install_command(extra)}")
