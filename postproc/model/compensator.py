"""The compensator: one ONNX file that maps commanded TCP poses to positioning errors.

Contract (version 3), shared by ``train`` (which writes it) and ``compensate`` (which runs it),
and the interface of any other program that runs the file (onnxruntime alone: ``examples/``,
``docs/INTEGRATION.md``):

* every input but ``pose`` is optional in the ONNX sense: a graph input of ONNX optional type,
  ``optional(tensor(float))`` [N, 6], that onnxruntime lists in ``get_inputs()`` beside
  ``pose`` (C/C++/C#: the session's inputs, type ``ONNX_TYPE_OPTIONAL``) and that a caller feeds
  a plain float32 tensor or leaves out; the graph carries its default (float32 [1, 6] NaN,
  broadcast to ``pose``'s rows: ``contract.with_defaults``), so a caller that omits it gets its
  NaN meaning below, and an omitted ``previous_pose`` (or a row of it with a NaN) is the pose
  itself. A plain ``onnxruntime.InferenceSession(file)`` opens it without a warning.
  Contract-2 files (``postproc_contract`` "2") carry the same defaults as initializers of the
  inputs' names (onnxruntime lists those in ``get_overridable_initializers()`` only and warns
  at each session), contract-1 files have the same inputs without defaults; ``postproc model
  upgrade`` brings both to this contract, ``Compensator`` feeds every input the graph takes
  whichever it is;
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
  there; NaN rows (and a caller that leaves ``joints`` out) take the branch the model
  identified from its training data (the card's ``identified.ik_branch``), which for a target
  in another configuration is the correction of the wrong arm (``postproc model info`` and
  ``compensate -v`` say so for a model with ``joints``). So the fixed
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
* optional input ``load``: float32 [N, 4] = the payload the robot carries at each target:
  mass (kg) and its centre of mass cx, cy, cz (mm, in the flange frame); a row with a NaN (and
  a caller that leaves ``load`` out) = the model's reference load (the card's
  ``loads.reference``: the load a load-blind model would assume). For load-aware models
  (``train`` on data with ``load_mass`` columns at more than one load): the compliance terms
  take each target's gravity torque with that load on the flange, a physical model that
  extrapolates to loads between and beyond those measured; ``Compensator.load_reach`` says
  where (the card's ``loads.extrapolate``). Models without it (``takes_load`` False) are the
  error at the load(s) their data was measured with;
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
  ``postproc/schemas/model_card.schema.json``, ``card.py``): ``postproc_contract`` "3" (a
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
  optional ``loads`` {"measured": [[mass, cx, cy, cz], ...] the distinct loads of the data (kg,
  mm in the flange frame), "rows": [n, ...] the rows at each, "reference": [mass, cx, cy, cz]
  (what a NaN row of ``load`` means; for a model without ``load`` the load it assumes),
  "extrapolate": k (a load-aware model measured at two or more masses reaches masses 0…k × the
  largest measured, centres of mass up to k × the farthest measured or "com_mm"; one measured at
  one mass, and a load-blind one, only the loads measured: ``load_reach``), "aware": bool}; a card without ``loads``
  says nothing of the load (``measured_loads`` empty);
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
agrees with its hypothesis is kept — it lands within SETTLE_TOLERANCE_MM and, with the
orientation, its attitude within SETTLE_TOLERANCE_DEG (a wrist's side turns a tool whose TCP
is on the A6 axis without moving it) — the one nearest the plain iteration's command if
several do, and if none agrees the one with the smallest worst case over both sides (the joint then sits
in its dead band: ``Settled.inside``, reported by compensate as P321). Targets after a changed
one are checked again, in program order across chunks.
"""
from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from ..core.diagnostics import P306, P307, P308, PostprocError
from ..core.resources import model_path
from ..settings import MAX_ITERATIONS
from .contract import (
    INPUT_APPROACH,
    INPUT_JOINTS,
    INPUT_LOAD,
    INPUT_POSE,
    INPUT_PREVIOUS,
    INPUT_PREVIOUS_JOINTS,
    INPUT_TOOL,
    LEGACY_OUTPUT_JOINTS,
    OUTPUT_ERROR,
    OUTPUT_JOINTS,
    OUTPUT_ROTATION,
    OUTPUT_STD,
    _interface_problems,
    _json_or_text,
    _metadata_problem,
    _version_problem,
)
from .envelope import Envelope
from .settle import Chain, CommandChunk, Order, _corrected_attitude, _Settle

# (2048 rows: the intermediates of the hybrid graph stay in cache: ~10 % less CPU than 8192 and
# the same numbers, each row's float32 result does not depend on the batch's length when it is
# a multiple of the SIMD width; benchmarks/compensate_speed.py)
PREDICT_BATCH = 2048
# Rows per chunk of ``command_chunks``: the unit compensate overlaps model runs and rewriting by,
# and a streamed program's chunk for a model that settles the approach. 16,384: a 1M-target CAM
# program streams in 215 MB (65,536: 420 MB, over issue 13's 300 MB) at the same speed; the
# settling's chunk borders move, which changed 2 of 200,000 coordinates by 0.001 mm (last digit)
COMMAND_CHUNK = 1 << 14
# A ``predict`` of at least this many rows runs a session of the graph cut to the outputs it
# asks for (session.py: onnxruntime runs every node whichever outputs are asked; the fixed-point
# iterations need no ``error_std``: 3.3 against 6.5 µs per row for the shipped model, the same
# numbers), its optional inputs plain tensors (no If: ~5 %); smaller ones keep the start-up of
# one session
CUT_ROWS = 8192
# More fixed-point iterations than this is a typo or a hostile model card, not a method (a hang).


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
    wants_load: bool = False  # the graph takes the payload at each target (``load``)
    settle: bool = True  # settle the commands on their approach where the model can (False: the plain fixed point)
    defaults: tuple = ()  # the inputs a caller may omit (contract 3: of optional type; 2: with initializers; contract.py)

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
    def takes_load(self) -> bool:
        """The graph takes the payload at each target (input ``load``): a load-aware model."""
        return self.wants_load

    @property
    def loads(self) -> dict:
        """The card's ``loads`` ({} where it has none; see the contract)."""
        loads = self.metadata.get("loads")
        return loads if isinstance(loads, dict) else {}

    @property
    def measured_loads(self) -> np.ndarray:
        """The loads the model's data was measured with [K, 4] (mass kg, centre of mass cx, cy,
        cz mm in the flange frame: the card's ``loads.measured``); [0, 4] where the card does
        not say."""
        rows = self.loads.get("measured")
        try:
            out = np.asarray(rows, float).reshape(-1, 4)
        except (TypeError, ValueError):
            return np.empty((0, 4))
        return out if np.isfinite(out).all() else np.empty((0, 4))

    @property
    def reference_load(self) -> np.ndarray | None:
        """[4]: the load a NaN row of ``load`` stands for (the card's ``loads.reference``), None
        where the card does not say."""
        ref = self.loads.get("reference")
        try:
            ref = np.asarray(ref, float).reshape(4)
        except (TypeError, ValueError):
            return None
        return ref if np.isfinite(ref).all() else None

    def load_reach(self, load: np.ndarray) -> np.ndarray:
        """[N] bool: True where the model can compensate a target carrying ``load`` [N, 4] (mass
        kg, centre of mass mm; a row with a NaN is the reference load: True). A load-aware model
        (``takes_load``) measured at two or more masses reaches the masses in [0,
        ``loads.extrapolate`` × the largest measured mass] (and a centre of mass no farther from
        the flange than ``loads.extrapolate`` × the farthest measured, at least ``loads.com_mm``:
        the card's rule, from benchmarks/loads.py); one measured at one mass, and a model without
        ``load`` input, reach only the loads measured (within ``loads.mass_tolerance_kg``, default
        1 kg, and 10 mm); a model whose card states no loads reaches the NaN rows only."""
        load = np.asarray(load, float).reshape(-1, 4)
        unknown = np.isnan(load).any(axis=1)
        measured = self.measured_loads
        if not len(measured):
            return unknown
        mass, com = load[:, 0], np.linalg.norm(load[:, 1:], axis=1)
        with np.errstate(invalid="ignore"):
            if self.takes_load and len(np.unique(measured[:, 0])) > 1:
                k = float(self.loads.get("extrapolate", 1.0))
                top = k * measured[:, 0].max()
                far = max(k * np.linalg.norm(measured[:, 1:], axis=1).max(), float(self.loads.get("com_mm", 0.0)))
                ok = (mass >= 0) & (mass <= top + 1e-9) & ((com <= far + 1e-9) | (mass == 0))
            else:
                tol = float(self.loads.get("mass_tolerance_kg", 1.0))
                near = ((np.abs(mass[:, None] - measured[None, :, 0]) <= tol)
                        & (np.linalg.norm(load[:, None, 1:] - measured[None, :, 1:], axis=2) <= 10.0))
                ok = near.any(axis=1) | (mass == 0) & (measured[:, 0] == 0).any()
        return unknown | ok

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
                approach: np.ndarray | None = None, previous_joints: np.ndarray | None = None, std: bool = False,
                load: np.ndarray | None = None):
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
        rows unknown). With ``std`` (a model with ``error_std``): that [N] mm is returned last.
        ``load`` [N, 4] (or [4] for every row): the payload at each pose (mass kg, centre of mass
        cx, cy, cz mm in the flange frame; NaN rows: the model's reference load), fed to a model
        with that input (``takes_load``), ignored by others."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        inputs = self._inputs(poses, previous, joints, tool, approach, previous_joints, load)
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
        one of the graph cut to them (made once per output set from the bytes loaded, its
        optional inputs plain tensors: session.py; the whole graph's where it cannot be cut)."""
        if rows < self.cut_rows or not self.data:
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

    def _inputs(self, poses, previous, joints, tool, approach=None, previous_joints=None,
                load=None) -> dict[str, np.ndarray]:
        """The model's inputs, float32 [N, 6] each (``load`` [N, 4]): ``pose``; ``previous_pose``
        (the pose itself where not given), ``joints``, ``tool``, ``approach``, ``previous_joints``
        and ``load`` (NaN where not given) for a model that takes them."""
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
        if self.wants_load:
            shape = (len(poses), 4)
            inputs[INPUT_LOAD] = (np.full(shape, np.nan, np.float32) if load is None
                                  else np.ascontiguousarray(np.broadcast_to(np.asarray(load, np.float32), shape)))
        return inputs

    def command(self, poses: np.ndarray, iterations: int | None = None, joints=None, tool=None,
                with_joints: bool = False, load=None):
        """Commanded positions [N, 3] so that the robot lands on ``poses[:, :3]``: c = P + Ê(c).
        ``joints`` [N, 6] deg: the controller's joint angles at the *targets* (their
        configuration; every iteration's command is solved on that branch by the model, see
        the contract); ``tool`` [N, 6]: the TCP on the flange. With ``with_joints``: (commands,
        the targets' joint angles [N, 6] deg or None; see ``predict``). The rows are in program
        order: for a model with ``previous_pose`` each target comes from the previous row's
        command. ``load`` [N, 4]: the payload at each target (see ``predict``)."""
        if isinstance(joints, bool):
            joints, with_joints = None, joints
        poses = np.asarray(poses, dtype=float).reshape(-1, 6)
        out = np.empty((len(poses), 3))
        q = np.empty((len(poses), 6)) if with_joints and self.has_joints else None
        for start, commands, q_part in self.command_chunks(poses, iterations, joints, tool, with_joints, load=load):
            out[start:start + len(commands)] = commands
            if q is not None:
                q[start:start + len(commands)] = q_part
        return (out, q) if with_joints else out

    def command_chunks(self, poses: np.ndarray, iterations: int | None = None, joints=None, tool=None,
                       with_joints: bool = False, orientation: bool = False,
                       chain: "Chain | None" = None, std: bool = False,
                       order: "Order | None" = None, load=None) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
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
        target is no row come from another command than the row before's (one chunk of all rows).
        ``load`` [N, 4] (or [4]): the payload at each target (NaN rows: the model's reference
        load), fed to a model that takes it (``takes_load``) at every iteration."""
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
        load = None if load is None or not self.wants_load else np.broadcast_to(np.asarray(load, float), (len(poses), 4))
        if order is not None and not order.sequential:
            return self._ordered(poses, iterations, with_joints, *rows, orientation, std, order, load)
        return self._chunks(poses, iterations, with_joints, *rows, orientation, chain, std, load)

    def command_std(self, commands: np.ndarray, before: np.ndarray | None = None, joints=None, tool=None,
                    previous_joints=None, order: "Order | None" = None, load=None) -> np.ndarray:
        """The model's ``error_std`` [N] mm at commands [N, 6] (program order), each reached from
        the command before it (``previous_pose``; the first row's: ``before`` [6], the command
        of the target before them, None: the row itself), its approach as the graph computes it
        (``approach`` NaN). ``joints``, ``tool``, ``previous_joints``, ``load``: as ``predict``."""
        commands = np.asarray(commands, float).reshape(-1, 6)
        previous = None
        if self.wants_previous and order is not None and not order.sequential:
            previous = order.previous(commands)
        elif self.wants_previous:
            head = commands[:1] if before is None else np.asarray(before, float).reshape(1, 6)
            previous = np.vstack([head, commands[:-1]])
        return self.predict(commands, previous, joints=joints, tool=tool, previous_joints=previous_joints, std=True,
                            load=load)[1]

    def _ordered(self, poses: np.ndarray, iterations: int, with_joints: bool, joints: np.ndarray | None,
                 tool: np.ndarray | None, orientation: bool, std: bool, order: Order, load: np.ndarray | None = None):
        """``command_chunks`` for rows in an :class:`Order` that is not row after row: one chunk,
        each row's previous command its predecessor's (the same fixed-point iteration)."""
        settle = _Settle(self, iterations, orientation, std, order) if self.settles else None
        given = {"joints": joints, "tool": tool}
        if load is not None:
            given["load"] = load
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
                chain: "Chain | None" = None, std: bool = False,
                load: np.ndarray | None = None) -> Iterator[tuple[int, np.ndarray, np.ndarray | None]]:
        chunk = self.command_chunk
        chain = Chain() if chain is None else chain
        settle = _Settle(self, iterations, orientation, std) if self.settles else None
        if settle is not None:
            settle.head = chain.settled
        for start in range(0, len(poses), chunk):
            part = poses[start:start + chunk]
            given = {"joints": None if joints is None else joints[start:start + chunk],
                     "tool": None if tool is None else tool[start:start + chunk]}
            if load is not None:
                given["load"] = load[start:start + chunk]
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
    # (an optional input: of ONNX optional type, contract 3; contract 2's, an input with its default
    # initializer, is an "overridable initializer" to onnxruntime)
    overridable = session.get_overridable_initializers()
    inputs = {i.name: i for i in (*session.get_inputs(), *overridable)}
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
        wants_load=INPUT_LOAD in inputs,
        defaults=tuple([i.name for i in session.get_inputs() if i.type.startswith("optional(")]
                       + [i.name for i in overridable]),
    )


