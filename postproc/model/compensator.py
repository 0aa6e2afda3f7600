"""The compensator: one ONNX file that maps commanded TCP poses to positioning errors.

Contract (version 2), shared by ``train`` (which writes it) and ``compensate`` (which runs it),
and the interface of any other program that runs the file (onnxruntime alone: ``examples/``,
``docs/INTEGRATION.md``):

* every input but ``pose`` is optional in the ONNX sense: the graph carries a default for it
  (an initializer of the same name, float32 [1, 6] NaN, broadcast to ``pose``'s rows:
  ``contract.with_defaults``), so a caller that omits it gets its NaN meaning below, and an
  omitted ``previous_pose`` (or a row of it with a NaN) is the pose itself; contract-1 files
  (``postproc_contract`` "1") have the same inputs without defaults (``postproc model upgrade``
  adds them); ``Compensator`` feeds every input the graph takes either way;
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
* optional input ``tool``: float32 [N, 6] (X, Y, Z mm, A, B, C deg of the TCP on the flange:
  the program's $TOOL at each target), a row with a NaN = the model's own tool (the card's
  ``tool.frame``); for physical models that compute the error at any TCP: the graph solves the
  nominal IK of the flange pose that puts that TCP at ``pose`` (P·T⁻¹·T₀ for the
  description's IK) and evaluates the identified arm with that TCP on its identified flange
  (the identified tool offset a shift fixed to the flange, the mount's rotation where the data
  separated it). ``train``'s hybrid and kinematic models have it; pose-only models do not
  (P304 for another $TOOL);
* optional input ``approach``: float32 [N, 6], only beside ``previous_pose``: the approach
  sign each joint takes the target with (+1, −1; 0 = the middle of its lost motion) that the
  model assumes in place of the one it computes from ``previous_pose``; NaN = from
  ``previous_pose``. ``Compensator`` feeds NaN, except where it settles the approach (below);
* optional input ``previous_joints``: float32 [N, 6] deg (models with ``previous_pose`` and
  ``joints``), the controller's joint angles at the target before each one (the previous
  row's ``joints``; NaN rows unknown: the graph solves ``previous_pose`` on this target's
  branch): a change of configuration or turn between two targets (A4 from 179° to −179°
  turns 358°, not 2°) decides the approach direction, which the poses alone do not show.
  ``Compensator.command`` feeds the previous row's ``joints`` (the first row's: NaN);
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
  vector r of nominal → actual in the base frame (R_actual = exp(r)·R_pose; ``compensate
  --orientation``). ``train``'s hybrid/kinematic graphs have it only when the orientation was
  identified from measured orientations (``a_meas,b_meas,c_meas``; the card's
  ``identified.orientation.fitted``): a model without it cannot be used with ``--orientation``
  (P306), a model never outputs an orientation error that no data stood behind;
* optional output ``error_std``: float32 [N, 1] mm, how sure the model is at each target: the
  standard deviation of a coordinate of the residual a compensation leaves, E − Ê (root mean
  over X, Y, Z), = √(σ² + tr(J_t C J_tᵀ)/3) with C the identification's parameter covariance, σ
  its residual std per coordinate (at the training rows, evaluated as the graph evaluates them)
  and J_t the identified arm's sensitivity to its parameters at
  the target (at the graph's q, approach signs and tool; ``training/uncertainty.py``): small
  where the training data pinned the parameters down, large where it did not reach. ``train``'s
  hybrid/kinematic graphs have it (not a re-calibration's, not the networks alone); of the
  identified arm only (σ errs on the safe side where residual networks were kept). onnxruntime
  computes only the outputs asked for: ``compensate`` and ``check`` ask for it at the final
  commands (in the run the approach settling makes there: ``command_chunks(std=True)``), and
  only to hold the targets to ``--max-std`` (P336);
* ``metadata_props`` (values JSON-encoded where structured; JSON Schema
  ``postproc/schemas/model_card.schema.json``, ``model_card.py``): ``postproc_contract`` "2" (a
  newer version is refused naming it),
  ``name``, ``robot``, ``tool`` {"name", "frame", optional "measured": [[X,Y,Z,A,B,C], ...]
  the TCPs of the data, "unseparated": [[x,y,z], ...] unit directions (flange frame) of the
  mount rotation the data cannot tell from a shift (P319 where a TCP's lever arm makes them
  matter), "valid": the tools the model is valid for, in words}, ``envelope`` {"box": [x0,x1,y0,y1,z0,z1],
  "attitude": [A,B,C], "range": deg, optional "joints": [[lo, hi] × 6] deg: each joint's trained
  arc, from lo (in [−180, 180)) counterclockwise to hi (lo ≤ hi < lo + 360; hi may pass 180:
  an arc across ±180), see :func:`joint_arcs`}, ``reach`` {"center": [x,y,z], "radius_min",
  "radius_max"} (TCP distance from the shoulder), optional ``controller_base`` [X,Y,Z,A,B,C]
  (the frame the robot's controller takes a program's base-relative poses in, in the model's
  frame, where they differ: a UR description in ROS's base_link has 0,0,0,180,0,0; a program's
  targets — not a pose list's rows, which are in the model's frame — are taken through it:
  ``findings.model_bases``), ``data_sha256``, ``method``,
  ``structure``, ``accuracy`` {"val_mean_mm", "val_max_mm", ...}, ``iterations``; optional
  (hybrid/kinematic models) ``identified`` {"parameters": {group: [...]} (rad, mm, rad/Nm, as
  ``training.kinematic.Layout`` orders them), "ripple" [[joint, order]], "ripple_amplitudes"
  [[sin, cos]], "tau_mean" [27], "parameter_std" {group: [...]} (the spread of the estimate),
  "parameter_posterior_std" {group: [...]} (what is known of each value), "residual_std_mm",
  "nominal_sha256" (the robot description it is relative to: ``kinematic.nominal_digest``),
  "ik_family", "ik_branch", "residual_nets", ...}: what ``train --update`` re-fits from (the
  residual networks it reads back from the graph's initializers ``module.nets.K.*``); a model
  written by ``--update`` adds ``update`` {"from", "from_sha256", "rows", "groups",
  "moved_at_sigmas", "parameters": [{"group", "name", "unit", "old", "new", "change", "std",
  "moved"}]}; optional ``uncertainty`` {"max_std_mm" (the bound on ``error_std``
  compensate and check apply without ``--max-std``: uncertainty.MAX_STD_FACTOR × the
  identification's residual std), "residual_std_mm"} beside ``error_std``; optional ``transfer`` (benchmarks/cross_series.py: figures on other series);
  optional ``demonstration`` {"robot", "robot_seed"}: trained on data ``postproc measure``
  simulated, a demonstration model of a simulated robot (compensate and check say so, P340).

The command sent for target P is c = P + Ê(c), solved by fixed-point iteration from
c₀ = P (one iteration = the method's c = P + Ê(P)).

Settling the approach (models with ``approach`` and ``ik_joints``): where a joint barely moves
between two targets, the correction itself can reverse its motion, so the side of its lost
motion the model assumed is not the side the robot takes (and the iteration may flip between
the two). After the iterations, one more run at the commands checks each target: its command
must be the fixed point under the approach signs its own joint motion (from the previous
target's command) produces; a joint that does not move keeps the sign of its last motion
(as the robot's gear does: the simulator's rule). A target that is not is solved again under
each hypothesis of the approach signs of its joints that move least (at most SETTLE_JOINTS;
2^k sign sets and the middle of the lost motion), batched; the command whose joint motion
agrees with its hypothesis is kept (the smallest worst case over both sides if several do),
and if none agrees the one with the smallest worst case over both sides (the joint then sits
in its dead band: ``Settled.inside``, reported by compensate as P321). Targets after a changed
one are checked again, in program order across chunks.
"""
from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from ..core.diagnostics import P306, P307, P308, PostprocError
from ..core.resources import model_path

CONTRACT_VERSION = "2"
# the contract versions this postproc reads: 1 (every input a graph takes required), 2 (the
# optional inputs carry defaults: contract.py); a newer file is refused naming its version
CONTRACT_VERSIONS = ("1", "2")
INPUT_POSE = "pose"
INPUT_PREVIOUS = "previous_pose"
OUTPUT_ERROR = "error"
INPUT_JOINTS = "joints"
INPUT_TOOL = "tool"
INPUT_PREVIOUS_JOINTS = "previous_joints"
OUTPUT_JOINTS = "ik_joints"
LEGACY_OUTPUT_JOINTS = "joints"  # (the output's name before the ``joints`` input existed)
OUTPUT_ROTATION = "rotation_error"
OUTPUT_STD = "error_std"
INPUT_APPROACH = "approach"
# a command further than this from c = P + Ê(c) under its own joint motion is not settled (mm):
# the plain iteration leaves ~1e-6 mm where the approach signs hold still
SETTLE_TOLERANCE_MM = 1e-3
# joints whose approach sign is hypothesised per unsettled target (2^k + 1 candidates)
SETTLE_JOINTS = 3
# passes over the targets after a changed command (a run of neighbours that all barely move)
SETTLE_PASSES = 32
# a joint step below this (deg) is no motion: the model's own dead band (training.kinematic's
# SIGN_DEADBAND, 2e-6 rad) in the float32 degrees of ``ik_joints``
STILL_DEG = 1.2e-4
# ... and a step below this (deg) is the same command: float32 joint angles of one pose differ
# by ~1e-5° between rows of a batch (SIMD tails); a joint between the two has moved too little
# for the model to tell which way (both sides are taken into account)
SAME_DEG = 3e-5
# (2048 rows: the intermediates of the hybrid graph stay in cache: ~10 % less CPU than 8192 and
# the same numbers, each row's float32 result does not depend on the batch's length when it is
# a multiple of the SIMD width; benchmarks/compensate_speed.py)
PREDICT_BATCH = 2048
# Rows per chunk of ``command_chunks``: the unit compensate overlaps model runs and rewriting by,
# and a streamed program's chunk for a model that settles the approach. 16,384: a 1M-target CAM
# program streams in 215 MB (65,536: 420 MB, over issue 13's 300 MB) at the same speed; the
# settling's chunk borders move, which changed 2 of 200,000 coordinates by 0.001 mm (last digit)
COMMAND_CHUNK = 1 << 14
# A ``predict`` of at least this many rows that asks for fewer outputs than the graph has runs a
# session of the graph cut to them (session.py: onnxruntime runs every node whichever outputs
# are asked; the fixed-point iterations need no ``error_std``: 3.3 against 6.5 µs per row for
# the shipped model, the same numbers); smaller ones keep the start-up of one session
CUT_ROWS = 8192
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
        """Boolean mask of joint angles [N, 6] (deg, any turn) outside the trained arcs widened
        by :func:`widened_arcs` (the training poses sample the box, not its joint-space hull: a
        pose inside the box may turn a joint a little past what any training pose did)."""
        if self.joints is None:
            return np.zeros(len(q_deg), bool)
        arcs = widened_arcs(self.joints)
        with np.errstate(invalid="ignore"):
            return np.any(np.mod(np.asarray(q_deg, float) - arcs[:, 0], 360.0) > arcs[:, 1] - arcs[:, 0], axis=1)


def joint_arcs(q_deg: np.ndarray) -> np.ndarray:
    """[J, 2] deg: each joint's smallest arc holding all its angles q_deg [N, J] (any turn): from
    lo in [−180, 180) counterclockwise to hi = lo + width (past 180 where the arc crosses ±180:
    a range of −170…170 is two arcs' worth apart from one of 170…190). The complement of the
    largest gap between the sorted angles on the circle."""
    w = np.sort(np.mod(np.asarray(q_deg, float).reshape(len(q_deg), -1) + 180.0, 360.0) - 180.0, axis=0)
    gaps = np.vstack([np.diff(w, axis=0), w[:1] + 360.0 - w[-1:]])  # gap after each sorted angle
    k = np.argmax(gaps, axis=0)
    cols = np.arange(w.shape[1])
    lo = w[(k + 1) % len(w), cols]
    return np.c_[lo, lo + 360.0 - gaps[k, cols]]


def widened_arcs(arcs: np.ndarray) -> np.ndarray:
    """[J, 2] deg: the trained arcs [J, 2] widened on each side by JOINT_MARGIN of their width +
    0.5°: where compensate warns P301 and the models' learned parts stop holding (one rule)."""
    lo, hi = np.asarray(arcs, float).T
    margin = JOINT_MARGIN * (hi - lo) + 0.5
    return np.c_[lo - margin, np.minimum(hi + margin, lo - margin + 360.0)]


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
    wants_previous_joints: bool = False  # the graph takes the previous target's ``joints``
    has_rotation: bool = False  # the graph also outputs ``rotation_error``
    has_std: bool = False  # the graph also outputs ``error_std``
    wants_approach: bool = False  # the graph takes fixed approach signs (``approach``)
    settle: bool = True  # settle the commands on their approach where the model can (False: the plain fixed point)
    defaults: tuple = ()  # the inputs a caller may omit (their default initializers: contract 2, contract.py)

    @property
    def settles(self) -> bool:
        """Commands are settled on their approach signs (see the module text): the graph takes
        ``approach`` beside ``previous_pose`` and outputs the joint angles."""
        return self.settle and self.wants_approach and self.wants_previous and self.has_joints
    # tuning, per instance (tests make them small on their own model); the module's values are
    # the defaults, read when the instance is made (a test may also change them for the models
    # a call loads itself, e.g. the CLI's)
    predict_batch: int = field(default_factory=lambda: PREDICT_BATCH)  # rows per onnxruntime call of ``predict``
    command_chunk: int = field(default_factory=lambda: COMMAND_CHUNK)  # rows per chunk of ``command_chunks``
    cut_rows: int = field(default_factory=lambda: CUT_ROWS)  # a predict this large runs a cut graph
    data: bytes = field(default=b"", repr=False)  # the ONNX file's bytes as loaded (to cut the graph from)
    _cut: dict = field(default_factory=dict, repr=False)  # outputs → session of the graph cut to them

    @property
    def name(self) -> str:
        # it goes into the stamp line: one line of printable ASCII, whatever the model card says
        name = str(self.metadata.get("name") or self.path.stem)
        return "".join(c if " " <= c <= "~" else c.encode("unicode_escape").decode("ascii") for c in name)

    @property
    def robot(self) -> str:
        return str(self.metadata.get("robot", ""))

    @property
    def demonstration(self) -> str | None:
        """What the card's ``demonstration`` says the model is ("a demonstration model of a
        simulated KR500-sim": trained on data ``postproc measure`` simulated), None for a model
        of a real robot's data (no such key)."""
        demo = self.metadata.get("demonstration")
        if not isinstance(demo, dict):
            return None
        return f"a demonstration model of a simulated {demo.get('robot') or self.robot or 'robot'}"

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
    def controller_base(self) -> np.ndarray:
        """4×4: the controller's base frame (a program's poses) in the model's frame (the card's
        ``controller_base``; identity where the model's frame is the controller's)."""
        from ..core.frames import frame_to_matrix

        pose = self.metadata.get("controller_base")
        return np.eye(4) if pose is None else frame_to_matrix(np.asarray(pose, float))

    @property
    def in_controller_base(self) -> bool:
        """The model's frame is the controller's base (no ``controller_base``, or the identity)."""
        return bool(np.array_equal(self.controller_base, np.eye(4)))

    @property
    def nominal_attitude(self) -> np.ndarray | None:
        env = self.envelope
        return None if env is None else env.attitude

    @property
    def max_std_mm(self) -> float | None:
        """The card's bound on ``error_std`` (``uncertainty.max_std_mm``: what ``compensate`` and
        ``check`` hold the targets to without ``--max-std``), None for a model without one."""
        card = self.metadata.get("uncertainty")
        return float(card["max_std_mm"]) if self.has_std and isinstance(card, dict) and "max_std_mm" in card else None

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
                tool: np.ndarray | None = None, with_joints: bool = False, rotation: bool = False,
                approach: np.ndarray | None = None, previous_joints: np.ndarray | None = None, std: bool = False):
        """Ê for poses [N, 6] (robot base frame) → [N, 3] mm (float64). ``joints`` [N, 6] deg:
        the controller's joint angles at each pose (its configuration; NaN rows unknown), fed
        to a model with that input, ignored by others; ``tool`` [N, 6]: the TCP on the flange
        (likewise). With ``with_joints``: (Ê, the model's joint angles [N, 6] deg, or None for a
        model without that output); ``joints=True`` / ``False`` is read as ``with_joints`` (the
        older call). Batched: one onnxruntime call per ``predict_batch`` poses (a whole CAM program
        in one call would make the runtime hold every intermediate layer for every target).
        With ``rotation``: the rotation error [N, 3] deg is returned last. ``approach`` [N, 6]:
        approach signs to assume (NaN: from ``previous``), for a model with that input;
        ``previous_joints`` [N, 6] deg: the joint angles at the target before each pose (NaN
        rows unknown). With ``std`` (a model with ``error_std``): that [N] mm is returned last."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        inputs = self._inputs(poses, previous, joints, tool, approach, previous_joints)
        poses = inputs[INPUT_POSE]
        names = [OUTPUT_ERROR, self.joints_output] if with_joints and self.has_joints else [OUTPUT_ERROR]
        results = [np.empty((len(poses), 3)), np.empty((len(poses), 6))][:len(names)]
        if rotation:
            if not self.has_rotation:
                raise PostprocError(f"the model has no output '{OUTPUT_ROTATION}'", str(self.path), code=P306)
            names.append(OUTPUT_ROTATION)
            results.append(np.empty((len(poses), 3)))
        if std:
            if not self.has_std:
                raise PostprocError(f"the model has no output '{OUTPUT_STD}'", str(self.path), code=P306)
            names.append(OUTPUT_STD)
            results.append(np.empty((len(poses), 1)))

        session = self._session_for(names, len(poses))

        def run(at: int) -> None:
            batch = slice(at, at + self.predict_batch)
            feeds = {name: value[batch] for name, value in inputs.items()}
            try:
                outs = session.run(names, feeds)
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
            out.append(results[-2] if std else results[-1])
        if std:
            out.append(results[-1][:, 0])
        return out[0] if len(out) == 1 else tuple(out)

    def _session_for(self, names: list[str], rows: int):
        """The session to run ``names`` on ``rows`` rows: the whole graph's, or for a large run
        that asks for fewer outputs than it has, one of the graph cut to them (made once per
        output set from the bytes loaded; the whole graph's where it cannot be cut)."""
        if rows < self.cut_rows or not self.data or len(names) >= len(self.session.get_outputs()):
            return self.session
        key = tuple(names)
        if key not in self._cut:
            from .session import inference_session

            try:
                cut = inference_session(self.data, key)
            except Exception:  # noqa: BLE001 - speed only: the whole graph gives the same numbers
                cut = None
            self._cut[key] = cut if cut is not None else self.session
        return self._cut[key]

    def _inputs(self, poses, previous, joints, tool, approach=None, previous_joints=None) -> dict[str, np.ndarray]:
        """The model's inputs, float32 [N, 6] each: ``pose``; ``previous_pose`` (the pose itself
        where not given), ``joints``, ``tool``, ``approach`` and ``previous_joints`` (NaN where
        not given) for a model that takes them."""
        poses = np.ascontiguousarray(poses, dtype=np.float32).reshape(-1, 6)
        inputs = {INPUT_POSE: poses}
        if self.wants_previous:
            inputs[INPUT_PREVIOUS] = (poses if previous is None
                                      else np.ascontiguousarray(previous, dtype=np.float32).reshape(-1, 6))
        for name, wanted, value in ((INPUT_JOINTS, self.wants_joints, joints), (INPUT_TOOL, self.wants_tool, tool),
                                    (INPUT_APPROACH, self.wants_approach, approach),
                                    (INPUT_PREVIOUS_JOINTS, self.wants_previous_joints, previous_joints)):
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
                       with_joints: bool = False, orientation: bool = False,
                       chain: "Chain | None" = None, std: bool = False,
                       order: "Order | None" = None) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
        """``command`` chunk by chunk (``command_chunk`` rows) in row order: yields (first row,
        commands [n, 3], the targets' joint angles [n, 6] deg if ``with_joints`` and the model
        has them, else None), the same numbers as one ``command`` call (each chunk takes its
        first row's previous pose, per iteration, from the chunk before), so a caller can use
        the first rows while the model runs on the next ones. ``joints`` / ``tool``: as
        ``command`` (``joints=True`` / ``False``: the older ``with_joints``). With ``orientation``
        the commands are full poses [n, 6]: the fixed point on the orientation too, R_c =
        exp(−r̂(c))·R_P with r̂ the model's ``rotation_error`` (the A,B,C triple nearest P's).
        ``chain``: fed incrementally, a call for the rows after those of an earlier call with the
        same ``chain`` continues that call (previous pose, approach settling) as one call would.
        With ``std`` (a model with ``error_std``): each chunk's ``std`` [n] mm is the model's
        ``error_std`` at its commands (see :meth:`command_std`), taken from the run the approach
        settling makes at the commands anyway (a model that settles), else one more run.
        ``order``: the rows' predecessors in execution order (:class:`Order`; None: each row's is
        the row before): a program's targets after a branch, in a loop, or after a motion whose
        target is no row come from another command than the row before's (one chunk of all rows)."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        if std and not self.has_std:
            raise PostprocError(f"the model has no output '{OUTPUT_STD}'", str(self.path), code=P306)
        if orientation and not self.has_rotation:
            raise PostprocError(f"the model has no output '{OUTPUT_ROTATION}': it cannot correct orientation "
                                "(train it on data with a_meas,b_meas,c_meas)", str(self.path), code=P306)
        iterations = self.default_iterations if iterations is None else iterations
        if not 1 <= iterations <= MAX_ITERATIONS:
            raise PostprocError(f"--iterations must be between 1 and {MAX_ITERATIONS}", code=P308)
        poses = np.asarray(poses, dtype=float).reshape(-1, 6)
        rows = [None if v is None else np.broadcast_to(np.asarray(v, float), poses.shape) for v in (joints, tool)]
        if order is not None and not order.sequential:
            return self._ordered(poses, iterations, with_joints, *rows, orientation, std, order)
        return self._chunks(poses, iterations, with_joints, *rows, orientation, chain, std)

    def command_std(self, commands: np.ndarray, before: np.ndarray | None = None, joints=None, tool=None,
                    previous_joints=None, order: "Order | None" = None) -> np.ndarray:
        """The model's ``error_std`` [N] mm at commands [N, 6] (program order), each reached from
        the command before it (``previous_pose``; the first row's: ``before`` [6], the command
        of the target before them, None: the row itself), its approach as the graph computes it
        (``approach`` NaN). ``joints``, ``tool``, ``previous_joints``: as ``predict``."""
        commands = np.asarray(commands, float).reshape(-1, 6)
        previous = None
        if self.wants_previous and order is not None and not order.sequential:
            previous = order.previous(commands)
        elif self.wants_previous:
            head = commands[:1] if before is None else np.asarray(before, float).reshape(1, 6)
            previous = np.vstack([head, commands[:-1]])
        return self.predict(commands, previous, joints=joints, tool=tool, previous_joints=previous_joints, std=True)[1]

    def _ordered(self, poses: np.ndarray, iterations: int, with_joints: bool, joints: np.ndarray | None,
                 tool: np.ndarray | None, orientation: bool, std: bool, order: Order):
        """``command_chunks`` for rows in an :class:`Order` that is not row after row: one chunk,
        each row's previous command its predecessor's (the same fixed-point iteration)."""
        settle = _Settle(self, iterations, orientation, std, order) if self.settles else None
        given = {"joints": joints, "tool": tool}
        if self.wants_previous_joints and joints is not None:
            given["previous_joints"] = order.take(np.asarray(joints, float))
        trial = poses.copy()
        q = None
        for k in range(iterations):
            prev = order.previous(trial) if self.wants_previous else None
            rotation = None
            if k == 0 and (with_joints or settle):
                error, q, *rotation = self.predict(trial, prev, with_joints=True, rotation=orientation, **given)
            elif orientation:
                error, *rotation = self.predict(trial, prev, rotation=True, **given)
            else:
                error = self.predict(trial, prev, **given)
            trial[:, :3] = poses[:, :3] + error
            if orientation:
                trial[:, 3:6] = _corrected_attitude(poses[:, 3:6], rotation[0])
        inside = stds = None
        if settle is not None:
            inside, stds = settle.chunk(0, poses, trial, q, given)
        elif std:
            stds = self.command_std(trial, None, order=order, **given)
        yield CommandChunk(0, (trial if orientation else trial[:, :3]), q if with_joints else None, inside=inside,
                           std=stds)

    def _chunks(self, poses: np.ndarray, iterations: int, with_joints: bool, joints: np.ndarray | None,
                tool: np.ndarray | None, orientation: bool = False,
                chain: "Chain | None" = None, std: bool = False) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
        chunk = self.command_chunk
        chain = Chain() if chain is None else chain
        settle = _Settle(self, iterations, orientation, std) if self.settles else None
        if settle is not None:
            settle.head = chain.settled
        for start in range(0, len(poses), chunk):
            part = poses[start:start + chunk]
            given = {"joints": None if joints is None else joints[start:start + chunk],
                     "tool": None if tool is None else tool[start:start + chunk]}
            if self.wants_previous_joints and joints is not None:
                # the controller's angles at the target before each one (the first's: unknown)
                head = np.full((1, 6), np.nan) if start == 0 else joints[start - 1:start]
                given["previous_joints"] = np.vstack([head, given["joints"][:-1]])
            trial = part.copy()
            last = [trial[-1].copy()]
            q = None
            for k in range(iterations):
                prev = None
                if self.wants_previous:
                    # the pose commanded before each target is the previous target's *command*
                    # (the first target's is itself: nothing is known before it)
                    head = trial[:1] if chain.before is None else chain.before[k][None]
                    prev = np.vstack([head, trial[:-1]])
                rotation = None
                if k == 0 and (with_joints or settle):  # the first run is at the targets themselves: their joint angles
                    error, q, *rotation = self.predict(trial, prev, with_joints=True, rotation=orientation, **given)
                elif orientation:
                    error, *rotation = self.predict(trial, prev, rotation=True, **given)
                else:
                    error = self.predict(trial, prev, **given)
                trial[:, :3] = part[:, :3] + error
                if orientation:
                    trial[:, 3:6] = _corrected_attitude(part[:, 3:6], rotation[0])
                last.append(trial[-1].copy())
            before = None if chain.before is None else chain.before[-1]  # (the command before the chunk)
            chain.before = last
            inside = stds = None
            if settle is not None:
                inside, stds = settle.chunk(start, part, trial, q, given)
                chain.settled = settle.head
            elif std:
                stds = self.command_std(trial, before, **given)
            yield CommandChunk(start, (trial if orientation else trial[:, :3]), q if with_joints else None,
                               inside=inside, std=stds)


@dataclass
class Chain:
    """What a program's commands carry from one target to the next, for a program fed a part at
    a time (streaming compensate): the last row of the part before after each fixed-point
    iteration (``previous_pose``; None: the program's first target comes next), the approach
    settling's last command, joint angles and sides (``_Settle.head``), and the controller's
    joint angles at the last target (``controller.controller_inputs``: the configuration chain,
    LIN keeps / PTP nearest)."""

    before: list | None = None
    settled: tuple | None = None
    joints: np.ndarray | None = None
    branch: int | None = None  # (the controller's branch at the last target)
    origin: np.ndarray | None = None  # (the controller's start position, the program's first part's)


@dataclass
class Order:
    """Which row each row is reached from (its *predecessor* in execution order): ``prev`` [n]
    the row's index (-1: nothing known before it: its own pose, as a program's first target;
    -2: a pose given in ``fixed`` [n, 6], a target left as written before it). Rows come after
    their predecessors (``prev[i] < i``). None / ``sequential``: each row's is the row before."""

    prev: np.ndarray
    fixed: np.ndarray | None = None

    @property
    def sequential(self) -> bool:
        n = len(self.prev)
        return n == 0 or (self.prev[0] in (-1, -2) and (self.fixed is None or self.prev[0] == -1)
                          and bool((self.prev[1:] == np.arange(n - 1)).all()))

    def previous(self, values: np.ndarray) -> np.ndarray:
        """Each row's predecessor's row of ``values`` [n, k] (the row itself where none is known;
        the fixed pose's first k columns where one is given)."""
        prev = self.prev
        out = values[np.maximum(prev, 0)].copy()
        own = prev == -1
        out[own] = values[own]
        given = prev == -2
        if given.any():
            out[given] = self.fixed[given, :values.shape[1]] if self.fixed is not None else values[given]
        return out

    def take(self, values: np.ndarray, missing=np.nan) -> np.ndarray:
        """``values`` [n, k] of each row's predecessor, ``missing`` where it is not a row."""
        out = values[np.maximum(self.prev, 0)].copy()
        out[self.prev < 0] = missing
        return out

    def along(self, raw: np.ndarray, seed: np.ndarray | None = None) -> np.ndarray:
        """[n, k]: per column the last value ≠ 0 (NaN counts) along each row's chain of
        predecessors, itself first (``seed`` [k] before the first row of the chain; NaN)."""
        n, k = raw.shape
        out = np.full((n, k), np.nan)
        prev = self.prev
        starts = np.flatnonzero(np.r_[True, prev[1:] != np.arange(n - 1)])
        ends = np.r_[starts[1:], n]
        for a, b in zip(starts.tolist(), ends.tolist()):
            p = int(prev[a])
            head = out[p] if p >= 0 else (np.full(k, np.nan) if seed is None else seed)
            part = raw[a:b]
            idx = np.where(part != 0, np.arange(b - a)[:, None], -1)
            last = np.maximum.accumulate(idx, axis=0)
            out[a:b] = np.where(last >= 0, np.take_along_axis(part, np.maximum(last, 0), axis=0), head)
        return out


@dataclass
class Inside:
    """Targets whose command no approach hypothesis makes self-consistent: a joint barely
    moving there sits in its backlash dead band whatever is sent. ``rows`` [k] (program rows),
    ``joints`` [k, 6] bool (the joints in their dead band), ``worst_mm`` [k] (the smallest
    worst-case error over both sides of those joints, the command sent), ``error_mm`` [k] (the
    model's error with the side the command's own motion takes)."""

    rows: np.ndarray
    joints: np.ndarray
    worst_mm: np.ndarray
    error_mm: np.ndarray

    @staticmethod
    def join(parts: list["Inside | None"]) -> "Inside":
        parts = [p for p in parts if p is not None]
        if not parts:
            return Inside(np.zeros(0, int), np.zeros((0, 6), bool), np.zeros(0), np.zeros(0))
        return Inside(*(np.concatenate([getattr(p, f) for p in parts]) for f in ("rows", "joints", "worst_mm", "error_mm")))


class CommandChunk(tuple):
    """(first row, commands, joint angles or None), as ``command_chunks`` yields it; ``inside``:
    the chunk's :class:`Inside` targets (None for models that do not settle the approach);
    ``std``: the model's ``error_std`` [n] mm at the commands (None unless asked for)."""

    inside: Inside | None
    std: np.ndarray | None

    def __new__(cls, start: int, commands: np.ndarray, q: np.ndarray | None, inside: Inside | None = None,
                std: np.ndarray | None = None):
        self = super().__new__(cls, (start, commands, q))
        self.inside, self.std = inside, std
        return self


def _wrap_deg(a: np.ndarray) -> np.ndarray:
    return (a + 180.0) % 360.0 - 180.0


class _Settle:
    """The approach settling of ``command_chunks`` (module text), chunk after chunk in program
    order: keeps the last target's command, joint angles and approach signs for the next."""

    def __init__(self, model: "Compensator", iterations: int, orientation: bool, std: bool = False,
                 order: Order | None = None):
        self.model, self.iterations, self.orientation, self.std = model, iterations, orientation, std
        self.head: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # (command [6], q [6], signs [6])
        self.order = order  # (one chunk of rows in this execution order: ``Compensator._ordered``)

    # -- the joint motion of a chunk's commands: signs, and what the model must be told
    def _prev_q_signs(self, q: np.ndarray, signs: np.ndarray | None = None):
        """Joint angles [n, 6] and sides [n, 6] of each row's previous command (row 0: the chunk
        before's; the program's first target: itself, unknown side)."""
        if self.order is not None:
            o = self.order
            q_prev = o.take(q)
            own = o.prev == -1
            q_prev[own] = q[own]
            return q_prev, (None if signs is None else o.take(signs))
        if self.head is None:
            return np.vstack([q[:1], q[:-1]]), (None if signs is None else np.vstack([np.full((1, 6), np.nan), signs[:-1]]))
        return (np.vstack([self.head[1][None], q[:-1]]),
                None if signs is None else np.vstack([self.head[2][None], signs[:-1]]))

    def _motion(self, q: np.ndarray):
        """(step [n, 6] deg from the previous command, sides [n, 6] (the side each joint is on:
        its last motion's, NaN where unknown), keep [n, 6] (the ``approach`` of a joint that does
        not move: it keeps its side; NaN where it moves), unsure [n, 6] (a motion too small for
        the model's float32 joint angles to tell its direction))."""
        n = len(q)
        q_prev, _ = self._prev_q_signs(q)
        s_head = np.full(6, np.nan) if self.head is None else self.head[2]
        step = _wrap_deg(q - q_prev)
        raw = np.where(np.abs(step) <= SAME_DEG, 0.0, np.where(np.abs(step) > STILL_DEG, np.sign(step), np.nan))
        unsure = np.isnan(raw)
        if self.order is not None:
            first = self.order.prev < 0  # (from where nothing is known: the model's own rule)
            raw[first], unsure[first] = np.nan, False
            signs = self.order.along(raw)
            keep = np.where(raw == 0, signs, np.nan)
            return step, signs, keep, unsure
        if self.head is None:
            raw[0], unsure[0] = np.nan, False  # (from HOME: the model's own rule)
        idx = np.where(raw != 0, np.arange(n)[:, None], -1)
        last = np.maximum.accumulate(idx, axis=0)
        signs = np.where(last >= 0, np.take_along_axis(raw, np.maximum(last, 0), axis=0), s_head)
        keep = np.where(raw == 0, signs, np.nan)
        return step, signs, keep, unsure

    def _run(self, c: np.ndarray, prev: np.ndarray | None, approach: np.ndarray, given: dict, with_joints: bool,
             std: bool = False):
        """Ê [m, 3] (and q [m, 6]; the rotation error with ``orientation``; ``error_std`` [m] with
        ``std``) at commands ``c``; ``prev`` None: each row comes from itself (the program's first
        target)."""
        prev = c if prev is None else prev
        out = self.model.predict(c, prev, with_joints=with_joints, rotation=self.orientation,
                                 approach=approach, std=std, **given)
        return out if isinstance(out, tuple) else (out,)

    def _landing(self, c, prev, approach, given, q_prev, side_prev):
        """(Ê, q, rotation or None, unsure [m, 6]) at commands ``c`` with the sides their own
        motion takes (``approach`` where not NaN): a joint that does not move from ``q_prev``
        keeps ``side_prev``."""
        out = self._run(c, prev, approach, given, True)
        e, q, rot = out[0], out[1], (out[2] if self.orientation else None)
        step = _wrap_deg(q - q_prev)
        still = (np.abs(step) <= SAME_DEG) & np.isnan(approach) & ~np.isnan(side_prev)
        rows = np.flatnonzero(still.any(axis=1))
        if len(rows):
            again = self._run(c[rows], prev[rows], np.where(still[rows], side_prev[rows], approach[rows]),
                              _rows(given, rows), False)
            e[rows] = again[0]
            if self.orientation:
                rot[rows] = again[1]
        unsure = (np.abs(step) > SAME_DEG) & (np.abs(step) <= STILL_DEG)
        return e, q, rot, unsure

    def chunk(self, start: int, part: np.ndarray, trial: np.ndarray, q_target: np.ndarray,
              given: dict) -> tuple[Inside, np.ndarray | None]:
        """Settle ``trial`` (the chunk's commands [n, 6], changed in place) on the approach.
        Returns the chunk's Inside targets and, with ``std``, the ``error_std`` [n] at the settled
        commands (``Compensator.command_std``'s numbers: each pass's run at the commands, with
        the approach the graph computes, asks for it too; rows whose command or previous command
        changed after their last such run are run again)."""
        n = len(part)
        q = np.full((n, 6), np.nan)
        inside = np.zeros(n, bool)
        dead = np.zeros((n, 6), bool)
        worst = np.zeros(n)
        error = np.zeros(n)
        check = np.arange(n)
        keep = np.full((n, 6), np.nan)
        std = np.full(n, np.nan) if self.std else None
        std_at = np.full((n, 12), np.nan)  # the command and previous command each ``std`` row is of
        for _ in range(SETTLE_PASSES):
            if not len(check):
                break
            # each command's error with the sides its own joint motion gives
            prev_rows = self._previous(trial, check)
            if self.order is not None:
                first = self.order.prev[check] < 0
            else:
                first = check == 0 if self.head is None else np.zeros(len(check), bool)
            out = self._run(trial[check], prev_rows, np.full((len(check), 6), np.nan), _rows(given, check), True,
                            self.std)
            if self.std:
                std[check], std_at[check] = out[-1], np.c_[trial[check], prev_rows]
            q[check] = out[1]
            step, signs, keep, unsure = self._motion(q)
            e, rot = out[0], (out[2] if self.orientation else None)
            still = ~np.isnan(keep[check]).all(axis=1)
            if still.any():  # a joint that does not move keeps its side (the model alone: the middle)
                again = self._run(trial[check[still]], prev_rows[still], keep[check[still]],
                                  _rows(given, check[still]), False)
                e[still] = again[0]
                if self.orientation:
                    rot[still] = again[1]
            off = np.linalg.norm(part[check, :3] + e - trial[check, :3], axis=1) > SETTLE_TOLERANCE_MM
            if self.orientation:
                off |= np.abs(_wrap_deg(_corrected_attitude(part[check, 3:6], rot) - trial[check, 3:6])).max(axis=1) > 1e-6
            off |= unsure[check].any(axis=1)
            off &= ~first  # (the first target comes from HOME, far away: no doubt)
            inside[check] = False
            bad = check[off]
            if not len(bad):
                break
            old = trial[bad].copy()
            q_prev, side_prev = self._prev_q_signs(q, signs)
            none, joints, w, err = self._hypotheses(bad, part, trial, q, q_target, step, q_prev[bad], side_prev[bad],
                                                    prev_rows[off], given)
            inside[bad[none]], dead[bad[none]], worst[bad[none]], error[bad[none]] = True, joints[none], w[none], err[none]
            # the next pass: the targets after a changed command, and where a still joint's side changed
            changed = bad[np.abs(trial[bad] - old).max(axis=1) > 0]
            keep_after = self._motion(q)[2]
            again = np.zeros(n, bool)
            if self.order is not None:
                again[np.isin(self.order.prev, changed)] = True
            else:
                after = changed + 1
                again[after[after < n]] = True
            again |= ~((keep_after == keep) | (np.isnan(keep_after) & np.isnan(keep))).all(axis=1)
            check = np.flatnonzero(again)
        if self.std:
            every = np.arange(n)
            stale = np.flatnonzero((std_at != np.c_[trial, self._previous(trial, every)]).any(axis=1))
            if len(stale):
                prev_rows = self._previous(trial, stale)
                std[stale] = self._run(trial[stale], prev_rows, np.full((len(stale), 6), np.nan), _rows(given, stale),
                                       False, True)[-1]
        signs = self._motion(q)[1]
        self.head = (trial[-1].copy(), q[-1].copy(), signs[-1].copy())
        rows = np.flatnonzero(inside)
        return Inside(start + rows, dead[rows], worst[rows], error[rows]), std

    def _previous(self, trial: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """The command before each of ``rows`` [k, 6] (the chunk before's last; the program's
        first target's: itself)."""
        if self.order is not None:
            return self.order.previous(trial)[rows]
        before = rows - 1
        out = trial[np.maximum(before, 0)]
        if self.head is not None:
            out[before < 0] = self.head[0]
        return out

    def _hypotheses(self, bad, part, trial, q, q_target, step, q_prev, side_prev, prev_rows, given):
        """Solve targets ``bad`` again under each approach hypothesis of their SETTLE_JOINTS
        joints that move least (against what the correction turns them by); write the chosen
        commands and their joint angles into ``trial`` / ``q``. Returns per row: no hypothesis
        agrees [b], the joints in doubt [b, 6], the chosen command's worst case over both sides
        of them [b] mm and its error with the side its own motion takes [b] mm."""
        m = SETTLE_JOINTS
        turn = np.abs(_wrap_deg(q[bad] - q_target[bad])) + 1e-4
        slots = np.argsort(np.abs(step[bad]) / turn, axis=1, kind="stable")[:, :m]  # [b, m]
        combos = np.array(np.meshgrid(*[[-1.0, 1.0]] * m, indexing="ij")).reshape(m, -1).T  # [2^m, m]
        # + the middle of the lost motion, + every joint on the side it is on (no joint moves:
        # a target written twice), started from the previous command
        hyps = np.vstack([combos, np.zeros((1, m)), np.full((1, m), np.nan)])
        b, h, s = len(bad), len(hyps), len(combos)
        rep = np.repeat(np.arange(b), h)
        fixed = np.full((b * h, 6), np.nan)
        np.put_along_axis(fixed, slots[rep], np.tile(hyps, (b, 1)), axis=1)
        target, prev, sub = part[bad][rep], prev_rows[rep], _rows(given, bad[rep])
        qp, sp = q_prev[rep], side_prev[rep]
        cand, q_c = trial[bad][rep].copy(), q[bad][rep]
        stay = np.arange(b) * h + h - 1
        fixed[stay] = side_prev
        cand[stay], q_c[stay] = prev_rows, q_prev
        for _ in range(self.iterations + 1):  # the fixed point under each hypothesis
            # (a joint that barely moves is held on its side: a target written twice ends on its twin)
            still = np.isnan(fixed) & (np.abs(_wrap_deg(q_c - qp)) <= STILL_DEG) & ~np.isnan(sp)
            out = self._run(cand, prev, np.where(still, sp, fixed), sub, True)
            q_c = out[1]
            cand[:, :3] = target[:, :3] + out[0]
            if self.orientation:
                cand[:, 3:6] = _corrected_attitude(target[:, 3:6], out[2])
        # (no joint moves: exactly the previous command, the float32 model leaves ~1e-4 mm)
        twin = stay[np.abs(cand[stay] - prev[stay]).max(axis=1) <= SETTLE_TOLERANCE_MM]
        cand[twin] = prev[twin]
        # where each candidate lands with the sides its own motion takes
        real, q_cand, _, unsure = self._landing(cand, prev, np.full((b * h, 6), np.nan), sub, qp, sp)
        error = np.linalg.norm(target[:, :3] - cand[:, :3] + real, axis=1).reshape(b, h)
        moved = _wrap_deg(q_cand - qp)
        side = np.where(np.abs(moved) <= SAME_DEG, np.nan_to_num(sp), np.sign(moved))
        side = np.take_along_axis(side, slots[rep], axis=1).reshape(b, h, m)
        unsure_slot = np.take_along_axis(unsure, slots[rep], axis=1).reshape(b, h, m)
        # a joint is in doubt where the candidates take it to either side or too little to tell
        doubt = (side.max(axis=1) != side.min(axis=1)) | unsure_slot.any(axis=1)  # [b, m]
        agrees = (error <= SETTLE_TOLERANCE_MM) & ~unsure.any(axis=1).reshape(b, h)
        settled = agrees.any(axis=1)
        # where one agrees: the one nearest the plain fixed point's command
        near = np.linalg.norm(cand[:, :3] - trial[bad][rep][:, :3], axis=1).reshape(b, h)
        pick = np.argmin(np.where(agrees, near, np.inf), axis=1)
        worst = np.where(agrees, error, np.inf)
        # where none does: each candidate's worst case over both sides of the joints in doubt
        lost = np.flatnonzero(~settled)
        if len(lost):
            at = (lost[:, None] * h + np.arange(h)).ravel()  # their candidates
            rep2 = np.repeat(at, s)
            sides = np.where(doubt[lost][:, None, None, :], combos[None, None], side[lost][:, :, None, :]).reshape(-1, m)
            approach = np.full((len(rep2), 6), np.nan)
            np.put_along_axis(approach, slots[rep][rep2], sides, axis=1)
            out = self._landing(cand[rep2], prev[rep2], approach, _rows(sub, rep2), qp[rep2], sp[rep2])
            w = np.linalg.norm(target[rep2, :3] - cand[rep2, :3] + out[0], axis=1).reshape(len(lost), h, s).max(axis=2)
            worst[lost] = np.maximum(w, error[lost])
            pick[lost] = np.argmin(worst[lost], axis=1)
        chosen = np.arange(b) * h + pick
        trial[bad] = cand[chosen]
        q[bad] = q_cand[chosen]
        joints = np.zeros((b, 6), bool)
        np.put_along_axis(joints, slots, doubt, axis=1)
        return ~agrees.any(axis=1), joints, worst[np.arange(b), pick], error[np.arange(b), pick]


def _rows(given: dict, rows: np.ndarray) -> dict:
    return {k: None if v is None else v[rows] for k, v in given.items()}


def _corrected_attitude(abc: np.ndarray, rotation_error_deg: np.ndarray) -> np.ndarray:
    """A,B,C [N, 3] of exp(−r)·R(abc) (r: rotation vectors [N, 3] deg, nominal → actual in the
    base frame), on the triple and turns nearest ``abc``: the robot turned by r lands on abc."""
    from ..core import frames
    from ..core.frames import nearest_triple, small_transform

    undo = small_transform(np.radians(-np.asarray(rotation_error_deg, float)), np.zeros(3))[:, :3, :3]  # exp(−r)
    return nearest_triple(frames.abc_from_rotation(undo @ frames.rotation_from_abc(abc)), abc)


def _interface_problems(inputs: dict, outputs: dict, joints_output: str) -> list[str]:
    """What makes a session's inputs and outputs (name → node) not the contract's: names,
    shapes ([N, k] with a free batch size), float32."""
    problems = []
    if INPUT_POSE not in inputs:
        problems.append(f"no input '{INPUT_POSE}' (has {sorted(inputs)})")
    extra = set(inputs) - {INPUT_POSE, INPUT_PREVIOUS, INPUT_JOINTS, INPUT_TOOL, INPUT_APPROACH, INPUT_PREVIOUS_JOINTS}
    if extra:
        problems.append(f"unexpected inputs {sorted(extra)}")
    if OUTPUT_ERROR not in outputs:
        problems.append(f"no output '{OUTPUT_ERROR}' (has {sorted(outputs)})")
    if INPUT_APPROACH in inputs and INPUT_PREVIOUS not in inputs:
        problems.append(f"input '{INPUT_APPROACH}' without '{INPUT_PREVIOUS}'")
    for name, expected in ((INPUT_POSE, 6), (INPUT_PREVIOUS, 6), (INPUT_JOINTS, 6), (INPUT_TOOL, 6),
                           (INPUT_APPROACH, 6), (INPUT_PREVIOUS_JOINTS, 6)):
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
    if OUTPUT_STD in outputs and (len(outputs[OUTPUT_STD].shape) != 2 or outputs[OUTPUT_STD].shape[1] not in (1, None)):
        problems.append(f"output '{OUTPUT_STD}' has shape {outputs[OUTPUT_STD].shape}, expected [N, 1]")
    for node in (*inputs.values(), *outputs.values()):
        if node.name in (INPUT_POSE, INPUT_PREVIOUS, INPUT_JOINTS, INPUT_TOOL, INPUT_APPROACH, INPUT_PREVIOUS_JOINTS,
                         OUTPUT_ERROR, joints_output, OUTPUT_ROTATION, OUTPUT_STD) and node.type != "tensor(float)":
            problems.append(f"'{node.name}' is {node.type}, expected tensor(float) (float32)")
    return problems


def load_model(path: str | Path | None = None) -> Compensator:
    """Load and check an ONNX compensator (default: the shipped ``models/default.onnx``; a bare
    name that is no file, ``irb6700``, a shipped model: ``models/irb6700.onnx``)."""
    path = Path(path) if path is not None else model_path()
    if not path.is_file() and path.parent == Path(".") and path.suffix in ("", ".onnx"):
        shipped = model_path(path.with_suffix(".onnx").name)
        path = shipped if shipped.is_file() else path
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
    # (an optional input with its default initializer is an "overridable initializer" to onnxruntime)
    inputs = {i.name: i for i in (*session.get_inputs(), *session.get_overridable_initializers())}
    outputs = {o.name: o for o in session.get_outputs()}
    joints_output = OUTPUT_JOINTS if OUTPUT_JOINTS in outputs or INPUT_JOINTS in inputs else LEGACY_OUTPUT_JOINTS
    problems = _interface_problems(inputs, outputs, joints_output)
    if problems:
        raise PostprocError("not a postproc compensator: " + "; ".join(problems), str(path), code=P306)
    meta = {k: _json_or_text(v) for k, v in session.get_modelmeta().custom_metadata_map.items()}
    problem = _version_problem(meta)
    if problem:
        raise PostprocError(problem, str(path), code=P306)
    problem = _metadata_problem(meta)
    if problem:
        raise PostprocError(f"model card (metadata_props) is malformed: {problem}", str(path), code=P306)
    return Compensator(
        path=path,
        session=session,
        metadata=meta,
        sha256=hashlib.sha256(data).hexdigest(),
        data=data,
        wants_previous=INPUT_PREVIOUS in inputs,
        has_joints=joints_output in outputs,
        joints_output=joints_output,
        wants_joints=INPUT_JOINTS in inputs,
        wants_tool=INPUT_TOOL in inputs,
        wants_previous_joints=INPUT_PREVIOUS_JOINTS in inputs,
        has_rotation=OUTPUT_ROTATION in outputs,
        has_std=OUTPUT_STD in outputs,
        wants_approach=INPUT_APPROACH in inputs,
        defaults=tuple(i.name for i in session.get_overridable_initializers()),
    )


def contract_version(meta: dict) -> str:
    """The contract version of a model card (``postproc_contract``; a file without one, made by
    other tools, is read as version 1)."""
    value = meta.get("postproc_contract", "1")
    return str(value) if not isinstance(value, float) else f"{value:g}"


def _version_problem(meta: dict) -> str | None:
    version = contract_version(meta)
    if version in CONTRACT_VERSIONS:
        return None
    newer = version.isdigit() and int(version) > int(CONTRACT_VERSIONS[-1])
    return (f"model contract version {version!r} (metadata postproc_contract) is "
            + ("newer than this postproc reads" if newer else "not a contract version")
            + f" (it reads {', '.join(CONTRACT_VERSIONS)}){': update postproc' if newer else ''}")


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
    if meta.get("controller_base") is not None and not _numbers(meta["controller_base"], 6):
        return "'controller_base' must be [X,Y,Z,A,B,C]"
    tool = meta.get("tool")
    if isinstance(tool, dict) and tool.get("frame") is not None and not _numbers(tool["frame"], 6):
        return "'tool' frame must be [X,Y,Z,A,B,C]"
    card = meta.get("uncertainty")
    if card is not None and not (isinstance(card, dict) and _numbers([card.get("max_std_mm")], 1)
                                 and card["max_std_mm"] > 0):
        return "'uncertainty' needs max_std_mm > 0"
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
