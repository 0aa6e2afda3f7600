"""A fleet's jobs: the fleet file → one :class:`RobotJob` per robot (its inputs, its training
settings, the digest a rerun compares), and reading a robot's input files on the client.

The fleet file (TOML)::

    [defaults]                       # optional; every robot inherits these
    method = "kinematic"             # postproc train --method
    robot = "models/kr500.toml"      # nominal description (--robot)
    args = ["--val-fraction", "0.2"] # further `postproc train` flags (its training settings)

    [[robot]]
    name = "cell1"                   # required, unique; the output folder's name
    data = "cell1.csv"               # required: the measurement CSV
    previous = "old/cell1.onnx"      # optional: the robot's previous model: train --update it

Paths are relative to the fleet file, resolved where ``postproc fleet`` runs (the client). A
bad file — a key, a value, a flag of ``args`` — is refused with P610 at its line.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

from ..core.diagnostics import P500, P610, PostprocError
from ..core.toml import key_line, read_toml
from ..settings import OPTIONS, Settings
from ..settings.sections import parse_flags

__all__ = ["RobotJob", "load_fleet", "read_inputs", "STATE_FILE", "TRAIN_OPTIONS"]

STATE_FILE = "fleet-state.json"
ROBOT_KEYS = {"name", "data", "robot", "method", "args", "previous"}
DEFAULT_KEYS = {"robot", "method", "args"}
# the settings a robot's ``args`` may give: train's (the training section and the robot)
TRAIN_OPTIONS = ("robot", *(name for name, o in OPTIONS.items() if o.section == "training"))


@dataclass
class RobotJob:
    name: str
    data: Path
    robot: Path | None = None
    method: str | None = None
    args: list[str] = field(default_factory=list)
    previous: Path | None = None

    def files(self) -> dict[str, Path]:
        """The robot's input files by role (``data``, ``robot``, ``previous``), as the client names them."""
        return {role: path for role, path in (("data", self.data), ("robot", self.robot), ("previous", self.previous))
                if path is not None}

    def settings(self, files: dict[str, Path] | None = None) -> Settings:
        """The robot's training settings, its inputs at ``files`` (by role; default its own
        paths): its name, method, robot description, previous model (re-calibration: OLD's base,
        zero offsets and tool re-fitted, the rest kept), then its ``args`` (train's flags, as
        ``postproc train`` takes them; the last word)."""
        files = files or self.files()
        given = Settings().override(name=self.name, method=self.method,
                                    robot=str(files["robot"]) if "robot" in files else None,
                                    update=files.get("previous"))
        return given.override(**parse_flags(self.args, TRAIN_OPTIONS))

    def digest(self) -> str:
        """sha256 over everything the robot's result depends on."""
        h = hashlib.sha256()
        for p in (self.data, self.robot, self.previous):
            h.update(_file_sha(p).encode() if p else b"-")
        h.update(json.dumps([self.method, self.args]).encode())
        return h.hexdigest()


def read_inputs(job: RobotJob) -> dict[str, tuple[str, bytes]]:
    """The robot's input files as the client reads them: role → (file name, bytes); what a task
    takes to its worker. PostprocError P500 naming the file when one cannot be read."""
    out = {}
    for role, path in job.files().items():
        try:
            out[role] = (path.name, path.read_bytes())
        except OSError as exc:
            raise PostprocError(f"cannot read the robot's {role} file: {exc.strerror or exc}", str(path),
                                code=P500) from None
    return out


def _file_sha(path: Path) -> str:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return "missing"


def load_fleet(path: str | Path) -> list[RobotJob]:
    """The fleet file's robots as jobs; PostprocError P610 (located) on a bad file."""
    path = Path(path)
    text, data = read_toml(path, P610, "fleet file")
    base = path.resolve().parent  # (the client's: workers elsewhere get the files, not the paths)

    def bad(message: str, line: int) -> PostprocError:
        return PostprocError(message, str(path), line, 1 if line else 0, P610)

    unknown = set(data) - {"defaults", "robot"}
    if unknown:
        key = sorted(unknown)[0]
        raise bad(f"unknown key '{key}' (expected [defaults] and [[robot]] tables)", key_line(text, None, key) or key_line(text, key))
    defaults = data.get("defaults", {})
    if not isinstance(defaults, dict) or set(defaults) - DEFAULT_KEYS:
        raise bad(f"[defaults] takes only {', '.join(sorted(DEFAULT_KEYS))}", key_line(text, "defaults"))
    robots = data.get("robot")
    if not isinstance(robots, list) or not robots:
        raise bad("no robots: add [[robot]] tables with name and data", 0)
    jobs, names = [], set()
    for i, entry in enumerate(robots):
        line = key_line(text, "robot", None, i)
        merged = {**defaults, **entry}
        extra = set(entry) - ROBOT_KEYS
        if extra:
            raise bad(f"robot {i + 1}: unknown key '{sorted(extra)[0]}'", line)
        for key in ("name", "data"):
            if not isinstance(merged.get(key), str) or not merged[key]:
                raise bad(f"robot {i + 1}: '{key}' (a string) is required", line)
        if merged["name"] in names or "/" in merged["name"] or merged["name"] in (".", ".."):
            raise bad(f"robot name '{merged['name']}' is repeated or not a folder name", line)
        names.add(merged["name"])
        args = merged.get("args", [])
        if not isinstance(args, list) or not all(isinstance(a, str) for a in args):
            raise bad(f"robot {i + 1}: 'args' must be a list of strings", line)
        rel = lambda k: (base / merged[k]) if merged.get(k) else None  # noqa: E731
        job = RobotJob(merged["name"], rel("data"), rel("robot"), merged.get("method"), args, rel("previous"))
        try:  # (its training settings checked here: a bad argument is the file's error, at the robot's line)
            job.settings()
        except (ValueError, PostprocError) as exc:
            raise bad(f"robot {i + 1}: {getattr(exc, 'message', exc)}", line) from None
        jobs.append(job)
    return jobs
