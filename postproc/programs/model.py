"""The types of a read program: ``Program`` (texts + targets) and ``Targets`` (columns),
with the ``Frame`` each target is programmed in. Re-exported by ``postproc.programs``."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.diagnostics import P222, Diagnostic

__all__ = ["Frame", "Targets", "TargetsBuilder", "Program", "ActiveFrames", "RobotRoot", "STAMP_PREFIX", "parse_load"]

# The one line postproc adds to a file it compensated (after the dialect's comment marker).
STAMP_PREFIX = "postproc: compensated with model"


@dataclass(frozen=True)
class Frame:
    """The frame a target was programmed in.

    ``base`` maps that frame to the robot base frame (4×4: INV_POS($ROBROOT):$BASE);
    ``tool`` is the active $TOOL as X,Y,Z,A,B,C (None: the model's own tool, stated with
    ``ActiveFrames(tool="model")``); ``label`` says where
    they came from, e.g. ``BASE_DATA[3] / TOOL_DATA[1]``.
    """

    base: np.ndarray
    tool: np.ndarray | None = None
    label: str = ""


def parse_load(value, which: str = "load") -> tuple:
    """A payload as its user states it: ``"MASS"`` or ``"MASS,CX,CY,CZ"`` (kg; centre of mass in
    mm in the flange frame, default 0,0,0), a number or a list of one or four numbers → (mass, cx,
    cy, cz); ValueError with the reason otherwise."""
    if isinstance(value, bool):
        raise ValueError(f"{which}: expected MASS or MASS,CX,CY,CZ (kg, mm), not {value!r}")
    if isinstance(value, (int, float)):
        items = [value]
    elif isinstance(value, (list, tuple)):
        items = list(value)
    elif isinstance(value, str):
        items = [v.strip() for v in value.split(",")]
    else:
        raise ValueError(f"{which}: expected MASS or MASS,CX,CY,CZ (kg, mm), not {value!r}")
    if len(items) not in (1, 4):
        raise ValueError(f"{which}: expected MASS or MASS,CX,CY,CZ (kg, mm), got {len(items)} numbers")
    try:
        four = tuple(float(v) for v in items) + (0.0, 0.0, 0.0)[:4 - len(items)]
    except (TypeError, ValueError):
        raise ValueError(f"{which}: expected MASS or MASS,CX,CY,CZ (kg, mm), not {value!r}") from None
    if not all(np.isfinite(four)) or four[0] < 0:
        raise ValueError(f"{which}: the mass must be a finite number ≥ 0 kg and the centre of mass finite")
    return four


@dataclass(frozen=True)
class RobotRoot:
    """$ROBROOT as known before a KRL program runs: the robot's base in $WORLD (the machine
    data's ``$ROBROOT_C``, or stated with ``--robroot`` / the settings' ``robroot``).
    ``frame`` X,Y,Z,A,B,C (mm, deg); None: it is known only at run time, ``why`` says why (a
    robot on a track: the machine data's ``$EX_KIN`` names an external ROBROOT kinematic);
    ``label`` says where it came from (``--robroot 0,0,2500,0,0,180``, a $machine.dat)."""

    frame: tuple | None
    label: str = ""
    why: str = ""
    # a track whose kinematics the machine data give (``postproc.robot.external.ExternalUnit``, carries
    # the robot): $ROBROOT moves with it, known at each target that states its axis
    unit: object = None

    @staticmethod
    def parse(value, label: str = "robroot") -> "RobotRoot":
        """Six numbers X,Y,Z,A,B,C (``"X,Y,Z,A,B,C"`` or a list of six) → RobotRoot; ValueError
        with the reason otherwise."""
        six = None if isinstance(value, str) and "," not in value else ActiveFrames.parse(value, "robroot")
        if not isinstance(six, tuple):
            raise ValueError(f"robroot: expected six numbers X,Y,Z,A,B,C (mm, deg) or a $machine.dat, not {value!r}")
        return RobotRoot(six, label)


@dataclass(frozen=True)
class ActiveFrames:
    """The $BASE / $TOOL active when a program starts, as its user states them (``compensate
    --base/--tool``, the settings' ``base`` / ``tool``), for programs that do not set them
    before their targets. Each is None (not stated: such targets are left as written), an int
    n (``BASE_DATA[n]`` / ``TOOL_DATA[n]`` of ``$config.dat``; 0 = ``$NULLFRAME``), or six
    floats X,Y,Z,A,B,C; the tool may also be ``"model"``: the model's own tool (its card).
    ``robroot``: $ROBROOT where the program does not set it (``RobotRoot``; None: not known,
    robot base = world assumed and said once, P224)."""

    base: int | tuple | None = None
    tool: int | tuple | str | None = None
    robroot: RobotRoot | None = None
    # the external units the user states (``--external``, settings ``external``, the simulated
    # robot's [[external]]: postproc.robot.external.ExternalUnit), for every dialect
    external: tuple = ()

    @property
    def frames_stated(self) -> bool:
        """Whether $BASE or $TOOL is stated (what only KRL and URScript programs take)."""
        return self.base is not None or self.tool is not None

    @staticmethod
    def parse(value, which: str):
        """``"N"``, ``"X,Y,Z,A,B,C"`` (or an int / a list of six numbers from TOML), ``"model"``
        (tool only) → the value kept; ValueError with the reason otherwise."""
        if value is None:
            return None
        if isinstance(value, bool):
            raise ValueError(f"{which}: expected N or X,Y,Z,A,B,C, not {value!r}")
        if isinstance(value, int):
            items = [value]
        elif isinstance(value, (list, tuple)):
            items = list(value)
        elif isinstance(value, str):
            if which == "tool" and value.strip().lower() == "model":
                return "model"
            items = [v.strip() for v in value.split(",")]
        else:
            raise ValueError(f"{which}: expected N or X,Y,Z,A,B,C, not {value!r}")
        if len(items) == 1:
            try:
                n = int(str(items[0]))
            except ValueError:
                n = -1
            if n < 0:
                raise ValueError(f"{which}: expected a {which.upper()}_DATA number ≥ 0 or X,Y,Z,A,B,C, not {value!r}")
            return n
        if len(items) != 6:
            raise ValueError(f"{which}: expected six numbers X,Y,Z,A,B,C (mm, deg), got {len(items)}")
        try:
            six = tuple(float(v) for v in items)
        except (TypeError, ValueError):
            raise ValueError(f"{which}: expected six numbers X,Y,Z,A,B,C (mm, deg), not {value!r}") from None
        if not all(np.isfinite(six)):
            raise ValueError(f"{which}: X,Y,Z,A,B,C must be finite numbers")
        return six

    @classmethod
    def of(cls, base=None, tool=None, robroot=None, external=()) -> "ActiveFrames | None":
        """From user values (strings, ints, lists; None = not stated; ``robroot`` a RobotRoot or
        six numbers; ``external`` ExternalUnits); None when none is."""
        if base is None and tool is None and robroot is None and not external:
            return None
        if robroot is not None and not isinstance(robroot, RobotRoot):
            robroot = RobotRoot.parse(robroot, f"robroot {robroot}")
        return cls(base=cls.parse(base, "base"), tool=cls.parse(tool, "tool"), robroot=robroot,
                   external=tuple(external or ()))

    @classmethod
    def stated(cls, base=None, tool=None, settings: "ActiveFrames | None" = None,
               robroot: RobotRoot | None = None, external=()) -> "ActiveFrames | None":
        """The command line's ``--base`` / ``--tool`` / ``--robroot`` / ``--external`` over the
        settings' (each on its own); a value that is not N / X,Y,Z,A,B,C is refused:
        PostprocError P222."""
        from ..core.diagnostics import PostprocError

        try:
            given = cls.of(base=base, tool=tool, robroot=robroot, external=external)
        except ValueError as exc:
            raise PostprocError(str(exc), "--" + str(exc).split(":")[0], 0, 0, P222) from None
        if settings is None or given is None:
            return given or settings
        return cls(base=given.base if given.base is not None else settings.base,
                   tool=given.tool if given.tool is not None else settings.tool,
                   robroot=given.robroot if given.robroot is not None else settings.robroot,
                   external=given.external or settings.external)


@dataclass
class Targets:
    """Columns, one row per Cartesian target, in program order.

    poses      [N, 6] float64  X,Y,Z,A,B,C in the target's own frame; NaN = a component
                               the program leaves out and that could not be filled
    spans      [N, 3, 2] int64 (start, end) of the X, Y, Z number tokens in
                               ``Program.texts[file]``; -1 where the component is absent
    file       [N] int32       index into Program.files of the text the numbers stand in
    line, col  [N] int32       1-based location of the target's aggregate (for messages)
    frame      [N] int32       index into Program.frames; -1 = left as written: the base
                               (P201) or the tool (P203: $TOOL set but not resolvable, e.g.
                               TOOL_DATA[6] not known, or unknown after a call) is not known,
                               or not set and not stated (P220/P221)
    motion     [N] int8        index into MOTIONS
    config     [N, 2] int16    (S, T) the target states (integers, 'B010' / 'H2' literals,
                               inline or in the POS/E6POS variable's value); -1 where it
                               does not state it (then a PTP takes the configuration nearest
                               the current axes, LIN/CIRC keep the current one)
    joints     [N, 6] float64  the controller's joint angles (deg) where the program gives
                               them (a pose list's q1..q6), NaN elsewhere (None: none given)
    abc_spans  [N, k, 2] int64 (start, end) of the orientation's k tokens in the program's
                               form (``Program.orientation``: A, B, C; RAPID's q1..q4; URScript's
                               rx, ry, rz), -1 where absent (None: the reader does not locate
                               them; ``compensate --orientation`` needs them)
    orientation [N, k] float64 the orientation's numbers as written, where the form is not A,B,C
                               (None: ``poses[:, 3:6]`` are them); ``written_orientation``
    prev       [N] int32       the row executed just before this one (its command is this row's
                               previous pose), -1 none known (the program's start, or after a
                               motion whose target is not a row); None: each row's is the row
                               before it (a pose list, a straight-line program)
    offset     [N, 3] float64  what the program adds to each X/Y/Z token before the motion uses it
                               (``XA.Z = XS1.Z + 300``: the token is XS1's Z): the token reads
                               pose − offset (None: zeros)
    twin       [N] int32       the first row with the same X/Y/Z tokens (one target executed
                               several times: in a loop, a routine called twice, after a merge),
                               -1 for a first one (None: every row is)
    group      [N] int32       rows that share any X/Y/Z token: one group, id ≥ 0; -1 alone (None:
                               every row is): a token is rewritten only where every row agrees
    start      [N, 6] float64  the axis position (deg, the controller's) the robot stands at
                               before the row where its predecessor is a joint motion to known
                               axis values (``PTP HOME``, ``movej(home_q)``; ``prev`` -1), NaN
                               elsewhere (None: no row has one): the arm configuration a
                               Cartesian target after it keeps
    relative   [N] int32       a relative motion's target (KRL ``LIN_REL {Z 20}`` after a known
                               start; its frame is the start's pose × the move, its X/Y/Z the
                               move's numbers): the row of the motion it starts from — the robot
                               moves from that row's command, so the rewrite takes that row's
                               correction off its numbers —; -1 an absolute target, or a start
                               without a row (None: every row is absolute)
    load       [N, 4] float64  the payload the robot carries at the row: mass (kg), centre of mass
                               cx, cy, cz (mm, flange frame); NaN where the program sets none (the
                               model's reference load, or ``--load``) or where it is not known
                               (None: no row has one and none is unknown)
    load_cause [N] int32       -1, or why the row's payload is not statically known: an index
                               into ``load_causes`` ((path, line, col, why, schedule) of each
                               cause: P235; ``schedule`` a payload schedule number its user
                               may state, Fanuc's PAYLOAD[n], else None)

    A frame's ``tool`` of None means the model's tool, stated by the user (``--tool model``);
    a $TOOL (or $BASE) that is not set and not stated (P221/P220) or set but not known makes
    the target's frame -1.
    """

    poses: np.ndarray
    spans: np.ndarray
    file: np.ndarray
    line: np.ndarray
    col: np.ndarray
    frame: np.ndarray
    motion: np.ndarray
    config: np.ndarray | None = None  # None: no target states S/T (filled with -1)
    joints: np.ndarray | None = None
    abc_spans: np.ndarray | None = None
    orientation: np.ndarray | None = None
    prev: np.ndarray | None = None
    offset: np.ndarray | None = None
    twin: np.ndarray | None = None
    group: np.ndarray | None = None
    start: np.ndarray | None = None
    relative: np.ndarray | None = None
    load: np.ndarray | None = None
    load_cause: np.ndarray | None = None
    load_causes: list = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.config is None:
            self.config = np.full((len(self.poses), 2), -1, np.int16)

    def written_orientation(self, rows=slice(None)) -> np.ndarray:
        """The orientation numbers of ``rows`` as written, in the program's form [n, k]."""
        return self.poses[rows, 3:6] if self.orientation is None else self.orientation[rows]

    def __len__(self) -> int:
        return len(self.poses)


class TargetsBuilder:
    """Collects targets row by row (plain lists: cheap to append) and builds the columns."""

    def __init__(self) -> None:
        self.poses: list = []  # each a sequence of 6 floats
        self.spans: list = []  # each a sequence of 6 ints (x0, x1, y0, y1, z0, z1)
        self.file: list[int] = []
        self.line: list[int] = []
        self.col: list[int] = []
        self.frame: list[int] = []
        self.motion: list[int] = []

    def add(self, pose, spans, file: int, line: int, col: int, frame: int, motion: int) -> None:
        self.poses.append(pose)
        self.spans.append(spans)
        self.file.append(file)
        self.line.append(line)
        self.col.append(col)
        self.frame.append(frame)
        self.motion.append(motion)

    def __len__(self) -> int:
        return len(self.poses)

    def build(self) -> Targets:
        n = len(self.poses)
        return Targets(
            poses=np.array(self.poses, dtype=np.float64).reshape(n, 6),
            spans=np.array(self.spans, dtype=np.int64).reshape(n, 3, 2),
            file=np.array(self.file, dtype=np.int32),
            line=np.array(self.line, dtype=np.int32),
            col=np.array(self.col, dtype=np.int32),
            frame=np.array(self.frame, dtype=np.int32),
            motion=np.array(self.motion, dtype=np.int8),
        )


@dataclass
class Program:
    """A parsed program: its files (paths or ``<stdin>``), their texts, targets in order."""

    files: list[str]
    texts: list[str]
    targets: Targets
    frames: list[Frame] = field(default_factory=list)
    diagnostics: list[Diagnostic] = field(default_factory=list)
    # what the reader assumed and says once, without leaving a target (P224: robot base = world)
    notes: list[Diagnostic] = field(default_factory=list)
    dialect: str = ""
    # the targets' frames map into the robot controller's base (programs: True); a pose list's
    # rows are in the frame its ``# frame:`` line states (controller: True, model: False) or,
    # unstated, in the model's frame where that is the controller's base (None)
    in_controller_base: bool | None = True
    stamps: dict[int, str] = field(default_factory=dict)  # file index → stamp line found in it
    newlines: list[str] = field(default_factory=list)  # dominant line ending per file
    comment: str = ";"  # the dialect's comment marker, for the stamp line
    config: list[str] | None = None  # the $config.dat texts it was read with (to read it again)
    active: ActiveFrames | None = None  # the $BASE/$TOOL/$ROBROOT stated for it (to read it again)
    from_text: bool = False  # made by read_program: its texts, read again, give it again
    # the rest of what read_program read it with (to read it again): a backup's system files
    # (``data``: path → text), the RAPID task's name (``task``), the ``registers`` setting
    read_with: dict = field(default_factory=dict)
    # some targets are variables (declared or assigned aggregates), whose numbers other
    # statements may read too (e.g. as a frame); False: every target is an inline aggregate
    named_targets: bool = True
    # mm per unit of the X/Y/Z numbers as written (URScript: metres, 1000): poses are held in mm,
    # the rewrite writes and the guards read the tokens in the file's own unit
    unit: float = 1.0
    # the form its orientation numbers are written in (frames.ORIENTATION_NAMES): "abc" (A,B,C
    # degrees), "quaternion" (RAPID's q1..q4 = w,x,y,z), "rotvec" (URScript's rx,ry,rz, radians)
    orientation: str = "abc"
    # [N] bool: the target states an arm configuration in a form postproc does not translate to
    # joint angles (URScript's get_inverse_kin qnear): a model that takes joint angles leaves it as
    # written (P309; configuration.stated_configuration)
    unmapped_configuration: np.ndarray | None = None
    # rows the analysis leaves as written, by the code that says why (P217: a target whose numbers
    # something else reads too); each was warned at its line
    held: dict = field(default_factory=dict)
    # each target row's motion statement (ir.Loc; None: the row's own place), where one point is
    # the target of several motions: messages about such a point name the motions involved
    sites: list = field(default_factory=list)
