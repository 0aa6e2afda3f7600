"""The one Settings object: frozen sections, each value checked where it is set.

Every option is declared once, in :data:`OPTIONS`: its name (the API keyword, the CLI's
destination), the section and field it sets, its key in a settings file, the flag the CLI
spells it with, and the check that turns a given value into the stored one (or says why not).
:meth:`Settings.override` applies values by those names; the settings file (``file.py``) and
the CLI (``postproc.cli.settings``) both go through it, so a value is checked the same way
wherever it comes from, and only its location differs (the file's key and line, or the flag).
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, fields, replace
from pathlib import Path

from ..core.diagnostics import P222, P226, P308, PostprocError
from ..programs.model import ActiveFrames, parse_load

__all__ = [
    "Settings", "Reading", "Rules", "Check", "Training", "Acceptance", "FreshPair", "Option", "OPTIONS",
    "DEFAULT_MAX_CORRECTION_MM", "MAX_ITERATIONS", "DIALECTS", "LIMITS", "parse_flags",
]

# An error model that predicts more than this is wrong, not the robot (guard, --max-correction).
DEFAULT_MAX_CORRECTION_MM = 5.0
# fixed-point iterations at most (--iterations, a model card's 'iterations')
MAX_ITERATIONS = 100
DIALECTS = ("krl", "poses", "rapid", "urscript", "fanuc")
# acceptance limit → (the figure of a verdict it bounds, unit)
LIMITS = {"max_mean": ("after.mean", "mm"), "max_p95": ("after.p95", "mm"), "max_max": ("after.max", "mm"),
          "max_orientation_mean": ("orientation_after.mean", "deg")}
_WILDCARD = re.compile(r"\*\*/|\*\*|\*|\?")


# --------------------------------------------------------------------------- sections


@dataclass(frozen=True)
class Reading:
    """How programs are read: ``config`` ($config.dat files with BASE_DATA / TOOL_DATA; RAPID
    modules whose data are read; a FANUC LS frame file), ``dialect`` (None: by the file's
    suffix), ``active`` (the $BASE / $TOOL / $ROBROOT / external units a program runs in where it
    does not set them itself), ``registers`` (a controller backup's register values: "backup"
    uses them where no program read writes the register, "runtime" makes every register a
    run-time value — cells where a PLC, vision or KAREL writes them), ``load`` (the payload in force
    where a program sets none: mass kg, centre of mass cx, cy, cz mm; None: the model's reference
    load), ``payloads`` (the controller's numbered payloads a program selects by number: a Fanuc
    ``PAYLOAD[n]`` schedule, (n, load) pairs)."""

    config: tuple[Path, ...] | None = None
    dialect: str | None = None
    active: ActiveFrames | None = None
    registers: str = "backup"
    load: tuple | None = None
    payloads: tuple = ()

    def payload(self, n: int) -> tuple | None:
        """The load of payload schedule ``n`` (``payloads``), None where not stated."""
        return next((load for k, load in self.payloads if k == n), None)

    @property
    def config_list(self) -> list[str] | None:
        return [str(p) for p in self.config] if self.config else None


@dataclass(frozen=True)
class Rules:
    """What compensate and check apply to a program's targets (compensation/findings.py)."""

    iterations: int | None = None  # fixed-point iterations (None: the model's)
    strict: bool = False  # warnings refuse (compensate) or count as findings (check)
    force: bool = False  # lifts P401, P408, P409, P304, P310
    max_correction_mm: float = DEFAULT_MAX_CORRECTION_MM  # larger corrections are refused (P303)
    max_std_mm: float | None = None  # bound on the model's error_std (P336); None: the card's; inf: none
    fill_partial: bool = True  # False: a partial aggregate is refused (P216), not filled in
    orientation: bool = False  # correct the orientation too (the model's rotation_error)


@dataclass(frozen=True)
class FreshPair:
    """A compensated output kept in the repository beside its source (patterns under ``root``)."""

    source: str
    output: str
    root: Path
    model: Path | None = None  # None: the settings' model
    config: tuple[Path, ...] | None = None  # None: the settings' config

    def matches(self) -> list[tuple[Path, Path]]:
        """(source, output) paths for every existing source file, sorted."""
        regex = _pattern_regex(self.source)
        out = []
        for path in sorted(self.root.glob(self.source)):
            m = regex.fullmatch(path.relative_to(self.root).as_posix())
            if m and path.is_file():
                out.append((path, self.root / _substitute(self.output, m.groups())))
        return out

    def orphans(self) -> list[Path]:
        """Existing outputs whose source does not exist."""
        regex = _pattern_regex(self.output)
        out = []
        for path in sorted(self.root.glob(self.output)):
            m = regex.fullmatch(path.relative_to(self.root).as_posix())
            if m and path.is_file() and not (self.root / _substitute(self.source, m.groups())).is_file():
                out.append(path)
        return out


@dataclass(frozen=True)
class Check:
    """What ``postproc check`` reports: ``ignore`` (codes not reported), ``fresh`` (compensated
    outputs kept beside their sources)."""

    ignore: frozenset[str] = frozenset()
    fresh: tuple[FreshPair, ...] = ()


@dataclass(frozen=True)
class Training:
    """How ``postproc train`` fits a model (model/training/fitting.py)."""

    method: str = "hybrid"
    hidden: tuple[int, ...] | None = None  # hidden layer widths (None: the method's)
    optimizer: str | None = None  # backprop optimiser of the pose-only networks (None: lm)
    epochs: int | None = None  # backprop epochs at most (None: the method's)
    seed: int = 0  # the training's random draws
    split_seed: int = 0  # the validation rows' draw
    val_fraction: float | None = None  # rows held out (None: 5 %, none below 100 rows)
    search: bool = False  # search the hidden layers first
    scheduler: str | None = None  # --search's candidates as tasks on this Dask scheduler
    tcp: tuple[float, ...] | None = None  # the TCP on the flange the data were measured with (X,Y,Z,A,B,C)
    pose_only: bool = False  # identified methods without the visiting order
    register: bool = False  # the measured columns are in a tracker's frame
    update: Path | None = None  # the model to re-calibrate
    name: str | None = None  # the model card's name (None: the output file's stem)


@dataclass(frozen=True)
class Acceptance:
    """The limits a cell's CI holds verify and report to (acceptance/verdict.py): positioning
    error after compensation (mm), orientation error after (deg); None: not stated."""

    max_mean: float | None = None
    max_p95: float | None = None
    max_max: float | None = None
    max_orientation_mean: float | None = None

    @property
    def stated(self) -> dict:
        return {name: getattr(self, name) for name in LIMITS if getattr(self, name) is not None}


@dataclass(frozen=True)
class Settings:
    """The settings of one run, whole: ``path`` (the settings file they were read from, None:
    none), ``model`` (the ONNX model: a path or a shipped model's name; None: the default),
    ``robot`` (the robot: its description file or its name — one meaning everywhere, see
    :func:`postproc.robot.description.robot_ref`), and a section per use case. Frozen: a use
    case gets it whole and cannot change it; :meth:`override` makes another."""

    path: Path | None = None
    model: str | Path | None = None
    robot: str | None = None
    reading: Reading = Reading()
    rules: Rules = Rules()
    check: Check = Check()
    training: Training = Training()
    acceptance: Acceptance = Acceptance()

    @property
    def root(self) -> Path:
        """The folder the settings' relative paths start from (the file's, else the current one)."""
        return self.path.parent if self.path is not None else Path.cwd()

    def override(self, **values) -> "Settings":
        """These settings with ``values`` (option names of :data:`OPTIONS`; None: not given,
        kept) applied, each checked; PostprocError with the option's flag and code otherwise."""
        return self.apply(values, source=None)

    def apply(self, values: dict, source: "Source | None" = None) -> "Settings":
        """``values`` by option name applied in order (``source``: where they come from, for the
        errors: a settings file's key and line; None: the CLI / API, by the option's flag)."""
        out = self
        for name, value in values.items():
            if value is None:
                continue
            option = OPTIONS.get(name)
            if option is None:
                import difflib

                close = difflib.get_close_matches(name, list(OPTIONS), n=1)
                raise TypeError(f"unknown setting {name!r}" + (f"; did you mean {close[0]!r}?" if close else ""))
            try:
                checked = option.check(value, out, source)
            except ValueError as exc:
                raise (source.error(name, str(exc)) if source is not None else option.error(str(exc))) from None
            out = option.set(out, checked)
        return out


# --------------------------------------------------------------------------- options


class Source:
    """Where option values come from when not the CLI / API: a settings file (``file.py``)."""

    root: Path

    def error(self, name: str, message: str) -> PostprocError:  # pragma: no cover - the file's
        raise NotImplementedError


@dataclass(frozen=True)
class Option:
    """One setting: ``section`` (None: a field of Settings itself) and ``field``; ``flag`` the
    CLI's spelling (messages of values given there); ``key`` the settings file's (None: not
    there); ``check(value, settings, source) -> stored`` raises ValueError with what it expects;
    ``code`` the error's code for a value from the CLI / API."""

    name: str
    section: str | None
    field: str
    flag: str
    key: str | None
    check: Callable
    code: str = P308
    # how a flag's text becomes a value (int, float, str); None: a switch, its presence is ``on``
    text: Callable[[str], object] | None = str
    on: bool = True

    def set(self, settings: Settings, value) -> Settings:
        if self.section is None:
            return replace(settings, **{self.field: value})
        section = getattr(settings, self.section)
        return replace(settings, **{self.section: replace(section, **{self.field: value})})

    def error(self, message: str) -> PostprocError:
        if self.code in (P222, P226):  # the frames: "base: expected …", shown at the flag
            return PostprocError(message, self.flag, 0, 0, self.code)
        return PostprocError(f"{self.flag} {message}", "", 0, 0, self.code)


def _bool(value, settings, source):
    if not isinstance(value, bool):
        raise ValueError(f"must be true or false, not {value!r}")
    return value


def _positive_mm(value, settings, source):
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < math.inf:
        # (NaN would switch a bound off silently: every comparison with it is False)
        raise ValueError(f"must be a positive number of mm, not {value}")
    return float(value)


def _std_bound(value, settings, source):
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:  # (inf: no bound)
        raise ValueError(f"must be a positive number of mm, not {value}")
    return float(value)


def _limit(value, settings, source):
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 < value < math.inf:
        raise ValueError(f"must be a positive number, not {value}")
    return float(value)


def _iterations(value, settings, source):
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_ITERATIONS:
        raise ValueError(f"must be between 1 and {MAX_ITERATIONS}, not {value!r}")
    return value


def _int(value, settings, source):
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"must be a whole number, not {value!r}")
    return value


def _positive_int(value, settings, source):
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"must be a positive whole number, not {value!r}")
    return value


def _number(value, settings, source):
    # (the range is the split's rule: model.training.data.split_indices, P506, where the rows are known)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"must be a number, not {value!r}")
    return float(value)


def _text(value, settings, source):
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"must be text, not {value!r}")
    return value.strip()


def _robot(value, settings, source):
    if isinstance(value, Path):
        value = str(value)
    if not isinstance(value, str) or not value.strip():
        raise ValueError("expected the robot's name (as in the model card, e.g. \"KR500-sim\") or its description "
                         f"file (FILE.toml), not {value!r}")
    value = value.strip()
    if source is not None and value.lower().endswith(".toml"):
        value = str(source.root / value)
    return value


def _path(value, settings, source):
    if not isinstance(value, str | Path) or not str(value):
        raise ValueError(f"expected a path, not {value!r}")
    return source.root / value if source is not None else Path(value)


def _model(value, settings, source):
    if not isinstance(value, str | Path) or not str(value):
        raise ValueError(f"expected the path of an ONNX model, not {value!r}")
    return source.root / value if source is not None else value


def _paths(value, settings, source):
    items = [value] if isinstance(value, str | Path) else value
    if not isinstance(items, list | tuple) or not items or not all(isinstance(v, str | Path) for v in items):
        raise ValueError("expected a path or a list of paths")
    return tuple((source.root / v) if source is not None else Path(v) for v in items)


def _dialect(value, settings, source):
    if value not in DIALECTS:
        raise ValueError(f"must be one of {', '.join(DIALECTS)}, not {value!r}")
    return value


def _registers(value, settings, source):
    if value not in ("backup", "runtime"):
        raise ValueError(f"must be 'backup' or 'runtime', not {value!r}")
    return value


def _codes(value, settings, source):
    items = [c.strip() for c in value.split(",")] if isinstance(value, str) else value
    if not isinstance(items, Iterable):
        raise ValueError("expected a list of codes such as [\"P301\"]")
    items = [c.upper() if isinstance(c, str) else c for c in items if c != ""]
    if not all(isinstance(c, str) and re.fullmatch(r"P\d{3}", c) for c in items):
        raise ValueError("expected a list of codes such as [\"P301\"]")
    return settings.check.ignore | frozenset(items)


def widths(text: str) -> tuple[int, ...]:
    """``"20,10,5"`` → (20, 10, 5): positive layer widths; ValueError otherwise."""
    try:
        values = tuple(int(v) for v in str(text).replace(" ", "").split(",") if v)
    except ValueError:
        values = ()
    if not values or any(v < 1 for v in values):
        raise ValueError(f"expected positive layer widths like 20,10,5, got {text!r}")
    return values


def _hidden(value, settings, source):
    if isinstance(value, str):
        return widths(value)
    if not isinstance(value, list | tuple) or not value or any(
            isinstance(v, bool) or not isinstance(v, int) or v < 1 for v in value):
        raise ValueError(f"expected positive layer widths like 20,10,5, got {value!r}")
    return tuple(value)


def _tcp(value, settings, source):
    from ..measurements.csv import parse_tool

    text = ",".join(str(v) for v in value) if isinstance(value, list | tuple) else str(value)
    try:
        return tuple(float(v) for v in parse_tool(text))
    except PostprocError as exc:
        raise ValueError(exc.message) from None


def _active(value, settings, source):
    if not isinstance(value, ActiveFrames):
        raise ValueError(f"expected an ActiveFrames, not {value!r}")
    return value


def _frame(which: str):
    """base / tool: N or X,Y,Z,A,B,C (tool also 'model'), over what the settings state."""
    def check(value, settings, source):
        parsed = ActiveFrames.parse(value, which)  # (ValueError "base: expected …")
        return _with(settings.reading.active, **{which: parsed})
    return check


def _robroot(value, settings, source):
    from ..programs.krl.machine import robroot_option

    robroot = robroot_option(value, source.root if source is not None else None,  # (ValueError "robroot: …")
                             label="robroot =" if source is not None else "--robroot")
    return _with(settings.reading.active, robroot=robroot)


def _load(value, settings, source):
    return parse_load(value)  # (ValueError "load: …")


def _payloads(value, settings, source):
    """``{1 = "300,0,0,250", 2 = "12.5"}`` (or ``--payload 1=300,0,0,250`` given several times):
    the controller's numbered payloads → (n, load) pairs."""
    if isinstance(value, (list, tuple)) and all(isinstance(v, str) and "=" in v for v in value):
        value = dict(v.split("=", 1) for v in value)
    if not isinstance(value, dict):
        raise ValueError('expected a table of numbered payloads, e.g. {1 = "300,0,0,250"}')
    out = []
    for k, v in value.items():
        try:
            n = int(str(k))
        except ValueError:
            raise ValueError(f"payloads: {k!r} is not a payload number") from None
        out.append((n, parse_load(v, f"payloads.{k}")))
    return tuple(sorted(out))


def _external(value, settings, source):
    from ..robot.external import read_external

    if not isinstance(value, str | Path) or not str(value).strip():
        raise ValueError("expected the path of a TOML with [[external]] tables")
    path = source.root / value if source is not None else Path(value)
    return _with(settings.reading.active, external=read_external(path))


def _with(active: ActiveFrames | None, **given) -> ActiveFrames:
    return replace(active or ActiveFrames(), **given)


def _fresh(value, settings, source):
    if not isinstance(value, list) or not all(isinstance(p, dict) for p in value):
        raise ValueError("expected a list of {source = ..., output = ...} tables")
    root = source.root if source is not None else Path.cwd()
    pairs = []
    for i, pair in enumerate(value):
        key = f"fresh[{i}]"
        unknown = [k for k in pair if k not in ("source", "output", "model", "config")]
        if unknown:
            raise ValueError(f"{key}: unknown key '{unknown[0]}' (known: source, output, model, config)")
        if "source" not in pair or "output" not in pair:
            raise ValueError(f"{key}: each pair needs both 'source' and 'output'")
        src, out = _pattern(pair["source"], key + ".source"), _pattern(pair["output"], key + ".output")
        if _WILDCARD.findall(src) != _WILDCARD.findall(out):
            raise ValueError(f"{key}: '{out}' must have the same wildcards in the same order as '{src}'")
        if not _WILDCARD.search(src):
            raise ValueError(f"{key}: '{src}' has no wildcard: write the single pair as a pattern, e.g. 'src/*.src'")
        model = pair.get("model")
        if model is not None and not isinstance(model, str):
            raise ValueError(f"{key}.model: expected the path of an ONNX model")
        config = _paths(pair["config"], settings, source) if "config" in pair else None
        pairs.append(FreshPair(src, out, root, root / model if model is not None else None, config))
    return tuple(pairs)


def _pattern(value, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise ValueError(f"{where}: expected a glob pattern such as 'src/*.src'")
    if "[" in value or value.startswith("/"):
        raise ValueError(f"{where}: patterns are relative and use only *, ? and **/")
    return value


def _pattern_regex(pattern: str) -> re.Pattern:
    pieces, pos = [], 0
    for m in _WILDCARD.finditer(pattern):
        pieces.append(re.escape(pattern[pos:m.start()]))
        pieces.append({"**/": "((?:.*/)?)", "**": "(.*)", "*": "([^/]*)", "?": "([^/])"}[m.group()])
        pos = m.end()
    pieces.append(re.escape(pattern[pos:]))
    return re.compile("".join(pieces))


def _substitute(pattern: str, groups: tuple[str, ...]) -> str:
    values = iter(groups)
    return _WILDCARD.sub(lambda m: next(values), pattern)


def _options(*rows) -> dict[str, Option]:
    out = {}
    for name, section, field_name, flag, key, check, *more in rows:
        code = more[0] if more and isinstance(more[0], str) and more[0].startswith("P") else P308
        out[name] = Option(name, section, field_name, flag, key, check, code, *_TEXT[name])
    return out


_SWITCH, _OFF = (None, True), (None, False)
# how a flag's text is read (argparse's type; the fleet file's train args): (text, on)
_TEXT: dict[str, tuple] = {
    "strict": _SWITCH, "force": _SWITCH, "orientation": _SWITCH, "fill_partial": _OFF, "search": _SWITCH,
    "pose_only": _SWITCH, "register": _SWITCH,
    "hidden": (widths, True), "iterations": (int, True), "epochs": (int, True), "seed": (int, True), "split_seed": (int, True),
    "max_correction_mm": (float, True), "max_std_mm": (float, True), "val_fraction": (float, True),
    "max_mean": (float, True), "max_p95": (float, True), "max_max": (float, True), "max_orientation_mean": (float, True),
}


class _Text(dict):
    def __missing__(self, name):
        return (str, True)


_TEXT = _Text(_TEXT)


OPTIONS: dict[str, Option] = _options(
    # name               section       field                 CLI flag                 file key           check
    ("model",            None,         "model",              "--model",               "model",           _model),
    ("robot",            None,         "robot",              "--robot",               "robot",           _robot),
    ("config",           "reading",    "config",             "--config",              "config",          _paths),
    ("dialect",          "reading",    "dialect",            "--dialect",             None,              _dialect),
    ("active",           "reading",    "active",             "active",                None,              _active),
    ("base",             "reading",    "active",             "--base",                "base",            _frame("base"), P222),
    ("tool",             "reading",    "active",             "--tool",                "tool",            _frame("tool"), P222),
    ("robroot",          "reading",    "active",             "--robroot",             "robroot",         _robroot, P226),
    ("external",         "reading",    "active",             "--external",            "external",        _external),
    ("registers",        "reading",    "registers",          "--registers",           "registers",       _registers),
    ("load",             "reading",    "load",               "--load",                "load",            _load, P222),
    ("payloads",         "reading",    "payloads",           "--payload",             "payloads",        _payloads, P222),
    ("iterations",       "rules",      "iterations",         "--iterations",          "iterations",      _iterations),
    ("strict",           "rules",      "strict",             "--strict",              "strict",          _bool),
    ("force",            "rules",      "force",              "--force",               None,              _bool),
    ("max_correction_mm", "rules",     "max_correction_mm",  "--max-correction",      "max_correction",  _positive_mm),
    ("max_std_mm",       "rules",      "max_std_mm",         "--max-std",             "max_std",         _std_bound),
    ("fill_partial",     "rules",      "fill_partial",       "--no-fill-partial",     None,              _bool),
    ("orientation",      "rules",      "orientation",        "--orientation",         None,              _bool),
    ("ignore",           "check",      "ignore",             "--ignore",              "ignore",          _codes),
    ("fresh",            "check",      "fresh",              "fresh",                 "fresh",           _fresh),
    ("method",           "training",   "method",             "--method",              None,              _text),
    ("hidden",           "training",   "hidden",             "--hidden",              None,              _hidden),
    ("optimizer",        "training",   "optimizer",          "--optimizer",           None,              _text),
    ("epochs",           "training",   "epochs",             "--epochs",              None,              _positive_int),
    ("seed",             "training",   "seed",               "--seed",                None,              _int),
    ("split_seed",       "training",   "split_seed",         "--split-seed",          None,              _int),
    ("val_fraction",     "training",   "val_fraction",       "--val-fraction",        None,              _number),
    ("search",           "training",   "search",             "--search",              None,              _bool),
    ("scheduler",        "training",   "scheduler",          "--scheduler",           None,              _text),
    ("tcp",              "training",   "tcp",                "--tool",                None,              _tcp),
    ("pose_only",        "training",   "pose_only",          "--pose-only",           None,              _bool),
    ("register",         "training",   "register",           "--register",            None,              _bool),
    ("update",           "training",   "update",             "--update",              None,              _path),
    ("name",             "training",   "name",               "--name",                None,              _text),
    ("max_mean",         "acceptance", "max_mean",           "--max-mean",            "max_mean",        _limit),
    ("max_p95",          "acceptance", "max_p95",            "--max-p95",             "max_p95",         _limit),
    ("max_max",          "acceptance", "max_max",            "--max-max",             "max_max",         _limit),
    ("max_orientation_mean", "acceptance", "max_orientation_mean", "--max-orientation-mean", "max_orientation_mean",
     _limit),
)

# the settings file's keys → option names
FILE_KEYS = {o.key: o.name for o in OPTIONS.values() if o.key is not None}
assert {f.name for f in fields(Rules)} <= {o.field for o in OPTIONS.values() if o.section == "rules"}


def parse_flags(tokens: list[str], names: Iterable[str]) -> dict[str, object]:
    """Option values from command-line style ``tokens`` (``--val-fraction 0.2``,
    ``--val-fraction=0.2``, ``--search``) for the options ``names`` only (their flags); ValueError
    naming the token for anything else. (A fleet file's ``args``: the settings of its trainings.)"""
    by_flag = {OPTIONS[n].flag: OPTIONS[n] for n in names}
    out: dict[str, object] = {}
    i = 0
    while i < len(tokens):
        flag, eq, value = tokens[i].partition("=")
        option = by_flag.get(flag)
        if option is None:
            raise ValueError(f"unknown option {tokens[i]!r} (known: {', '.join(sorted(by_flag))})")
        if option.text is None:
            if eq:
                raise ValueError(f"{flag} takes no value")
            out[option.name] = option.on
        else:
            if not eq:
                i += 1
                if i >= len(tokens):
                    raise ValueError(f"{flag} needs a value")
                value = tokens[i]
            try:
                out[option.name] = option.text(value)
            except ValueError:
                raise ValueError(f"{flag} expects {option.text.__name__ if option.text is not str else 'text'}, "
                                 f"not {value!r}") from None
        i += 1
    return out
