"""Re-calibration: ``postproc train NEW.csv -o new.onnx --update OLD.onnx``.

A robot changes between measurement campaigns in a few known ways: the tracker is set up
again (a new base registration), the axes are re-mastered after a crash or a motor change
(joint zero offsets), the probe or tool is mounted again (TCP offset). Its geometry,
compliance, backlash and gears do not. So an update re-fits at most — each group in turn, kept
only where the new rows' GCV score n·RSS/(n − p_eff)² beats the step before's by REGION_GAIN
(the card's ``update.choice``: a wide campaign's model re-fitted on 30 rows of another lost
accuracy to zero offsets and a tool the rows did not ask for: IPA B 0.365 mm with the new frame
alone, 0.386 with all three)

* ``base`` (6: rotation vector rad, offset mm),
* ``zero`` (6: joint zero offsets, rad),
* ``tool`` (3: TCP offset mm, along the flange's axes),
* ``tool_rotation`` (3: the TCP frame's turn, rad) where OLD fitted the orientation and the new
  rows measured it (``a_meas,b_meas,c_meas``): then the orientation is re-fitted with the position
  (OLD's lever, mm/rad) and the updated model keeps ``rotation_error``; new rows without
  orientations give a model without it (OLD's orientation part would be stale after a re-mount)

of OLD's identified model on the new rows — the rows are a new campaign: base, zero and tool are
the 15 parameters every campaign after the first gets in a fit of several campaigns
(``KinematicModel.fit(campaigns=)``; several campaigns in an update are refused, P519, in
training/fitting.py) — as regularised least squares toward OLD's values
(and, where the new rows ask for it, the joint placements: see "The region" below):

    min ‖FK_id(q; θ) − measured‖² + Σ_i (σ_r² / s_i²)·(θ_i − θ_i,old)²

with σ_r OLD's residual std per coordinate and s_i² = OLD's std of θ_i (its covariance, from
the model card) squared + ``DRIFT`` (how far that parameter may move between campaigns)
squared. Every other parameter (placements, compliance, coupling, backlash, ripple orders and
amplitudes), the residual networks (read back from OLD's graph), the joint ranges and the
envelope are OLD's. A base rotation about Z and A1's zero offset are one effect (both turn
the whole arm about the A1 axis): the prior splits it by their spreads, and the posterior std
reports that the data did not tell them apart.

The region. An identification holds best in the joint region its rows covered: the geometry
fitted there carries a little of that region's unmodelled error (on the IPA UR10, a model of
Series C's joint region leaves 0.45–0.50 mm on the other series' regions after the 15-parameter
update, with 30 rows or with 400). So the update also tries the joint placements (36: each
joint frame's small turn and shift) free around OLD's values, with prior spreads
``REGION_FACTORS`` × (1 mrad, 0.5 mm), and keeps the one of those fits with the least
generalised cross-validation score n·RSS/(n − p_eff)² on the new rows if it is below
``REGION_GAIN`` × the score without them (else: placements kept) — the rows decide, nothing
else (IPA, 30 rows, 5 draws each: B / D / A 0.468 / 0.455 / 0.496 → 0.436 / 0.379 / 0.474 mm
on each series' other rows; the simulator's re-mastering keeps them). The card's
``update.region`` gives each factor's score and the one chosen.

The parameters that moved are those whose change exceeds ``MOVED_SIGMAS`` times its posterior
std, σ²·(JᵀJ + W)⁻¹ (σ² the new rows' residual variance per coordinate): name, old, new,
change, std (deg for angles, mm for lengths).

A model with ``error_std`` keeps it: OLD's parameter covariance (read from its graph) for what
the update kept, the re-fit's for what it moved, the new rows' residual variance.

OLD must carry its identification in its card (``identified.parameters``, ``ripple_amplitudes``,
``tau_mean``: hybrid/kinematic models since ``--update`` exists): else P317 (a DNN/gpso model,
an older card); a model of another robot description: P318.
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ...core.diagnostics import P317, P318, P505, PostprocError
from ...robot.description import RobotDescription
from ...robot.kinematics.twin import make_ik
from .hybrid import HybridModel, ResidualNet, learned_ranges
from .kinematic import GROUPS, KinematicModel, Layout, nominal_digest

__all__ = ["UPDATE_GROUPS", "DRIFT", "OldModel", "Update", "read_old_model", "update_model"]

UPDATE_GROUPS = ("base", "zero", "tool")
ORIENTATION_GROUPS = ("tool_rotation",)  # re-fitted too where the new rows measured the orientation
# how far each re-fitted parameter may move between campaigns (1σ of the prior on top of OLD's
# std): a new tracker set-up (10 mrad, 10 mm after the import's rigid fit), re-mastering
# (5 mrad = 0.29°), a probe or tool mounted again (10 mm; turned by 50 mrad = 2.9°)
DRIFT = {"base": np.r_[np.full(3, 0.01), np.full(3, 10.0)], "zero": np.full(6, 0.005), "tool": np.full(3, 10.0),
         "tool_rotation": np.full(3, 0.05)}
# the joint placements' prior spreads tried (× REGION_SPREAD per joint: turn rad, shift mm); 0: kept
REGION_FACTORS = (0.0, 0.1, 0.2, 0.5, 1.0)
REGION_SPREAD = np.r_[np.full(3, 1e-3), np.full(3, 0.5)]
# ... and kept only when its GCV score is below this share of the 15-parameter fit's (parsimony:
# on the simulator's re-mastering the placements change the score by 0.2 %, on IPA by 4–50 %)
REGION_GAIN = 0.95
# a re-fitted parameter moved when its change exceeds this many posterior stds
MOVED_SIGMAS = 3.0
# each group's parameters: (name, is an angle)
NAMES = {"base": [("rx", True), ("ry", True), ("rz", True), ("x", False), ("y", False), ("z", False)],
         "zero": [(f"A{j}", True) for j in range(1, 7)], "tool": [("x", False), ("y", False), ("z", False)],
         "tool_rotation": [("rx", True), ("ry", True), ("rz", True)],
         "placement": [(f"A{j}.{c}", c.startswith("r")) for j in range(1, 7) for c in ("rx", "ry", "rz", "x", "y", "z")]}


@dataclass
class OldModel:
    """What a re-calibration takes from OLD: its identification and everything around it."""

    path: Path
    sha256: str
    card: dict
    layout: Layout
    theta: np.ndarray  # [P] (rad, mm, rad/Nm as the layout)
    std: np.ndarray  # [P] OLD's std of each parameter (NaN: not stored)
    residual_std_mm: float  # OLD's residual std per coordinate
    tau_mean: np.ndarray  # [27]
    ik: torch.nn.Module
    use_previous: bool
    nets: list[ResidualNet] = field(default_factory=list)
    hidden: tuple[int, ...] = (32, 32)
    joint_range: list | None = None
    envelope: dict | None = None
    covariance: np.ndarray | None = None  # [P, P] OLD's parameter covariance (its graph's error_std), if it has one
    lever: float | None = None  # mm/rad: OLD fitted the orientation with this weight (None: position only)
    learned_var: float = 0.0  # mm²: what OLD's error_std adds outside its joint arcs (its learned parts)


@dataclass
class Update:
    """The updated model and what moved."""

    model: HybridModel
    old: OldModel
    rows: int
    parameters: list[dict]  # every re-fitted parameter: group, name, unit, old, new, change, std, moved
    region: dict | None = None  # the placements' spread factors tried, their GCV scores, the one chosen
    choice: dict | None = None  # the groups tried in turn, their GCV scores, the ones chosen

    @property
    def moved(self) -> list[dict]:
        return [p for p in self.parameters if p["moved"]]

    def card(self) -> dict:
        """The new model card's ``update`` entry."""
        return {"from": self.old.card.get("name") or self.old.path.stem, "from_sha256": self.old.sha256,
                "rows": self.rows, "groups": list(dict.fromkeys(p["group"] for p in self.parameters)),
                "moved_at_sigmas": MOVED_SIGMAS, "region": self.region, "choice": self.choice,
                "parameters": self.parameters}


def _refuse(message: str, path: Path, code: str = P317) -> PostprocError:
    return PostprocError(message, str(path), code=code)


def _initializers(data: bytes) -> dict[str, np.ndarray]:
    """OLD's graph's named initializers (its residual networks' weights, its covariance)."""
    import onnx
    from onnx import numpy_helper

    return {i.name: numpy_helper.to_array(i) for i in onnx.load_from_string(data).graph.initializer}


def _residual_nets(path: Path, weights: dict, count: int) -> tuple[list[ResidualNet], tuple[int, ...]]:
    """OLD's residual networks, read back from its graph's named initializers ``weights``."""
    if not count:
        return [], (32, 32)
    nets, hidden = [], ()
    for k in range(count):
        prefix = f"module.nets.{k}."
        layers = sorted({int(n[len(prefix) + 4:].split(".")[0]) for n in weights if n.startswith(prefix + "net.")})
        try:
            state = {name[len(prefix):]: torch.as_tensor(np.array(w, dtype=np.float64)) for name, w in weights.items()
                     if name.startswith(prefix)}
            # the exporter keeps one initializer for equal tensors, under the first network's
            # name: the networks fitted on the same rows share their standardisation
            for key in ("x_mean", "x_std", "y_std"):
                earlier = [f"module.nets.{j}.{key}" for j in range(k) if f"module.nets.{j}.{key}" in weights]
                if key not in state and earlier:
                    state[key] = torch.as_tensor(np.array(weights[earlier[0]], dtype=np.float64))
            shapes = [tuple(state[f"net.{i}.weight"].shape) for i in layers]
            hidden = tuple(s[0] for s in shapes[:-1])
            net = ResidualNet(shapes[0][1], hidden, state["x_mean"], state["x_std"], state["y_std"])
            net.load_state_dict(state)
        except (KeyError, IndexError, RuntimeError) as exc:
            raise _refuse(f"--update: the model card names {count} residual network(s), but network {k} cannot be read "
                          f"back from the graph ({type(exc).__name__}: {exc}); re-train without --update", path) from None
        nets.append(net.eval())
    return nets, hidden


def read_old_model(path: str | Path, description: RobotDescription) -> OldModel:
    """OLD's identification from its model card (and its residual networks from its graph);
    P317 when it has none to re-fit, P318 when it is of another robot description."""
    from ..compensator import load_model

    path = Path(path)
    old = load_model(path)
    card = old.metadata
    found = card.get("identified") if isinstance(card.get("identified"), dict) else {}
    params = found.get("parameters") if isinstance(found.get("parameters"), dict) else {}
    method = card.get("method", "?")
    if not params:
        raise _refuse(f"--update re-fits an identified model, but this model's card stores no identified parameters "
                      f"(method: {method}): train the new data without --update, or update a hybrid/kinematic model",
                      path)
    missing = [k for k in ("ripple_amplitudes", "tau_mean", "ik_family", "ik_branch", "ripple", "nominal_sha256")
               if k not in found]
    if missing:
        raise _refuse(f"--update: this model's card is older than --update (no {', '.join(missing)} under "
                      f"'identified'): re-train it once with this version, then update it", path)
    if card.get("robot") != description.name:
        raise _refuse(f"--update: the model is of robot {card.get('robot')!r}, the description given is "
                      f"{description.name!r} ({description.path}): give the old model's description with --robot",
                      path, P318)
    if found["nominal_sha256"] != nominal_digest(description):
        raise _refuse(f"--update: the description {description.path} is not the one the model was identified on "
                      f"(same name {description.name!r}, other nominal chain, flange, tool, masses or HOME): give "
                      f"that description with --robot", path, P318)
    groups = tuple(g for g in GROUPS if g in params)
    ripple = [(int(j) - 1, int(n)) for j, n in found["ripple"]]
    layout = Layout(groups, ripple)
    amplitudes = np.asarray(found["ripple_amplitudes"], dtype=np.float64).reshape(-1)
    stds = found.get("parameter_std") or {}
    try:
        theta = np.concatenate([np.asarray(params[g], dtype=np.float64) for g in groups] + [amplitudes])
        std = np.concatenate([np.asarray(stds.get(g, [math.nan] * layout.sizes[g]), dtype=np.float64) for g in groups]
                             + [np.full(len(amplitudes), math.nan)])
        tau_mean = np.asarray(found["tau_mean"], dtype=np.float64)
        ik = make_ik(description, found["ik_family"], tuple(float(b) for b in found["ik_branch"]))
    except (ValueError, TypeError) as exc:
        raise _refuse(f"--update: the model card's identification is malformed ({exc})", path) from None
    except PostprocError as exc:
        raise _refuse(f"--update: the description {description.path} cannot solve the model's IK "
                      f"({exc.message})", path, P318) from None
    if len(theta) != layout.n or len(std) != layout.n or tau_mean.shape != (27,):
        raise _refuse(f"--update: the model card's identification is malformed ({len(theta)} values for "
                      f"{layout.n} parameters of {', '.join(groups)} + {len(ripple)} ripple orders)", path)
    envelope = card.get("envelope") if isinstance(card.get("envelope"), dict) else None
    joint_range = (envelope or {}).get("joints")
    if joint_range is None:
        raise _refuse("--update: the model card has no trained joint ranges (envelope.joints)", path)
    data = path.read_bytes()
    weights = _initializers(data)
    nets, hidden = _residual_nets(path, weights, int(found.get("residual_nets") or 0))
    covariance = _graph_covariance(weights, layout.n)
    learned_var = float(np.asarray(weights.get("module.learned_var", 0.0)))
    residual_std = float(found.get("residual_std_mm") or 0.0)
    if not residual_std > 0:  # (a card without it: the training residual's mean norm ≈ 1.6 σ per coordinate)
        residual_std = float(((card.get("accuracy") or {}).get("train_mean_mm") or 0.1)) / 1.6
    orientation = found.get("orientation") if isinstance(found.get("orientation"), dict) else {}
    lever = orientation.get("lever_mm_per_rad") if orientation.get("fitted") else None
    return OldModel(path, hashlib.sha256(data).hexdigest(), card, layout, theta, std, residual_std, tau_mean, ik,
                    old.wants_previous, nets, hidden, joint_range, envelope, covariance,
                    float(lever) if lever else None, learned_var=learned_var)


def _graph_covariance(weights: dict, n: int) -> np.ndarray | None:
    """OLD's parameter covariance [n, n] from its graph's initializers (the buffer behind
    ``error_std``), or None for a model without that output."""
    cov = weights.get("module.covariance")
    if cov is None:
        return None
    cov = np.array(cov, dtype=np.float64)
    return cov if cov.shape == (n, n) else None


def _prior(old: OldModel, groups: tuple[str, ...], drift: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(free [P] bool, weights [P] mm² per unit²) of the re-fit; ``drift``: spreads of groups not
    in ``DRIFT`` (the placements')."""
    drift = {**DRIFT, **(drift or {})}
    free = np.zeros(old.layout.n, bool)
    spread = np.full(old.layout.n, np.inf)
    slices = old.layout.slices()
    for g in groups:
        if g not in slices:
            continue
        free[slices[g]] = True
        prior_std = np.nan_to_num(old.std[slices[g]], nan=0.0)
        spread[slices[g]] = np.sqrt(prior_std**2 + drift[g] ** 2)
    return free, old.residual_std_mm**2 / spread**2


def _net_part(old: OldModel, description: RobotDescription, poses: np.ndarray, previous: np.ndarray | None,
              q_deg: np.ndarray | None) -> np.ndarray:
    """[N, 3] mm: what OLD's residual networks add at these rows (0 outside its joint ranges)."""
    from ...robot.kinematics.twin import Arm
    from .hybrid import HybridModule
    from .kinematic import KinematicErrorModule

    kinematic = KinematicErrorModule(Arm(description), old.ik, old.layout, old.theta, old.use_previous, old.tau_mean)
    pose = torch.as_tensor(poses)
    prev = None if previous is None else torch.as_tensor(np.asarray(previous, dtype=np.float64).reshape(-1, 6))
    q_in = None if q_deg is None else torch.as_tensor(np.radians(np.asarray(q_deg, dtype=np.float64).reshape(-1, 6)))
    ranges = learned_ranges(old.joint_range)
    with torch.no_grad():
        full = HybridModule(kinematic, old.nets, ranges)(pose, prev, q_in)
        alone = HybridModule(kinematic, [], ranges)(pose, prev, q_in)
    return (full - alone).numpy()


def update_model(old: OldModel, description: RobotDescription, poses: np.ndarray, errors: np.ndarray,
                 previous: np.ndarray | None = None, q_deg: np.ndarray | None = None,
                 groups: tuple[str, ...] = UPDATE_GROUPS, rotation_errors: np.ndarray | None = None) -> Update:
    """OLD re-fitted on the new rows (commanded poses [N, 6], errors E [N, 3], the pose visited
    before each row, the controller's joint angles [N, 6] deg if known, the measured orientation
    errors [N, 3] deg if any): see the module text."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 6)
    lever = old.lever if rotation_errors is not None else None
    if lever is not None:
        groups = tuple(groups) + tuple(g for g in ORIENTATION_GROUPS if g not in groups)
    else:
        rotation_errors = None
    free, weights = _prior(old, groups)
    if not free.any():
        raise _refuse(f"--update: the model identified none of {', '.join(groups)}", old.path)
    if 3 * len(poses) < free.sum():
        raise PostprocError(f"{len(poses)} rows give {3 * len(poses)} measured coordinates, fewer than the "
                            f"{int(free.sum())} parameters --update re-fits: measure at least {-(-int(free.sum()) // 3)} "
                            f"poses (30 recommended)", code=P505)
    errors = np.asarray(errors, dtype=np.float64).reshape(-1, 3)
    target = errors
    if old.nets:  # the identification is re-fitted to what OLD's residual networks leave
        came_from = poses if previous is None else previous  # (unknown: from HOME, as the re-fit takes it)
        target = errors - _net_part(old, description, poses, came_from if old.use_previous else None, q_deg)
    # what the new rows ask for: the groups in turn (a new frame; re-mastered axes; a tool mounted
    # again), each step kept only where its GCV score beats the step before's by REGION_GAIN
    # (``choice``), then the joint placements on top of them all (``region``)
    extra = tuple(g for g in groups if g in ORIENTATION_GROUPS)
    ladder = [t for t in (tuple(g for g in groups if g not in ORIENTATION_GROUPS)[:k + 1] for k in
                          range(len([g for g in groups if g not in ORIENTATION_GROUPS])))]
    steps = []
    for tried in ladder:
        if not _prior(old, tried + extra)[0].any():
            continue
        steps.append((0.0, tried + extra, _refit(old, description, tried + extra, {}, poses, target, previous, q_deg,
                                                 rotation_errors, lever)))
    best = steps[0]
    for step in steps[1:]:
        if step[2][-1] < REGION_GAIN * best[2][-1]:
            best = step
    choice = {"candidates": [{"groups": list(t), "gcv": round(f[-1], 6) if math.isfinite(f[-1]) else None}
                             for _, t, f in steps], "chosen": list(best[1])}
    fits, region = [steps[-1]], None
    if "placement" in old.layout.groups and "placement" not in groups:
        for factor in REGION_FACTORS[1:]:
            tried = steps[-1][1] + ("placement",)
            fits.append((factor, tried, _refit(old, description, tried, {"placement": np.tile(factor * REGION_SPREAD, 6)},
                                               poses, target, previous, q_deg, rotation_errors, lever)))
    if len(fits) > 1:
        region = {"factors": [f for f, _, _ in fits], "spread_rad_mm": REGION_SPREAD[[0, 3]].tolist(),
                  "gcv": [round(f[-1], 6) if math.isfinite(f[-1]) else None for _, _, f in fits]}
    placed = min(fits[1:], key=lambda f: f[2][-1], default=None)
    if placed is not None and placed[2][-1] < REGION_GAIN * best[2][-1]:
        best = placed
        choice["chosen"] = list(best[1])
    factor, groups, (km, free, weights, jf, a_inv, sigma2, _) = best
    if region is not None:
        region["chosen"] = factor
    model = HybridModel.refitted(description, km, old.nets, old.hidden, old.joint_range, old.envelope, poses, errors,
                                 previous if old.use_previous else None, q_deg, rotation_errors)
    post_std = np.sqrt(np.clip(np.diag(a_inv), 0.0, None) * sigma2)
    std = old.std.copy()
    std[free] = post_std
    model.identification_std_ = (std, old.residual_std_mm)
    if old.covariance is not None:
        # error_std goes on: OLD's covariance of what it kept, the re-fit's posterior of what it
        # moved (σ²A⁻¹, as ``uncertainty``'s predictive covariance: the directions the new rows
        # do not separate keep their prior's spread), the new rows' residual variance (what this
        # campaign leaves unexplained) and OLD's learned parts' variance outside its arcs
        cov = old.covariance.copy()
        cov[free, :], cov[:, free] = 0.0, 0.0
        cov[np.ix_(free, free)] = sigma2 * a_inv
        model.module_.set_uncertainty(cov, sigma2, old.learned_var)
    column = {int(i): k for k, i in enumerate(np.flatnonzero(free))}  # parameter → its place among the free ones
    table = []
    slices = old.layout.slices()
    for g in groups:
        if g not in slices:
            continue
        for i, (name, angle) in zip(range(slices[g].start, slices[g].stop), NAMES[g]):
            scale = math.degrees(1.0) if angle else 1.0
            before, after, std = old.theta[i] * scale, km.theta_[i] * scale, post_std[column[i]] * scale
            table.append({"group": g, "name": f"{g}.{name}", "unit": "deg" if angle else "mm",
                          "old": round(float(before), 6), "new": round(float(after), 6),
                          "change": round(float(after - before), 6), "std": round(float(std), 6),
                          "moved": bool(abs(after - before) > MOVED_SIGMAS * std)})
    return Update(model, old, model.n_train_, table, region, choice)


def _refit(old: OldModel, description: RobotDescription, groups: tuple[str, ...], drift: dict, poses, target,
           previous, q_deg, rotation_errors, lever):
    """One re-fit of ``groups`` → (KinematicModel, free, weights, J of the free parameters,
    (JᵀJ + W)⁻¹, σ² per coordinate, GCV score: inf where it has as many effective parameters
    as measured coordinates)."""
    free, weights = _prior(old, groups, drift)
    km = KinematicModel(description, groups=old.layout.groups, ripple=list(old.layout.ripple))
    km.refit(old.layout, old.theta, old.tau_mean, old.ik, old.use_previous, free, weights, poses, target, previous,
             q_deg, learned_ranges(old.joint_range), rotation_errors, lever)
    # the posterior of the re-fitted parameters: σ²(JᵀJ + W)⁻¹ at the solution
    _, jac, _ = km._state
    jf = jac[:, free]
    a_inv = np.linalg.pinv(jf.T @ jf + np.diag(weights[free]), hermitian=True)
    p_eff = float(np.trace(a_inv @ (jf.T @ jf)))
    r = np.asarray(km.train_residual_, float).reshape(-1)
    if km.orientation_:  # (the orientation's rows as the fit weighed them: rad × lever)
        r = np.r_[r, lever * np.radians(np.asarray(km.train_rotation_residual_, float).reshape(-1))]
    rss, dof = float(r @ r), len(r) - p_eff
    gcv = len(r) * rss / dof**2 if dof >= 1.0 else math.inf  # (as many parameters as coordinates: no score)
    return km, free, weights, jf, a_inv, rss / max(dof, 1.0), gcv
