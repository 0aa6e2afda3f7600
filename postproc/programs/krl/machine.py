"""A controller backup's machine data (``KRC/R1/Mada/$machine.dat``) → the $ROBROOT a KRL
program starts with (``RobotRoot``): ``$ROBROOT_C`` (KSS 5.x and older: ``$ROBROOT``), the
robot's base in $WORLD (a ceiling robot: C 180, a wall robot: B 90, a robot on a pedestal: Z),
or, when ``$EX_KIN`` names an external ROBROOT kinematic (``ET1 #ERSYS``: a robot on a track,
$ROBROOT moves with the track's axes), a $ROBROOT known only at run time.

Where a backup keeps it: ``Mada/`` beside the ``System/`` of its ``$config.dat``, or below a
backup directory (``found_machine``); ``with_machine`` puts it into the ``ActiveFrames`` of a
read unless the user stated ``--robroot`` (or the settings' ``robroot``), which wins.
Only the lines that matter are read: the rest of the machine data (axis data, motor and
servo parameters) is no concern of a post-processor and is not parsed.

The controller's own absolute-accuracy model (KUKA's "positionally accurate robot model",
option Absolute Accuracy): ``accuracy_model`` reads ``$ABS_ACCUR`` from a backup's
``Mada/$machine.dat`` and ``Mada/$custom.dat`` (``backup_accuracy``: the backup a program's
files lie in). KUKA's system-variable documentation (KSS 8.1–8.3 "System Variables", section
$ABS_ACCUR, with $ABS_RELOAD and $ABS_UPDATE) gives it as an ENUM: #ACTIVATED (the model is
active), #SUPPRESSED (suppressed for now by ``$SUPPRESS_ABS_ACCUR``), #NONE (no such model);
KSS 5.x and older as a BOOL (TRUE = on). A robot whose controller corrects its positioning error
itself must not get postproc's correction too (``findings.accuracy_rule``: P408, P409 where
suppressed). A Status bit marking points taught with that model is *not* used: KUKA's
documentation found defines S bits 0–2 only (``robot.conventions.arm_status``).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path

from ...core.diagnostics import P107, P226, P408, PostprocError, line_col
from ..model import ActiveFrames, RobotRoot
from .syntax import _NUM

__all__ = ["MACHINE_NAME", "CUSTOM_NAME", "is_machine", "robroot_of", "ersys_unit", "read_machine", "found_machine", "beside_config",
           "with_machine", "robroot_option", "AccuracyModel", "accuracy_model", "backup_accuracy"]

MACHINE_NAME = "$machine.dat"
CUSTOM_NAME = "$custom.dat"
# `BOOL $ABS_ACCUR=TRUE` (KSS 5.x), `DECL <enum> $ABS_ACCUR=#ACTIVATED` (KSS 8.x); group 1: the value
_ABS_ACCUR = re.compile(r"^[ \t]*(?:DECL[ \t]+)?(?:[A-Z_][A-Z0-9_]*[ \t]+)?\$ABS_ACCUR[ \t]*=[ \t]*([^\s;]*)",
                        re.I | re.M)
_SUPPRESS = re.compile(r"^[ \t]*(?:DECL[ \t]+)?(?:BOOL[ \t]+)?\$SUPPRESS_ABS_ACCUR[ \t]*=[ \t]*([^\s;]*)",
                       re.I | re.M)
_ACTIVE, _SUPPRESSED, _OFF = ("TRUE", "#ACTIVATED"), ("#SUPPRESSED",), ("FALSE", "#NONE")
# how far above a program's file its backup's root (the folder with Mada/) may lie: KRC/R1/Program/sub/x.src
BACKUP_LEVELS = 4

# `FRAME $ROBROOT_C={X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0}` (group 1: `_C`, group 2: the components)
_ROBROOT = re.compile(r"^[ \t]*(?:DECL[ \t]+)?FRAME[ \t]+\$ROBROOT(_C)?[ \t]*=[ \t]*\{([^}\r\n]*)\}", re.I | re.M)
# `DECL EX_KIN $EX_KIN={ET1 #ERSYS,ET2 #NONE,…}`: #ERSYS = the external ROBROOT kinematic
_EX_KIN = re.compile(r"^[ \t]*(?:DECL[ \t]+)?EX_KIN[ \t]+\$EX_KIN[ \t]*=[ \t]*\{([^}\r\n]*)\}", re.I | re.M)
_ERSYS = re.compile(r"\b(ET\d)[ \t]+#ERSYS\b", re.I)
_COMPONENT = re.compile(r"[ \t]*([XYZABC])[ \t]+([-+]?" + _NUM + r")[ \t]*", re.I)


def is_machine(path: str | Path) -> bool:
    return Path(path).name.casefold() == MACHINE_NAME.casefold()


def robroot_of(text: str, path: str) -> RobotRoot:
    """The $ROBROOT the machine data ``text`` (of file ``path``) gives; P226 (located) when it
    has no ``$ROBROOT_C`` or a malformed one."""
    kin = _EX_KIN.search(text)
    track = _ERSYS.search(kin.group(1)) if kin else None
    if track:
        line, _ = line_col(text, kin.start())
        et = track.group(1).upper()
        unit, missing = ersys_unit(text, path, et)
        where = f"$EX_KIN {et} #ERSYS, {path}:{line}: a track"
        if unit is not None:
            return RobotRoot(None, path, f"the robot is on an external kinematic ({where}): its $ROBROOT moves with "
                             f"{unit.axis}", unit)
        return RobotRoot(None, path, f"the robot is on an external kinematic ({where}): its $ROBROOT moves with that "
                         f"kinematic's axes, whose kinematics the machine data do not give ({missing}; give them with "
                         "--external)")
    found = sorted(_ROBROOT.finditer(text), key=lambda m: m.group(1) is None)  # ($ROBROOT_C first)
    if not found:
        raise PostprocError("no $ROBROOT_C in this machine data: give --robroot X,Y,Z,A,B,C", path, 0, 0, P226)
    m = found[0]
    six: dict[str, float] = {}
    for part in m.group(2).split(","):
        c = _COMPONENT.fullmatch(part)
        key = c.group(1).upper() if c else None
        if c is None or key in six:
            line, col = line_col(text, m.start(2))
            raise PostprocError(f"$ROBROOT{m.group(1) or ''} is not a frame {{X …,Y …,Z …,A …,B …,C …}} of numbers",
                                path, line, col, P226)
        six[key] = float(c.group(2))
    if len(six) != 6:
        line, col = line_col(text, m.start(2))
        raise PostprocError(f"$ROBROOT{m.group(1) or ''} lacks {', '.join(k for k in 'XYZABC' if k not in six)}",
                            path, line, col, P226)
    line, _ = line_col(text, m.start())
    return RobotRoot(tuple(six[k] for k in "XYZABC"), f"$ROBROOT{m.group(1) or ''} of {path}:{line}")


def _frame(text: str, name: str) -> tuple | None:
    """The six numbers of ``FRAME <name>={X …,…}`` in machine data, None where absent or not six
    numbers."""
    m = re.search(r"^[ \t]*(?:DECL[ \t]+)?FRAME[ \t]+" + re.escape(name) + r"[ \t]*=[ \t]*\{([^}\r\n]*)\}", text,
                  re.I | re.M)
    if m is None:
        return None
    six: dict[str, float] = {}
    for part in m.group(1).split(","):
        c = _COMPONENT.fullmatch(part)
        if c is None or c.group(1).upper() in six:
            return None
        six[c.group(1).upper()] = float(c.group(2))
    return tuple(six[k] for k in "XYZABC") if len(six) == 6 else None


def ersys_unit(text: str, path: str, et: str = "ET1"):
    """The track ``et`` of machine data (``$EX_KIN {ET1 #ERSYS}``) as an ExternalUnit carrying
    the robot: one axis (``$ET1_AX``'s TR_A1, TR_A2/TR_A3 #NONE) of ``$AXIS_TYPE[6+k]`` 1
    (linear, mm) or 3/5 (rotational, deg), moving along / about the Z axis of ``$ET1_TA1KR``;
    world ← robot base = ``$ERSYSROOT : $ET1_TA1KR : joint(E) : $ET1_TFLA3`` (KUKA's machine data
    documentation, KR C2 "Machine Data" 2.1.4 $AXIS_TYPE and 2.2.x $ET1_…; docs/EXTERNAL.md).
    (unit, None), or (None, what is missing) — never a guess."""
    from ...core.frames import compose, frame_to_matrix, matrix_to_frame
    from ...robot.external import ExternalUnit

    ax = re.search(r"^[ \t]*(?:DECL[ \t]+)?ET_AX[ \t]+\$" + et + r"_AX[ \t]*=[ \t]*\{([^}\r\n]*)\}", text, re.I | re.M)
    if ax is None:
        return None, f"no ${et}_AX"
    axes = dict(re.findall(r"(TR_A[123])[ \t]+#(\w+)", ax.group(1).upper()))
    first = axes.get("TR_A1", "NONE")
    if not re.fullmatch(r"E[1-6]", first):
        return None, f"${et}_AX names no external axis E1…E6 as TR_A1"
    if any(axes.get(k, "NONE") != "NONE" for k in ("TR_A2", "TR_A3")):
        return None, f"${et}_AX names more than one axis (postproc takes a one-axis track)"
    k = int(first[1])
    t = re.search(r"^[ \t]*\$AXIS_TYPE\[[ \t]*" + str(6 + k) + r"[ \t]*\][ \t]*=[ \t]*(\d+)", text, re.M)
    kind = {"1": "prismatic", "3": "rotary", "5": "rotary"}.get(t.group(1)) if t else None
    if kind is None:
        return None, f"$AXIS_TYPE[{6 + k}] (the type of {first}) is not 1, 3 or 5" if t else f"no $AXIS_TYPE[{6 + k}]"
    frames = {}
    for name in ("$ERSYSROOT", f"${et}_TA1KR", f"${et}_TFLA3"):
        f = _frame(text, name)
        if f is None:
            return None, f"no {name} frame"
        frames[name] = f
    mount = matrix_to_frame(compose(frame_to_matrix(frames["$ERSYSROOT"]), frame_to_matrix(frames[f"${et}_TA1KR"])))
    line, _ = line_col(text, ax.start())
    return ExternalUnit(name=et, type=kind, axis=first, carries="robot", direction=(0.0, 0.0, 1.0),
                        mount=tuple(float(v) for v in mount), flange=frames[f"${et}_TFLA3"],
                        source=f"{path}:{line}"), None


def read_machine(path: str | Path) -> RobotRoot:
    """:func:`robroot_of` a machine data file (P107 when it cannot be read)."""
    try:
        text = Path(path).read_bytes().decode("latin-1")
    except FileNotFoundError:
        raise PostprocError("no such file", str(path), 0, 0, P107) from None
    except OSError as exc:
        raise PostprocError(f"cannot read: {exc.strerror}", str(path), 0, 0, P107) from None
    return robroot_of(text, str(path))


def _in(folder: Path | None, name: str, directory: bool = False) -> Path | None:
    """The file (or ``directory``) ``folder/name`` in whatever case it is on disk (backups come
    from Windows)."""
    if folder is None or not folder.is_dir():
        return None
    return next((p for p in sorted(folder.iterdir()) if p.name.casefold() == name.casefold()
                 and (p.is_dir() if directory else p.is_file())), None)


def found_machine(directory: Path) -> list[Path]:
    """``directory/Mada/$machine.dat``, else the shallowest ``Mada/$machine.dat`` below it
    (``KRC/`` → ``KRC/R1/Mada/$machine.dat``); several at one depth are all returned."""
    here = _in(_in(directory, "Mada", directory=True), MACHINE_NAME)
    if here is not None:
        return [here]
    found = sorted(p for p in directory.rglob("*") if is_machine(p) and p.parent.name.casefold() == "mada"
                   and p.is_file())
    if not found:
        return []
    depth = min(len(p.relative_to(directory).parts) for p in found)
    return [p for p in found if len(p.relative_to(directory).parts) == depth]


def beside_config(config: Path) -> Path | None:
    """The ``Mada/$machine.dat`` of the backup a ``System/$config.dat`` belongs to."""
    config = Path(config)
    if config.parent.name.casefold() != "system":
        return None
    return _in(_in(config.parent.parent, "Mada", directory=True), MACHINE_NAME)


def with_machine(active: ActiveFrames | None, configs=(), machines=()) -> ActiveFrames | None:
    """``active`` with the $ROBROOT of the backup's machine data, unless it states one: the
    ``$machine.dat`` files of ``machines`` (given, or ``found_machine`` in a cell's directory),
    else the one beside each ``System/$config.dat`` of ``configs``. None found: ``active`` as
    it is (the reader then assumes robot base = world and says so, P224). Two different ones:
    refused (P226)."""
    if active is not None and active.robroot is not None:
        return active
    found = [Path(m) for m in machines] or [
        m for c in configs if isinstance(c, (str, Path)) and (m := beside_config(Path(c))) is not None]
    unique = list(dict.fromkeys(p.resolve() for p in found))
    if not unique:
        return active
    if len(unique) > 1:
        raise PostprocError(f"several machine data ({', '.join(str(p) for p in unique)}): one robot's $ROBROOT; "
                            "give --robroot", str(unique[0]), 0, 0, P226)
    robroot = read_machine(found[0])
    return ActiveFrames(robroot=robroot) if active is None else replace(active, robroot=robroot)


def robroot_option(value, root: Path | None = None, label: str = "--robroot") -> RobotRoot | None:
    """``--robroot`` / the settings' ``robroot``: six numbers X,Y,Z,A,B,C, or the path of a
    ``$machine.dat`` (relative to ``root``); None stays None. ValueError for anything else."""
    if value is None:
        return None
    if isinstance(value, str) and "," not in value:
        path = Path(value) if root is None else Path(root) / value
        if not path.is_file():
            raise ValueError(f"robroot: expected six numbers X,Y,Z,A,B,C (mm, deg) or a $machine.dat; no such file "
                             f"{str(path)!r}")
        return read_machine(path)
    robroot = RobotRoot.parse(value)
    return replace(robroot, label=f"{label} {','.join(f'{v:g}' for v in robroot.frame)}")


@dataclass(frozen=True)
class AccuracyModel:
    """The controller's absolute-accuracy model as a backup states it: ``state`` "active" or
    "suppressed", the value as written, where (``path``:``line``:``col``)."""

    state: str
    value: str
    path: str
    line: int
    col: int

    def where(self) -> str:
        return f"{self.path}:{self.line}"


def accuracy_model(text: str, path: str) -> AccuracyModel | None:
    """The state of ``$ABS_ACCUR`` in machine data ``text`` (of ``path``): active, suppressed
    (``#SUPPRESSED``, or an active one with ``$SUPPRESS_ABS_ACCUR=TRUE``), None where it is off or
    not there. A value that is none of KUKA's (TRUE/FALSE, #ACTIVATED/#SUPPRESSED/#NONE) is
    refused at its place (P408): the state it means cannot be known."""
    found = _ABS_ACCUR.search(text)
    if found is None:
        return None
    value = found.group(1).upper()
    line, col = line_col(text, found.start(1))
    if value in _OFF:
        return None
    if value not in _ACTIVE + _SUPPRESSED:
        raise PostprocError(f"$ABS_ACCUR = {found.group(1)!r} is none of TRUE, FALSE, #ACTIVATED, #SUPPRESSED, #NONE: "
                            "whether the controller's absolute-accuracy model is on cannot be told", path, line, col,
                            P408)
    suppress = _SUPPRESS.search(text)
    if value in _ACTIVE and suppress is not None and suppress.group(1).upper() == "TRUE":
        line, col = line_col(text, suppress.start(1))
        return AccuracyModel("suppressed", "$SUPPRESS_ABS_ACCUR=TRUE", path, line, col)
    return AccuracyModel("active" if value in _ACTIVE else "suppressed", f"$ABS_ACCUR={found.group(1)}", path, line, col)


def _backup_data(file: Path) -> list[Path]:
    """The ``Mada/$machine.dat`` and ``Mada/$custom.dat`` of the backup ``file`` lies in: the
    nearest folder above it (at most BACKUP_LEVELS up) with a ``Mada/`` folder."""
    folder = file.resolve().parent
    for _ in range(BACKUP_LEVELS):
        mada = _in(folder, "Mada", directory=True)
        if mada is not None:
            return [p for name in (MACHINE_NAME, CUSTOM_NAME) if (p := _in(mada, name)) is not None]
        if folder.parent == folder:
            break
        folder = folder.parent
    return []


def backup_accuracy(files) -> AccuracyModel | None:
    """The controller's absolute-accuracy model of the backup the program ``files`` lie in (an
    active one before a suppressed one), None where no backup's machine data turns it on. A
    file that is not on disk (standard input, a text given in memory) has no backup."""
    found = []
    for data in dict.fromkeys(p for f in files if Path(f).is_file() for p in _backup_data(Path(f))):
        try:
            text = data.read_bytes().decode("latin-1")
        except OSError as exc:
            raise PostprocError(f"cannot read: {exc.strerror}", str(data), 0, 0, P107) from None
        model = accuracy_model(text, str(data))
        if model is not None:
            found.append(model)
    return min(found, key=lambda m: m.state != "active", default=None)
