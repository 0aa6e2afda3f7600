"""The compensator: one ONNX file that maps commanded TCP poses to positioning errors.

Contract (version 1), shared by ``train`` (which writes it) and ``compensate`` (which runs it):

* input ``pose``: float32 [N, 6] = X, Y, Z (mm), A, B, C (deg) in the robot base frame;
* optional input ``previous_pose``: float32 [N, 6], the pose commanded just before each
  target (program order), for models that learn direction-dependent error (backlash);
  ``compensate`` passes the previous target's compensated command (the first target's
  previous pose is the target itself: nothing is known before it); models without it are
  plain pose → error maps;
* optional input ``joints``: float32 [N, 6] deg, the controller's joint angles at each
  target (from its S/T, or a measurement's q1..q6); a row of NaN = unknown. The model uses
  them as the *configuration*: it solves the nominal IK of ``pose`` on the branch those
  angles are on (shoulder / elbow / wrist read from them) and evaluates its identified arm
  there; NaN rows take the branch the model identified from its training data. So the fixed
  point below stays right: the caller passes the joints of the *target* P once, and every
  iteration's command c (a few mm from P) is solved on that branch — q(c), not q(P).
  ``Compensator`` feeds NaN when the caller has none;
* optional input ``tool``: float32 [N, 6] (X, Y, Z mm, A, B, C deg of the TCP on the flange),
  NaN = the model's own tool (the card's ``tool``); for physical models that compute the error
  at any TCP. (Declared here so that callers can pass it; the shipped training does not
  export it yet.)
* output ``error``: float32 [N, 3] mm, E = P_target − P_actual; normalisation lives inside
  the graph;
* optional output ``ik_joints``: float32 [N, 6] deg, the controller's joint angles (nominal IK,
  on the branch of ``joints`` where given) the model computed for ``pose``, wrapped to
  [−180, 180): with ``envelope.joints`` in the card, ``compensate`` warns for targets whose
  joints lie outside the trained ranges (a pose-box can hide a wrist flip); the model itself
  leaves out its learned parts that do not extrapolate (gear-ripple orders, residual networks)
  outside those ranges and keeps the physical ones. (Models written before the ``joints``
  input have this output named ``joints``: still read. ONNX cannot name an input and an
  output alike.)
* optional output ``rotation_error``: float32 [N, 3] deg, the orientation error as a rotation
  vector of nominal → actual in the base frame (``compensate --orientation``);
* ``metadata_props`` (values JSON-encoded where structured): ``postproc_contract`` "1",
  ``name``, ``robot``, ``tool`` {"name", "frame"}, ``envelope`` {"box": [x0,x1,y0,y1,z0,z1],
  "attitude": [A,B,C], "range": deg, optional "joints": [[lo, hi] × 6] deg}, ``reach`` {"center": [x,y,z], "radius_min",
  "radius_max"} (TCP distance from the shoulder), ``data_sha256``, ``method``,
  ``structure``, ``accuracy`` {"val_mean_mm", "val_max_mm", ...}, ``iterations``.

The command sent for target P is c = P + Ê(c), solved by fixed-point iteration from
c₀ = P (one iteration = the method's c = P + Ê(P)).
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from .diagnostics import P306, P307, P308, PostprocError
from .resources import model_path

CONTRACT_VERSION = "1"
INPUT_POSE = "pose"
INPUT_PREVIOUS = "previous_pose"
OUTPUT_ERROR = "error"
INPUT_JOINTS = "joints"
INPUT_TOOL = "tool"
OUTPUT_JOINTS = "ik_joints"
LEGACY_OUTPUT_JOINTS = "joints"  # (the output's name before the ``joints`` input existed)
OUTPUT_ROTATION = "rotation_error"
# (8192 rows: the intermediates of the hybrid graph stay in cache, 11 % faster than 65536; measured)
PREDICT_BATCH = 8192
# Rows per chunk of ``command_chunks``: the unit compensate overlaps model runs and rewriting by.
COMMAND_CHUNK = 1 << 16
# Joint ranges of the envelope are widened by this share of each range (+ 0.5°) before warning.
JOINT_MARGIN = 0.05
# More fixed-point iterations than this is a typo or a hostile model card, not a method (a hang).
MAX_ITERATIONS = 100


def _json_or_text(value: str):
    try:
        return json.loads(value)
    except (ValueError, TypeError):
        return value


@dataclass
class Envelope:
    """The training envelope: a box of positions and a range of attitudes around a centre."""

    box: np.ndarray  # [6] x0,x1,y0,y1,z0,z1
    attitude: np.ndarray  # [3] A,B,C
    range: float  # ± deg per component
    joints: np.ndarray | None = None  # [6, 2] deg: each joint's range over the training poses

    def outside(self, poses: np.ndarray, tolerance_mm: float = 1.0, tolerance_deg: float = 0.5) -> np.ndarray:
        """Boolean mask of poses [N, 6] outside the box or the attitude range."""
        lo, hi = self.box[0::2] - tolerance_mm, self.box[1::2] + tolerance_mm
        xyz = poses[:, :3]
        out = np.any((xyz < lo) | (xyz > hi), axis=1)
        # per component; angles wrap at ±180. A rotation has two A,B,C triples, (A, B, C) and
        # (A+180, 180−B, C+180), and compensate passes the one with |B| ≤ 90: an envelope
        # around B = 90 (tool pointing down) holds half its poses in the other triple.
        abc = poses[:, 3:6]
        alt = abc + np.array([180.0, 0.0, 180.0])
        alt[:, 1] = 180.0 - abc[:, 1]
        limit = self.range + tolerance_deg
        d, d_alt = ((t - self.attitude + 180.0) % 360.0 - 180.0 for t in (abc, alt))
        return out | (np.any(np.abs(d) > limit, axis=1) & np.any(np.abs(d_alt) > limit, axis=1))

    def outside_joints(self, q_deg: np.ndarray) -> np.ndarray:
        """Boolean mask of joint angles [N, 6] (deg) outside the trained ranges widened by
        JOINT_MARGIN of each range + 0.5° (the training poses sample the box, not its joint-space
        hull: a pose inside the box may turn a joint a little past what any training pose did)."""
        if self.joints is None:
            return np.zeros(len(q_deg), bool)
        lo, hi = self.joints[:, 0], self.joints[:, 1]
        margin = JOINT_MARGIN * (hi - lo) + 0.5
        with np.errstate(invalid="ignore"):
            return np.any((q_deg < lo - margin) | (q_deg > hi + margin), axis=1)


@dataclass
class Compensator:
    """A loaded compensator. Create with :func:`load_model`; reuse it for every program."""

    path: Path
    session: object  # onnxruntime.InferenceSession
    metadata: dict = field(default_factory=dict)
    sha256: str = ""
    wants_previous: bool = False
    has_joints: bool = False  # the graph also outputs the IK's joint angles
    joints_output: str = OUTPUT_JOINTS  # that output's name (older models: LEGACY_OUTPUT_JOINTS)
    wants_joints: bool = False  # the graph takes the controller's ``joints`` (configuration)
    wants_tool: bool = False  # the graph takes the TCP on the flange (``tool``)
    has_rotation: bool = False  # the graph also outputs ``rotation_error``
    # tuning, per instance (tests make them small on their own model, nothing process-wide)
    predict_batch: int = PREDICT_BATCH  # rows per onnxruntime call of ``predict``
    command_chunk: int = COMMAND_CHUNK  # rows per chunk of ``command_chunks``

    @property
    def name(self) -> str:
        # it goes into the stamp line: one line of printable ASCII, whatever the model card says
        name = str(self.metadata.get("name") or self.path.stem)
        return "".join(c if " " <= c <= "~" else c.encode("unicode_escape").decode("ascii") for c in name)

    @property
    def robot(self) -> str:
        return str(self.metadata.get("robot", ""))

    @property
    def tool(self) -> dict:
        tool = self.metadata.get("tool")
        return tool if isinstance(tool, dict) else {}

    @property
    def envelope(self) -> Envelope | None:
        env = self.metadata.get("envelope")
        if not isinstance(env, dict):
            return None
        joints = np.asarray(env["joints"], float) if env.get("joints") is not None else None
        return Envelope(np.asarray(env["box"], float), np.asarray(env["attitude"], float), float(env["range"]), joints)

    @property
    def nominal_attitude(self) -> np.ndarray | None:
        env = self.envelope
        return None if env is None else env.attitude

    @property
    def default_iterations(self) -> int:
        try:
            return max(1, int(self.metadata.get("iterations", 2)))
        except (TypeError, ValueError):
            return 2

    def beyond_reach(self, positions: np.ndarray) -> np.ndarray:
        """Boolean mask of positions [N, 3] that no configuration of the robot reaches."""
        reach = self.metadata.get("reach")
        if not isinstance(reach, dict):
            return np.zeros(len(positions), bool)
        with np.errstate(over="ignore"):  # 1e200 mm is beyond reach, not worth a RuntimeWarning
            r = np.linalg.norm(positions - np.asarray(reach["center"], float), axis=1)
        return (r > float(reach["radius_max"])) | (r < float(reach.get("radius_min", 0.0)))

    def predict(self, poses: np.ndarray, previous: np.ndarray | None = None, joints=None,
                tool: np.ndarray | None = None, with_joints: bool = False, rotation: bool = False):
        """Ê for poses [N, 6] (robot base frame) → [N, 3] mm (float64). ``joints`` [N, 6] deg:
        the controller's joint angles at each pose (its configuration; NaN rows unknown), fed
        to a model with that input, ignored by others; ``tool`` [N, 6]: the TCP on the flange
        (likewise). With ``with_joints``: (Ê, the model's joint angles [N, 6] deg, or None for a
        model without that output); ``joints=True`` / ``False`` is read as ``with_joints`` (the
        older call). Batched: one onnxruntime call per ``predict_batch`` poses (a whole CAM program
        in one call would make the runtime hold every intermediate layer for every target).
        With ``rotation``: the rotation error [N, 3] deg is returned last."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        inputs = self._inputs(poses, previous, joints, tool)
        poses = inputs[INPUT_POSE]
        names = [OUTPUT_ERROR, self.joints_output] if with_joints and self.has_joints else [OUTPUT_ERROR]
        results = [np.empty((len(poses), 3)), np.empty((len(poses), 6))][:len(names)]
        if rotation:
            if not self.has_rotation:
                raise PostprocError(f"the model has no output '{OUTPUT_ROTATION}'", str(self.path), code=P306)
            names.append(OUTPUT_ROTATION)
            results.append(np.empty((len(poses), 3)))

        def run(at: int) -> None:
            batch = slice(at, at + self.predict_batch)
            feeds = {name: value[batch] for name, value in inputs.items()}
            try:
                outs = self.session.run(names, feeds)
            except Exception as exc:  # onnxruntime's own types: a graph that does not run on [N, 6]
                raise PostprocError(f"the model failed on {len(poses)} poses: {str(exc).splitlines()[0][:200]}",
                                    str(self.path), code=P306) from None
            for name, out, result in zip(names, outs, results):
                out = np.asarray(out)
                if out.shape != (len(feeds[INPUT_POSE]), result.shape[1]):
                    raise PostprocError(f"model returned shape {out.shape}, expected ({len(feeds[INPUT_POSE])}, "
                                        f"{result.shape[1]}) (output '{name}')", str(self.path), code=P306)
                result[batch] = out

        starts = range(0, len(poses), self.predict_batch)
        if len(starts) == 1:
            run(0)
        elif len(starts) > 1:
            # batches on every core: the session runs single-threaded (cheap start for small
            # programs) and releases the GIL, so one thread per core fills the machine
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(max_workers=min(os.cpu_count() or 1, 8)) as pool:
                list(pool.map(run, starts))
        out = [results[0]]
        if with_joints:
            out.append(results[1] if self.has_joints else None)
        if rotation:
            out.append(results[-1])
        return out[0] if len(out) == 1 else tuple(out)

    def _inputs(self, poses, previous, joints, tool) -> dict[str, np.ndarray]:
        """The model's inputs, float32 [N, 6] each: ``pose``; ``previous_pose`` (the pose itself
        where not given), ``joints`` and ``tool`` (NaN where not given) for a model that takes them."""
        poses = np.ascontiguousarray(poses, dtype=np.float32).reshape(-1, 6)
        inputs = {INPUT_POSE: poses}
        if self.wants_previous:
            inputs[INPUT_PREVIOUS] = (poses if previous is None
                                      else np.ascontiguousarray(previous, dtype=np.float32).reshape(-1, 6))
        for name, wanted, value in ((INPUT_JOINTS, self.wants_joints, joints), (INPUT_TOOL, self.wants_tool, tool)):
            if wanted:
                inputs[name] = (np.full(poses.shape, np.nan, np.float32) if value is None
                                else np.ascontiguousarray(np.broadcast_to(np.asarray(value, np.float32), poses.shape)))
        return inputs

    def command(self, poses: np.ndarray, iterations: int | None = None, joints=None, tool=None,
                with_joints: bool = False):
        """Commanded positions [N, 3] so that the robot lands on ``poses[:, :3]``: c = P + Ê(c).
        ``joints`` [N, 6] deg: the controller's joint angles at the *targets* (their
        configuration; every iteration's command is solved on that branch by the model, see
        the contract); ``tool`` [N, 6]: the TCP on the flange. With ``with_joints``: (commands,
        the targets' joint angles [N, 6] deg or None; see ``predict``). The rows are in program
        order: for a model with ``previous_pose`` each target comes from the previous row's
        command."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        poses = np.asarray(poses, dtype=float).reshape(-1, 6)
        out = np.empty((len(poses), 3))
        q = np.empty((len(poses), 6)) if with_joints and self.has_joints else None
        for start, commands, q_part in self.command_chunks(poses, iterations, joints, tool, with_joints):
            out[start:start + len(commands)] = commands
            if q is not None:
                q[start:start + len(commands)] = q_part
        return (out, q) if with_joints else out

    def command_chunks(self, poses: np.ndarray, iterations: int | None = None, joints=None, tool=None,
                       with_joints: bool = False,
                       orientation: bool = False) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
        """``command`` chunk by chunk (``command_chunk`` rows) in row order: yields (first row,
        commands [n, 3], the targets' joint angles [n, 6] deg if ``with_joints`` and the model
        has them, else None), the same numbers as one ``command`` call (each chunk takes its
        first row's previous pose, per iteration, from the chunk before), so a caller can use
        the first rows while the model runs on the next ones. ``joints`` / ``tool``: as
        ``command`` (``joints=True`` / ``False``: the older ``with_joints``). With ``orientation``
        the commands are full poses [n, 6]: the fixed point on the orientation too, R_c =
        exp(−r̂(c))·R_P with r̂ the model's ``rotation_error`` (the A,B,C triple nearest P's)."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        if orientation and not self.has_rotation:
            raise PostprocError(f"the model has no output '{OUTPUT_ROTATION}': it cannot correct orientation "
                                "(train it on data with a_meas,b_meas,c_meas)", str(self.path), code=P306)
        iterations = self.default_iterations if iterations is None else iterations
        if not 1 <= iterations <= MAX_ITERATIONS:
            raise PostprocError(f"--iterations must be between 1 and {MAX_ITERATIONS}", code=P308)
        poses = np.asarray(poses, dtype=float).reshape(-1, 6)
        rows = [None if v is None else np.broadcast_to(np.asarray(v, float), poses.shape) for v in (joints, tool)]
        return self._chunks(poses, iterations, with_joints, *rows, orientation)

    def _chunks(self, poses: np.ndarray, iterations: int, with_joints: bool, joints: np.ndarray | None,
                tool: np.ndarray | None, orientation: bool = False) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
        chunk = self.command_chunk
        # the last row of the chunk before, after each iteration k (k = 0: the target itself)
        before: list[np.ndarray] | None = None
        for start in range(0, len(poses), chunk):
            part = poses[start:start + chunk]
            given = {"joints": None if joints is None else joints[start:start + chunk],
                     "tool": None if tool is None else tool[start:start + chunk]}
            trial = part.copy()
            last = [trial[-1].copy()]
            q = None
            for k in range(iterations):
                prev = None
                if self.wants_previous:
                    # the pose commanded before each target is the previous target's *command*
                    # (the first target's is itself: nothing is known before it)
                    head = trial[:1] if before is None else before[k][None]
                    prev = np.vstack([head, trial[:-1]])
                rotation = None
                if k == 0 and with_joints:  # the first run is at the targets themselves: their joint angles
                    error, q, *rotation = self.predict(trial, prev, with_joints=True, rotation=orientation, **given)
                elif orientation:
                    error, *rotation = self.predict(trial, prev, rotation=True, **given)
                else:
                    error = self.predict(trial, prev, **given)
                trial[:, :3] = part[:, :3] + error
                if orientation:
                    trial[:, 3:6] = _corrected_attitude(part[:, 3:6], rotation[0])
                last.append(trial[-1].copy())
            before = last
            yield start, (trial if orientation else trial[:, :3]), q


def _corrected_attitude(abc: np.ndarray, rotation_error_deg: np.ndarray) -> np.ndarray:
    """A,B,C [N, 3] of exp(−r)·R(abc) (r: rotation vectors [N, 3] deg, nominal → actual in the
    base frame), on the triple and turns nearest ``abc``: the robot turned by r lands on abc."""
    from . import frames
    from .simulator import nearest_triple, small_transform

    undo = small_transform(np.radians(-np.asarray(rotation_error_deg, float)), np.zeros(3))[:, :3, :3]  # exp(−r)
    return nearest_triple(frames.abc_from_rotation(undo @ frames.rotation_from_abc(abc)), abc)


def _interface_problems(inputs: dict, outputs: dict, joints_output: str) -> list[str]:
    """What makes a session's inputs and outputs (name → node) not the contract's: names,
    shapes ([N, k] with a free batch size), float32."""
    problems = []
    if INPUT_POSE not in inputs:
        problems.append(f"no input '{INPUT_POSE}' (has {sorted(inputs)})")
    extra = set(inputs) - {INPUT_POSE, INPUT_PREVIOUS, INPUT_JOINTS, INPUT_TOOL}
    if extra:
        problems.append(f"unexpected inputs {sorted(extra)}")
    if OUTPUT_ERROR not in outputs:
        problems.append(f"no output '{OUTPUT_ERROR}' (has {sorted(outputs)})")
    for name, expected in ((INPUT_POSE, 6), (INPUT_PREVIOUS, 6), (INPUT_JOINTS, 6), (INPUT_TOOL, 6)):
        if name in inputs and (len(inputs[name].shape) != 2 or inputs[name].shape[1] not in (expected, None, "6")
                               or isinstance(inputs[name].shape[0], int)):
            problems.append(f"input '{name}' has shape {inputs[name].shape}, expected [N, {expected}]")
    if OUTPUT_ERROR in outputs and (len(outputs[OUTPUT_ERROR].shape) != 2 or outputs[OUTPUT_ERROR].shape[1] not in (3, None)):
        problems.append(f"output '{OUTPUT_ERROR}' has shape {outputs[OUTPUT_ERROR].shape}, expected [N, 3]")
    if joints_output in outputs and (len(outputs[joints_output].shape) != 2
                                     or outputs[joints_output].shape[1] not in (6, None)):
        problems.append(f"output '{joints_output}' has shape {outputs[joints_output].shape}, expected [N, 6]")
    if OUTPUT_ROTATION in outputs and (len(outputs[OUTPUT_ROTATION].shape) != 2
                                       or outputs[OUTPUT_ROTATION].shape[1] not in (3, None)):
        problems.append(f"output '{OUTPUT_ROTATION}' has shape {outputs[OUTPUT_ROTATION].shape}, expected [N, 3]")
    for node in (*inputs.values(), *outputs.values()):
        if node.name in (INPUT_POSE, INPUT_PREVIOUS, INPUT_JOINTS, INPUT_TOOL, OUTPUT_ERROR,
                         joints_output, OUTPUT_ROTATION) and node.type != "tensor(float)":
            problems.append(f"'{node.name}' is {node.type}, expected tensor(float) (float32)")
    return problems


def load_model(path: str | Path | None = None) -> Compensator:
    """Load and check an ONNX compensator (default: the shipped ``models/default.onnx``)."""
    path = Path(path) if path is not None else model_path()
    if not path.is_file():
        raise PostprocError("model not found", str(path), code=P307)
    try:
        import onnxruntime  # noqa: F401  (installed?)
    except ImportError as exc:  # pragma: no cover - install problem
        raise PostprocError(f"onnxruntime is not installed: {exc}") from exc
    data = path.read_bytes()
    from .session import inference_session

    try:
        session = inference_session(data)  # (the graph optimised once per model: session.py)
    except Exception as exc:  # onnxruntime raises its own exception types
        raise PostprocError(f"not an ONNX model: {str(exc).splitlines()[0][:200]}", str(path), code=P306) from exc
    inputs = {i.name: i for i in session.get_inputs()}
    outputs = {o.name: o for o in session.get_outputs()}
    joints_output = OUTPUT_JOINTS if OUTPUT_JOINTS in outputs or INPUT_JOINTS in inputs else LEGACY_OUTPUT_JOINTS
    problems = _interface_problems(inputs, outputs, joints_output)
    if problems:
        raise PostprocError("not a postproc compensator: " + "; ".join(problems), str(path), code=P306)
    meta = {k: _json_or_text(v) for k, v in session.get_modelmeta().custom_metadata_map.items()}
    problem = _metadata_problem(meta)
    if problem:
        raise PostprocError(f"model card (metadata_props) is malformed: {problem}", str(path), code=P306)
    return Compensator(
        path=path,
        session=session,
        metadata=meta,
        sha256=hashlib.sha256(data).hexdigest(),
        wants_previous=INPUT_PREVIOUS in inputs,
        has_joints=joints_output in outputs,
        joints_output=joints_output,
        wants_joints=INPUT_JOINTS in inputs,
        wants_tool=INPUT_TOOL in inputs,
        has_rotation=OUTPUT_ROTATION in outputs,
    )


def _numbers(value, n: int) -> bool:
    """``value`` is a list of ``n`` finite numbers."""
    try:
        return isinstance(value, list) and len(value) == n and bool(np.isfinite(np.asarray(value, float)).all())
    except (TypeError, ValueError):
        return False


def _metadata_problem(meta: dict) -> str | None:
    """What is wrong with the parts of a model card that ``compensate`` relies on, if anything."""
    env = meta.get("envelope")
    if env is not None:
        if not (isinstance(env, dict) and _numbers(env.get("box"), 6) and _numbers(env.get("attitude"), 3)
                and _numbers([env.get("range")], 1) and env["range"] >= 0):
            return "'envelope' needs box [x0,x1,y0,y1,z0,z1], attitude [A,B,C] and range ≥ 0"
        if any(lo > hi for lo, hi in zip(env["box"][0::2], env["box"][1::2])):
            return f"'envelope' box {env['box']} has a lower bound above its upper bound"
        joints = env.get("joints")
        if joints is not None and not (isinstance(joints, list) and len(joints) == 6
                                       and all(_numbers(r, 2) and r[0] <= r[1] for r in joints)):
            return "'envelope' joints must be six [lo, hi] ranges (deg)"
    reach = meta.get("reach")
    if reach is not None and not (isinstance(reach, dict) and _numbers(reach.get("center"), 3)
                                  and _numbers([reach.get("radius_max"), reach.get("radius_min", 0.0)], 2)
                                  and reach["radius_max"] > 0):
        return "'reach' needs center [x,y,z], radius_max > 0 and optionally radius_min"
    tool = meta.get("tool")
    if isinstance(tool, dict) and tool.get("frame") is not None and not _numbers(tool["frame"], 6):
        return "'tool' frame must be [X,Y,Z,A,B,C]"
    iterations = meta.get("iterations")
    if iterations is not None and not (isinstance(iterations, int) and 1 <= iterations <= MAX_ITERATIONS):
        return f"'iterations' must be a whole number from 1 to {MAX_ITERATIONS}, not {iterations!r}"
    return None


def contract_metadata(**fields) -> dict[str, str]:
    """metadata_props for a compensator: structured values JSON-encoded, contract stamped."""
    out = {"postproc_contract": CONTRACT_VERSION}
    for key, value in fields.items():
        if value is None:
            continue
        out[key] = value if isinstance(value, str) else json.dumps(value, default=float)
    return out
