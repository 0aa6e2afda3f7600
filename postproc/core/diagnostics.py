"""Errors and warnings that point at a place in an input: ``path:line:col: CODE message``.

Every module raises :class:`PostprocError` for bad input and collects :class:`Diagnostic`
warnings; only the CLI decides how they are printed and which exit code they map to.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

# Exit codes shared by every subcommand (documented in the README).
EXIT_OK = 0
EXIT_FINDINGS = 1  # check found problems / verify exceeded --max-mean
EXIT_ERROR = 2  # bad input, usage error, internal error: nothing was written
EXIT_INTERRUPTED = 130  # Ctrl-C (128 + SIGINT, as shells report it): nothing was written


@dataclass(frozen=True)
class Code:
    """One diagnostic code of the registry: its usual severity and a one-line meaning."""

    code: str
    severity: str  # "error" | "warning" | "note": what it usually is (some are errors with --strict, see the meaning)
    meaning: str


# The registry: every code postproc reports, in order (README "Diagnostic codes" is generated
# from it: `postproc check --list-codes --markdown`). Modules use the names (`code=P101`);
# adding a code is one line here.
CODES: dict[str, Code] = {}


def _code(code: str, severity: str, meaning: str) -> str:
    assert code not in CODES and severity in ("error", "warning", "note"), code
    CODES[code] = Code(code, severity, meaning)
    return code


# P1xx: syntax and structure of an input, reading and writing files
P101 = _code("P101", "error", "syntax error")
P102 = _code("P102", "error", "structure error: a block, module or routine not opened or not closed where it must be")
P103 = _code("P103", "error", "a target (or its frame) that is not a finite number, or beyond float32; a KRL data list's "
             "initial value that is no constant (a name such as NaN, a function call)")
P104 = _code("P104", "error", "not a program of this kind: no DEF / MODULE, a header without x,y,z, a wrong number of fields")
P105 = _code("P105", "error", "an empty program or pose list; ;FOLD without ;ENDFOLD (or the reverse) is a warning")
P106 = _code("P106", "error", "a binary file (NUL bytes), not a robot program")
P107 = _code("P107", "error", "no such file or directory, or one that cannot be read or created")
P108 = _code("P108", "error", "a file whose dialect is not known from its suffix")
P109 = _code("P109", "error", "a program with a .dat cannot be written to standard output")
P110 = _code("P110", "error", "an output that cannot be written, or -o that is the input (--in-place allows it)")
P111 = _code("P111", "error", "a program too large for this machine's memory")
P112 = _code("P112", "error", "several $config.dat in one cell: give --config")
P117 = _code("P117", "error", "a URScript pose p[…] that has not six components (x, y, z, rx, ry, rz)")
P118 = _code("P118", "error", "Fanuc LS: a malformed frame file (--frames), a Cartesian position without X, Y, Z, W, P, R "
             "or with other units than mm/deg, or one in the RX, RY, RZ, RW, RP, RR form (not read)")
P119 = _code("P119", "error", "files of several robot families given as one run (KRL, RAPID, URScript, Fanuc LS): one run "
             "is one robot's programs; or a file given that no reader takes (a controller backup's file of an unknown kind)")
P190 = _code("P190", "error", "last check before writing: a span or new number that does not read back (a postproc bug)")
P191 = _code("P191", "error", "last check before writing: the new text does not read again as the same program (a postproc bug)")
# P2xx: frames and targets not statically known (the target is left as written)
P201 = _code("P201", "warning", "the target's base (frame) is not statically known: left as written")
P203 = _code("P203", "warning", "the target's $TOOL is not known: left as written")
P210 = _code("P210", "warning", "a relative motion (_REL, INC) whose start is not known statically: its absolute target is known only at run time")
P211 = _code("P211", "warning", "a target computed at run time (or an element the reader cannot enumerate)")
P212 = _code("P212", "warning", "target position not fully known: left as written")
P213 = _code("P213", "warning", "target orientation not known (the model's nominal attitude is assumed)")
P214 = _code("P214", "warning", "a point derived from another at run time (P2 = P1; P2.Z = …): it carries the other's correction")
P215 = _code("P215", "warning", "a target name declared in none of the files read (a global whose data list was not given)")
P216 = _code("P216", "error", "partial aggregate refused (compensate --no-fill-partial; filled in by default)")
P217 = _code("P217", "warning", "a target whose numbers other statements read too (a frame built from the point, a "
             "condition, a computation, a routine not read): compensating it would change them, left as written")
P218 = _code("P218", "warning", "a pose list that does not state its frame (# frame: controller or # frame: model) for a model "
               "whose frame is not the controller's base (the card's controller_base): left as written")
P220 = _code("P220", "warning", "$BASE (or both $BASE and $TOOL) not set before the target and not stated with --base: "
             "left as written")
P221 = _code("P221", "warning", "$TOOL not set before the target and not stated with --tool: left as written")
P222 = _code("P222", "error", "--load not MASS[,CX,CY,CZ] (a mass ≥ 0); --base / --tool not N, X,Y,Z,A,B,C (or model for the tool), naming a BASE_DATA[n] / "
             "TOOL_DATA[n] not in the $config.dat given, or given for a pose list / RAPID program")
P223 = _code("P223", "warning", "a point an INTERRUPT handler switched on may assign (INTERRUPT DECL … DO P = … / a DEF "
             "that assigns it): left as written")
P224 = _code("P224", "note", "(compensate -v, check) $ROBROOT not known (no --robroot, no backup's Mada/$machine.dat) and "
             "not set by the program: robot base = world ($NULLFRAME) assumed, said once per program")
P225 = _code("P225", "warning", "the robot's base or the target's frame moves with external axes (KRL: $ROBROOT on an "
             "external kinematic, $machine.dat $EX_KIN … #ERSYS, a base on a turntable; RAPID: a robtarget's eax_a…f in "
             "use, a work object a mechanical unit moves; LS: GP2 / extended axes) and its kinematics are not given "
             "(--external, machine data), or the target does not state that axis: left as written")
P226 = _code("P226", "error", "--robroot / settings robroot not X,Y,Z,A,B,C or a $machine.dat; a $machine.dat without "
             "$ROBROOT_C or with a malformed one; several machine data in one cell")
P227 = _code("P227", "error", "an external unit's description (--external, the settings' external, a robot description's "
             "[[external]], the machine data's $ETn_…) that is malformed or not one postproc can take")
P230 = _code("P230", "warning", "one set of numbers the program executes more than once (in a loop, a routine called "
             "twice, after a branch, copied into another point) where the runs need different corrections (other "
             "frames, tools, offsets, approaches) or one of them is left as written: left as written at every run")
P231 = _code("P231", "warning", "a point the program also moves to at an offset (RAPID Offs/RelTool, a KRL copy with a "
             "component changed): its numbers are compensated for the motions to the point itself, and the motions at "
             "an offset move with that correction, not their own (which motions, at their path:line, and how far off is "
             "said): those are not compensated")
P232 = _code("P232", "warning", "a call to a routine in none of the files read (not an instruction postproc knows): "
             "it may move to the global targets, and change the tools and frames, it can see (the message names them); "
             "the run is not complete (compensate exits 1)")
P233 = _code("P233", "warning", "a tool, work object, frame or target that a routine of the task changes (an assignment, "
             "an argument to a VAR/PERS/INOUT parameter, an instruction that sets it) in a routine the program's entry "
             "does not run (the pendant, an event routine or another task can): a run-time value, its targets left as "
             "written")
P234 = _code("P234", "note", "a value a backup's system files give (Fanuc posreg.va, numreg.va, sysframe.va; RAPID "
             "SYSPAR): used as the controller had it when the backup was taken (the note names the register and the "
             "file); settings 'registers = \"runtime\"' makes registers run-time values")
P235 = _code("P235", "warning", "the payload at a target is not statically known (a load set by code not read, from "
             "a run-time value, LOAD_DATA without $config.dat, a Fanuc PAYLOAD[n] without its schedule, branches that "
             "leave it different) and the model takes the load: left as written, said at the cause naming the motions; "
             "state it with --load or settings 'load' where the program sets none")
P236 = _code("P236", "note", "the program sets payloads but the model does not take a load: every target is compensated "
             "for the load the model was measured with (said once, naming where the program sets them)")
# P3xx: the model, its envelope and the robot
P301 = _code("P301", "warning", "target outside the model's training envelope (error with --strict)")
P302 = _code("P302", "error", "target beyond the nominal robot's reach (model metadata 'reach')")
P303 = _code("P303", "error", "the model's correction exceeds max_correction")
P304 = _code("P304", "error", "the program's $TOOL is not the model's tool")
P305 = _code("P305", "error", "the model returns NaN or inf at this target")
P306 = _code("P306", "error", "an ONNX file that is not a compensator (inputs, outputs, model card), or lacks an output asked for")
P307 = _code("P307", "error", "no such model")
P308 = _code("P308", "error", "--iterations outside 1…100, or --max-correction not a positive number")
P309 = _code("P309", "error", "no inverse-kinematics solution for this target (a warning, left as written, for models with a joints input)")
P310 = _code("P310", "error", "the model was trained on another robot than the configured one, or (a model that "
             "takes joint angles) on an arm of another controller than the program's dialect is written for")
P311 = _code("P311", "error", "a model with a joints input for a robot postproc has no description of")
P312 = _code("P312", "error", "--orientation where a target does not write all of its orientation's numbers (A/B/C, q1..q4, rx,ry,rz) or the reader does not locate them")
P313 = _code("P313", "warning", "the target's S/T is another arm configuration than the model evaluates: left as written")
P314 = _code("P314", "note", "(compensate -v, check) a KRL LIN or CIRC writes S/T the controller does not read: the "
             "robot runs it in the configuration it is in, another than the S/T written, and it is compensated for "
             "that one (the S/T stay as written)")
P317 = _code("P317", "error", "train --update: the old model has no identification to re-fit (a DNN/gpso model, an "
             "older card), --method is not hybrid/kinematic, or the new rows name other tools")
P318 = _code("P318", "error", "train --update: the old model is of another robot description than --robot (name or "
             "nominal geometry)")
P319 = _code("P319", "warning", "the target's $TOOL is far from the TCPs the model was measured with: the tool mount's "
             "rotation they could not separate may add ≥ 0.1 mm there (compensated; error with --strict)")
P320 = _code("P320", "error", "the data's tool sources disagree (--tool, # tool:, tool_x..tool_c), a malformed # tool: "
             "line, several tools for a pose-only method, or measure --tool for a plan that names its tools")
P321 = _code("P321", "note", "(compensate -v, models with an approach input) a joint barely moving at the target stays "
             "in its backlash dead band: compensated with the command of the smallest worst case over both sides")
P322 = _code("P322", "note", "(compensate -v, models with a previous_pose input) a target the program reaches from "
             "several places (after a branch, in a loop): its runs need slightly other commands (the approach), "
             "compensated with the one of the smallest worst case over them")
P323 = _code("P323", "note", "(compensate --orientation) targets near B = ±90° (gimbal lock: A and C turn about one "
             "axis there): the A,B,C triple nearest the one written changes A and C by much more than the rotation it "
             "corrects (both are said, once per file, at its first such target)")
P330 = _code("P330", "error", "a robot description that cannot be read or is not TOML")
P331 = _code("P331", "error", "a robot description with an unknown or misplaced table or key")
P332 = _code("P332", "error", "a robot description with a bad value")
P333 = _code("P333", "error", "a robot geometry the closed-form inverse kinematics does not cover")
P335 = _code("P335", "error", "poses out of the robot's reach (plan, simulator, ISO 9283 cube)")
P336 = _code("P336", "warning", "the model's error_std (its stated uncertainty) at the target exceeds --max-std "
             "(default: the card's uncertainty.max_std_mm); an error under --strict")
P337 = _code("P337", "warning", "plan --for: a program target the measurement data (--data) does not cover (its arm "
             "configuration, its tool, or a joint outside the data's arcs); as a note: targets not planned for")
P338 = _code("P338", "warning", "a target's payload differs from every load the model was measured with by more than it "
             "can extrapolate (the card's loads): left as written")
P339 = _code("P339", "note", "the model takes a load and the program does not set the payload before these targets "
             "(or not statically): compensated for --load where given, else for the load the model was measured "
             "with (its reference); state it with --load")
P340 = _code("P340", "note", "(compensate, check) the model is a demonstration model of a simulated robot (its card's "
             "'demonstration'): it knows nothing of a real robot; train one for yours")
P341 = _code("P341", "warning", "(compensate, check) the model does not take the load, and the program's payload is not "
             "the one it was measured with: its targets are compensated, the deflection under the other payload "
             "stays")
# P4xx: stamps and compensated outputs
P401 = _code("P401", "error", "already compensated (a stamp line): compensate refuses unless --force")
P402 = _code("P402", "error", "compensated with a model other than the configured one")
P403 = _code("P403", "error", "compensated twice")
P404 = _code("P404", "error", "the .src and .dat do not come from one compensation")
P405 = _code("P405", "error", "compensated output is stale: re-compensating its source gives other bytes")
P406 = _code("P406", "error", "compensated output is missing")
P407 = _code("P407", "warning", "compensated output has no source")
P408 = _code("P408", "error", "the controller's own absolute-accuracy model is active (the backup's $ABS_ACCUR in "
             "Mada/$machine.dat or $custom.dat): compensating would correct the error twice; compensate refuses "
             "unless --force")
P409 = _code("P409", "warning", "the controller's own absolute-accuracy model is suppressed for now ($ABS_ACCUR "
             "#SUPPRESSED): the program is compensated, and would be corrected twice where the model is switched on again")
# P5xx: data (measurement and pose CSV files, registration, plans)
P500 = _code("P500", "error", "a data file that cannot be read, is empty or has no rows")
P501 = _code("P501", "error", "a data file's columns: missing, misnamed, repeated, or given twice")
P502 = _code("P502", "error", "a data value that is not a finite number")
P503 = _code("P503", "error", "a data row of the wrong width, or rows that do not match the program or the earlier measurement")
P504 = _code("P504", "error", "a duplicate pose in the measurements (average repeated measurements into one row)")
P505 = _code("P505", "error", "too few measured points for the model's parameters")
P506 = _code("P506", "error", "--val-fraction leaves no training or validation rows")
P507 = _code("P507", "error", "measured columns in the tracker's frame: train with --register")
P508 = _code("P508", "error", "the robot description does not fit the data (or a name where a description file is needed)")
P509 = _code("P509", "error", "uncompensated errors too large: the measured points are in another frame or unit")
P510 = _code("P510", "error", "a registration the points do not determine (too few, collinear, rank < 2)")
P511 = _code("P511", "error", "registration inputs that are not matching [N, 3] arrays of finite points")
P512 = _code("P512", "error", "a bad plan or test parameter (box, count, wrist, tool, module name, cycles)")
P513 = _code("P513", "error", "measurements not in the robot base frame where they must be")
P514 = _code("P514", "warning", "a measurement CSV's s,t (no q1..q6) without an IK solution: those rows left out "
             "(refused when no row has one or the arm has no closed-form IK)")
P515 = _code("P515", "error", "a_meas,b_meas,c_meas more than 5° (median) from the commanded orientation: another "
             "frame, the probe's own axes or radians")
P516 = _code("P516", "error", "a training option the method does not have (--search, --optimizer: the pose-only "
             "networks'; it was ignored for the identified methods)")
P517 = _code("P517", "error", "positions in another unit than mm: a pose list or measurement CSV whose every x, y, z "
             "lies within ±5 for a robot that reaches metres (metres), or whose uncompensated errors are ~1/1000 of "
             "any robot's")
P518 = _code("P518", "error", "registered rows that do not fit one tracker frame (rigid fit residual far above a robot's "
             "error): the data hold several set-ups; name them (a 'campaign' column, or each campaign's file given "
             "to train)")
P519 = _code("P519", "error", "campaigns the training cannot use: a campaign too small to register (fewer than 6 rows), "
             "a pose-only network (one frame) or --update (its rows are one new campaign) given several")
P530 = _code("P530", "error", "an imported measurement file that does not state its units or its frame (no silent "
             "metres): a 'units:' / 'frame:' line or units in the header")
P531 = _code("P531", "error", "three-reflector measurements: the reflectors' places on the TCP frame missing or not "
             "three points, or a row whose three centres do not fit them (a swapped or moved SMR)")
P532 = _code("P532", "error", "imported points and commanded poses that do not match (a name without its pose, a "
             "pose measured twice, other counts where matched by order)")
P533 = _code("P533", "error", "postproc export: a nominal URDF that is not XML, has no chain of six revolute joints, "
             "or whose joints are not the robot description's (other axes, joint zeros, directions or lengths)")
# P6xx: a command's own inputs
P601 = _code("P601", "error", "verify's original and compensated programs are not one program")
P610 = _code("P610", "error", "bad settings (unknown key, bad value, bad TOML)")

# Reader warnings whose target never became a row of Targets: each one is a Cartesian
# target left as written (compensate counts them and exits 1; one place for the rule).
LEFT_AS_WRITTEN = frozenset({P210, P211, P212, P214, P215, P217, P223, P233})

# Warnings that make a run incomplete although no target was left on their account: code the
# program runs that postproc did not read (compensate exits 1, the summary says how many).
INCOMPLETE = frozenset({P232})


def codes_table(markdown: bool = False) -> str:
    """The registry as text: ``CODE severity meaning`` lines, or a Markdown table (the README's)."""
    if not markdown:
        return "".join(f"{c.code} {c.severity:<7} {c.meaning}\n" for c in CODES.values())
    rows = "".join(f"| {c.code} | {c.severity} | {c.meaning} |\n" for c in CODES.values())
    return "| code | severity | meaning |\n|---|---|---|\n" + rows


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


@dataclass(frozen=True)
class Diagnostic:
    """One finding about an input, located by 1-based line and column (0 = unknown)."""

    path: str
    line: int
    col: int
    code: str
    message: str
    severity: str = "warning"  # "warning" | "error"

    def format(self) -> str:
        # one line whatever the input held: a quoted '\r' or ESC would garble the terminal
        message = _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), self.message)
        if self.line <= 0:  # about the whole file (unreadable, not a model, ...)
            return f"{self.path}: {self.code} {message}"
        return f"{self.path}:{self.line}:{self.col}: {self.code} {message}"


class PostprocError(Exception):
    """Bad input or an impossible request. Carries a location when there is one."""

    def __init__(self, message: str, path: str = "", line: int = 0, col: int = 0, code: str = "E000"):
        super().__init__(message)
        self.message = message
        self.path = path
        self.line = line
        self.col = col
        self.code = code

    def diagnostic(self) -> Diagnostic:
        return Diagnostic(self.path, self.line, self.col, self.code, self.message, "error")

    def __str__(self) -> str:
        if not self.path:
            return f"{self.code} {self.message}"
        return self.diagnostic().format()


# places (path:line) a message names before "and N more"
MAX_PLACES = 5


def listed(places: list[str]) -> str:
    """``a.src:3, a.src:7 and 4 more``: the first MAX_PLACES places a message names, then how many others."""
    more = len(places) - MAX_PLACES
    return ", ".join(places[:MAX_PLACES]) + (f" and {more} more" if more > 0 else "")


def line_col(text: str, offset: int) -> tuple[int, int]:
    """1-based (line, column) of a character offset in ``text``."""
    line = text.count("\n", 0, offset) + 1
    start = text.rfind("\n", 0, offset) + 1
    return line, offset - start + 1


class LineIndex:
    """``line_col`` for many offsets of one text: the line starts found once (a reader that
    warns at thousands of targets stays linear)."""

    def __init__(self, text: str):
        self.text = text
        self._starts = None

    def _line_starts(self):
        if self._starts is None:
            import numpy as np

            newline = np.frombuffer(self.text.encode("latin-1", "replace"), np.uint8) == 10
            self._starts = np.concatenate([[0], np.flatnonzero(newline) + 1])
        return self._starts

    def line_col(self, offset: int) -> tuple[int, int]:
        starts = self._line_starts()
        k = int(starts.searchsorted(offset, "right")) - 1
        return k + 1, offset - int(starts[k]) + 1

    def lines_cols(self, offsets):
        """1-based (lines, columns) int32 arrays of many offsets at once (a reader's targets)."""
        import numpy as np

        starts = self._line_starts()
        k = starts.searchsorted(np.asarray(offsets, np.int64), "right") - 1
        return (k + 1).astype(np.int32), (np.asarray(offsets, np.int64) - starts[k] + 1).astype(np.int32)


def toml_error(exc: Exception, path: str, code: str) -> "PostprocError":
    """A TOML syntax error (tomllib's, which puts "(at line L, column C)" in its message) as a
    located PostprocError with ``code``."""
    m = re.search(r"\(at line (\d+), column (\d+)\)", str(exc))
    line, col = (int(m.group(1)), int(m.group(2))) if m else (0, 0)
    message = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
    return PostprocError(f"not valid TOML: {message}", str(path), line, col, code)
