"""``fit``: measurements → a fitted error model and its model card (``postproc train`` is
this function, its arguments mapped and its PostprocError mapped to exit codes).

    trained = fit("measured.csv", Settings().override(method="hybrid", robot="models/kr500.toml", seed=0))
    trained.model                   # the fitted estimator (HybridModel or ErrorModel)
    trained.card["accuracy"]        # the model card that export writes
    trained.export("cell3.onnx")    # the contract ONNX file, as `postproc train -o cell3.onnx`

The steps: read and check the rows (measurements.py, training/data.py), hold out
``val_fraction`` of them (drawn with ``split_seed``), ``register`` a tracker's measurements to
the base frame on the training rows, then fit

* an identified method (``methods.IDENTIFIED``): ``HybridModel`` on the robot's nominal
  description (``robot``: its .toml file; default the shipped models/kr500.toml) with the
  visiting order's approach directions (unless ``pose_only``), the data's joint angles, tools
  and orientations; or, with ``update=OLD.onnx``, OLD re-calibrated on these rows
  (training/update.py);
* a pose-only network (``methods.NETWORKS``): ``ErrorModel``, its hidden layers first searched
  with ``search`` (training/search.py, candidates run by ``search_engine``);

score it on the held-out rows and assemble the card (training/card.py: robot, reach, tool,
iterations). ``**params`` are the estimator's constructor parameters (``hidden``, ``epochs``,
``seed``, ``progress``; ``optimizer`` of the networks; see HybridModel / ErrorModel).
Messages name train's options (``--update``, ``--method``): they are the same whether the CLI
or a script calls. torch is imported only to fit.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ...core.diagnostics import P317, P320, P507, P508, P516, P519, PostprocError
from ...settings import Settings
from .card import (
    arm_metadata,
    card_iterations,
    demonstration_metadata,
    robot_metadata,
    tool_metadata,
    tool_name,
)
from .methods import IDENTIFIED, METHODS, NETWORKS

__all__ = ["fit", "TrainedModel", "SETTINGS", "ORIENTATION"]

# the identified methods' HybridModel parameters (over its defaults; **params over these);
# dnn-joints: no identification, only the networks on the joint angles (+ approach signs)
SETTINGS = {"hybrid": {"residual": "auto"}, "kinematic": {"residual": "none"},
            "dnn-joints": {"residual": "always", "hidden": (64, 64), "kinematic": {"groups": (), "ripple": []}}}
# the methods that fit measured orientations (a_meas,b_meas,c_meas) too; the others the position only
ORIENTATION = ("hybrid", "kinematic")


@dataclass
class TrainedModel:
    """What ``fit`` made: the fitted estimator, its model card, the rows it was fitted on and
    scored on (indices into the data), what it has to say (``notes``: warnings and what it did,
    one line each) and, where they apply, the fixed point's settling (networks), the
    re-calibration (``update.Update``) and the structure search (``search.SearchResult``)."""

    model: object
    card: dict  # the contract metadata export writes; "name" None: the file's stem
    train_rows: np.ndarray
    val_rows: np.ndarray
    notes: list[str] = field(default_factory=list)
    settled: int | None = None
    update: object | None = None
    search: object | None = None

    def export(self, path: str | Path) -> Path:
        """Write the contract ONNX file with the card (atomically), as ``postproc train -o``."""
        card = dict(self.card)
        card["name"] = card["name"] or Path(path).stem
        return self.model.export_onnx(path, **card)


@dataclass
class _Rows:
    """The data as fit uses it: the file's rows, its name in messages, each row's tool, the
    split, E and the orientation errors (after registration)."""

    data: object  # measurements.Measurements
    source: str
    tools: np.ndarray | None
    train: np.ndarray
    val: np.ndarray
    notes: list[str] = field(default_factory=list)
    errors: np.ndarray | None = None
    rotation_errors: np.ndarray | None = None
    campaigns: np.ndarray | None = None  # [N] int: each row's campaign (index into campaign_names), None: one
    campaign_names: list[str] = field(default_factory=list)
    registrations: dict = field(default_factory=dict)  # campaign name → (tracker → base [4, 4], rms mm)


def fit(measurements, settings: Settings = Settings(), *, progress: bool = False, search_engine=None,
        **params) -> TrainedModel:
    """Fit ``settings.training.method`` to ``measurements`` (a ``measurements.Measurements``, a
    CSV's path, or a list of them: each file a measurement campaign), with the settings whole:

    ``settings.robot``: the robot — its description file or a shipped robot's name (the nominal
    description the identified methods start from, default models/kr500.toml), or any name
    (networks: only for the card; a RobotDescription object too, for library callers).
    ``settings.training``: ``tcp`` (X,Y,Z,A,B,C the data were measured with, where the file does
    not say: ``# tool:``, tool_x..tool_c; a contradiction is refused, P320), ``val_fraction`` and
    ``split_seed`` (the held-out rows; None: ``data.default_val_fraction``, 5 %, none below 100
    rows: every row fitted, which ``notes`` says), ``register`` (the measured columns are a
    tracker's), ``pose_only`` (identified methods without the visiting order), ``update`` (OLD.onnx
    to re-calibrate), ``search`` (search the networks' hidden layers), ``name`` (the card's;
    None: the file's stem), ``seed``, ``hidden``, ``epochs``, ``optimizer``.
    ``progress``: bars on stderr; ``search_engine``: a callable giving a context manager that
    yields the candidates' ``map`` (``fleet.task_map``; None: in place); ``params``: further
    constructor parameters of the estimator (not settings: e.g. HybridModel's ``kinematic``).
    Raises PostprocError (P3xx/P5xx) on data, options or a robot it cannot use."""
    t = settings.training
    method, robot, tool, update, search, name = t.method, settings.robot, t.tcp, t.update, t.search, t.name
    params = {"seed": t.seed, "progress": progress,
              **{k: v for k, v in (("hidden", t.hidden), ("epochs", t.epochs), ("optimizer", t.optimizer)) if v is not None},
              **params}
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r} ({'|'.join(METHODS)})")
    if update and method not in IDENTIFIED:
        raise PostprocError(f"--update re-fits an identified model: --method {method} identifies none "
                            f"(use hybrid or kinematic, or leave --method out)", str(update), code=P317)
    if method in IDENTIFIED and (search or params.get("optimizer") is not None):
        given = " and ".join(o for o, v in (("--search", search), ("--optimizer", params.get("optimizer"))) if v)
        raise PostprocError(f"{given} applies to the pose-only networks ({', '.join(NETWORKS)}); --method {method} "
                            "identifies the robot's parameters (its residual networks have a fixed recipe: --hidden, "
                            "--epochs): leave it out", code=P516)
    rows = _split(measurements, tool, t.val_fraction, t.split_seed)
    if len(rows.campaign_names) > 1 and (method not in IDENTIFIED or update or method == "dnn-joints"):
        what = "--update re-fits OLD on one new campaign" if update else f"--method {method} learns in one frame"
        raise PostprocError(f"the data hold {len(rows.campaign_names)} campaigns ({', '.join(rows.campaign_names)}): "
                            f"{what}; give one campaign's rows, or train --method hybrid on them all",
                            rows.source, code=P519)
    # a robot description is read before the long part, so that a typo fails fast
    # (identified methods read it themselves: it is the model, and may be an arm postproc.robot.arm cannot solve)
    robot_meta = {} if method in IDENTIFIED else robot_metadata(robot)
    _measured(rows, t.register, method)
    if method in IDENTIFIED:
        return _identified(rows, method, _description(robot), t.pose_only, update, name, params)
    return _network(rows, method, robot_meta, search, search_engine, name, params)


def _split(measurements, tool, val_fraction: float, split_seed: int) -> _Rows:
    from ...measurements.csv import Measurements, combine_measurements, parse_tool, read_measurements
    from .data import (
        ALL_ROWS_BELOW,
        default_val_fraction,
        measured_tools,
        split_indices,
    )

    if isinstance(measurements, (list, tuple)):  # several files: each its campaign
        parts = [m if isinstance(m, Measurements) else read_measurements(m) for m in measurements]
        data = combine_measurements(parts)
        source = data.path
    elif isinstance(measurements, Measurements):
        data, source = measurements, measurements.path
    else:
        data, source = read_measurements(measurements), str(measurements)
    if isinstance(tool, str):
        tool = parse_tool(tool)
    tools = measured_tools(data, None if tool is None else np.asarray(tool, dtype=np.float64))
    train, val = split_indices(len(data), default_val_fraction(len(data), val_fraction), split_seed)
    notes = []
    if val_fraction is None and not len(val):
        notes.append(f"every one of the {len(data)} rows fitted, none held out for validation (fewer than "
                     f"{ALL_ROWS_BELOW} rows; --val-fraction F holds some out)")
    rows = _Rows(data, source, tools, train, val, notes)
    if data.campaigns is not None:
        names, codes = np.unique(data.campaigns.astype(str), return_inverse=True)
        order = list(dict.fromkeys(data.campaigns.astype(str)))  # (file order: the first is the reference frame)
        rank = np.array([order.index(n) for n in names])
        rows.campaigns, rows.campaign_names = rank[codes], order
    return rows


def _measured(rows: _Rows, register: bool, method: str) -> None:
    """E (and the orientation errors) of the rows, in the base frame (``register``: a
    tracker's measurements moved there on the training rows), checked."""
    from .data import check_errors, check_rotation_errors

    data = rows.data
    poses, measured = data.poses, data.measured
    frame = data.meta.get("frame", "base").lower()
    split = None
    if rows.campaigns is not None:
        measured = _campaigns_measured(rows, register)
    elif register:
        from ...core.registration import register_measurements

        mask = np.zeros(len(data), dtype=bool)
        mask[rows.train] = True
        from .data import frame_split

        split = frame_split(poses[rows.train, :3], measured[rows.train], data.lines[rows.train])
        measured, transform, rms = register_measurements(poses[:, :3], measured, mask)
        rows.notes.append(f"registered tracker → base on {len(rows.train)} training rows (rms {rms:.3f} mm)")
        if split:
            rows.notes.append(split)  # (said, and in P518 where the errors refuse the rows)
        if data.orientation is not None:  # the probe's orientation turns with the tracker frame
            from ...core.frames import abc_from_rotation, rotation_from_abc

            data = replace(data, orientation=abc_from_rotation(transform[:3, :3] @ rotation_from_abc(data.orientation)))
    elif frame != "base":
        raise PostprocError(f"measured columns are in the {frame}'s frame ('# frame: {frame}'): train with --register",
                            rows.source, code=P507)
    if data.holdout is not None and len(rows.val) and not data.holdout[rows.val].all():
        seen = int((~data.holdout[rows.val]).sum())
        rows.notes.append(
            f"warning: {seen} validation row(s) were used by the file's registration (holdout = 0): "
            "the validation figures are optimistic; use the import's --split-seed and a smaller --val-fraction"
        )
    if rows.campaigns is None:
        rows.notes += check_errors(poses[:, :3], measured, data.lines, rows.source, registered=register, split=split)
    rotation_errors = data.rotation_errors
    if rotation_errors is not None:
        check_rotation_errors(rotation_errors, data.lines, rows.source)
        if method not in ORIENTATION:
            rows.notes.append(f"warning: --method {method} fits the position only: a_meas,b_meas,c_meas not used "
                              "(the model has no rotation_error output; compensate --orientation refuses it)")
    rows.data, rows.errors, rows.rotation_errors = data, poses[:, :3] - measured, rotation_errors


# fewest rows of a campaign (its training rows) a rigid registration of its own is fitted on
MIN_CAMPAIGN_ROWS = 6


def _campaigns_measured(rows: _Rows, register: bool) -> np.ndarray:
    """The measured points of data of several campaigns, each campaign's in the base frame:
    registered on its own training rows where ``register`` and its file does not say
    '# frame: base' (a campaign's file saying '# frame: tracker' without ``register``: P507), each
    campaign's errors checked alone (P509/P518 at its own file)."""
    from ...core.registration import register_measurements
    from .data import check_errors

    data = rows.data
    poses, measured = data.poses, data.measured.copy()
    train = np.zeros(len(data), bool)
    train[rows.train] = True
    for k, name in enumerate(rows.campaign_names):
        mine = rows.campaigns == k
        info = data.campaign_files.get(name, {"path": rows.source, "meta": data.meta})
        path, frame = info["path"], info["meta"].get("frame", "base" if not register else "tracker").lower()
        fit_rows = mine & train
        if fit_rows.sum() < MIN_CAMPAIGN_ROWS and len(rows.campaign_names) > 1:
            raise PostprocError(f"campaign {name!r} has {int(fit_rows.sum())} training rows: a frame of its own "
                                f"needs at least {MIN_CAMPAIGN_ROWS} (measure more, or leave it out)", path,
                                int(data.lines[np.flatnonzero(mine)[0]]), 1, P519)
        if register and frame != "base":
            moved, transform, rms = register_measurements(poses[mine, :3], measured[mine], fit_rows[mine])
            measured[mine] = moved
            rows.registrations[name] = (transform, rms)
            rows.notes.append(f"campaign {name}: registered tracker → base on its {int(fit_rows.sum())} training rows "
                              f"(rms {rms:.3f} mm)")
        elif frame != "base":
            raise PostprocError(f"campaign {name!r}: measured columns are in the {frame}'s frame ('# frame: {frame}'): "
                                "train with --register", path, code=P507)
        rows.notes += check_errors(poses[mine, :3], measured[mine], data.lines[mine], path, registered=register,
                                   campaign=name)
    if data.orientation is not None and len(rows.campaign_names) > 1:
        rows.notes.append("warning: several campaigns: the orientation is not fitted (a_meas,b_meas,c_meas not used; "
                          "no rotation_error output)")
        rows.data = replace(data, orientation=None)
    return measured


def _several_tools(rows: _Rows) -> int:
    """How many TCPs the rows were measured with, if more than one (else 0)."""
    n = 0 if rows.tools is None else len(np.unique(rows.tools, axis=0))
    return n if n > 1 else 0


def _require_one_tool(rows: _Rows, method: str) -> None:
    """Refuse (P320) data of several tools for a method that learns one TCP's error."""
    if _several_tools(rows):
        raise PostprocError(f"--method {method} learns the error of one tool, the data have "
                            f"{_several_tools(rows)}: train --method hybrid (a physical model)", rows.source, code=P320)


def blind_loads_card(loads: np.ndarray) -> dict:
    """The card's ``loads`` of a model that does not take the load (``aware`` False): the loads
    its data was measured with and the rows at each."""
    from .features import measured_loads

    return {**measured_loads(loads)[2], "aware": False}


def _take(values: np.ndarray | None, rows: np.ndarray) -> np.ndarray | None:
    return None if values is None else values[rows]


# -- identified methods ------------------------------------------------------------------------


def _description(robot):
    """The nominal description an identified method starts from: ``robot`` (a description or
    its .toml), else the shipped default (a name other than the default's: P508)."""
    from ...robot.description import (
        RobotDescription,
        is_description_file,
        load_description,
        shipped_description,
    )

    if isinstance(robot, RobotDescription):
        return robot
    if not robot:
        return load_description()
    if is_description_file(robot):
        return load_description(robot)
    found = shipped_description(str(robot))
    if found is None:
        raise PostprocError(f"--method hybrid identifies the robot's kinematics: give its description file "
                            f"(--robot FILE.toml), not the name {robot!r}; or use --method gpso", code=P508)
    return found


@dataclass
class _Inputs:
    """The identified model's inputs of every row: the pose visited before (None: no visiting
    order), the joint angles (None: not in the data) and those of the row visited before."""

    previous: np.ndarray | None
    q_deg: np.ndarray | None
    q_previous: np.ndarray | None


def _identified(rows: _Rows, method: str, description, pose_only: bool, update, name, params) -> TrainedModel:
    from ...robot.configuration import measurement_joints
    from .features import previous_joints, previous_poses
    from .hybrid import HybridModel

    rotation_errors = rows.rotation_errors if method in ORIENTATION else None
    if rotation_errors is not None and _several_tools(rows):
        rows.notes.append("warning: the orientation is fitted from data of one tool: with several tools "
                          "(tool_x..tool_c) a_meas,b_meas,c_meas are not used (no rotation_error output)")
        rotation_errors = None
    if method == "dnn-joints":
        _require_one_tool(rows, method)
    poses = rows.data.poses
    # rows in visiting order (the first came from HOME): the approach direction of each joint
    previous = None if pose_only else previous_poses(poses)
    q_deg, stated, warnings = measurement_joints(description, rows.data, rows.tools)
    rows.notes += warnings
    if not stated.all():  # (the visiting order stays the file's: previous poses computed above)
        rows.train, rows.val = rows.train[stated[rows.train]], rows.val[stated[rows.val]]
    # where the arm really stood before each row (its configuration may differ from the row's)
    inputs = _Inputs(previous, q_deg, None if previous is None else previous_joints(q_deg))
    t = rows.train
    refit = None
    loads = rows.data.loads
    if loads is not None and (method == "dnn-joints" or update):
        rows.notes.append(f"warning: {'--update' if update else '--method ' + method} does not identify what loads "
                          "do: load_mass..load_cz not used (a load-blind model: the card states the loads measured)")
        loads = None
    if loads is not None and rows.campaigns is not None and len(rows.campaign_names) > 1:
        _loads_apart_from_campaigns(rows, loads)
    if update:
        refit = _update(rows, description, update, q_deg, rotation_errors)
        model = refit.model
        if rotation_errors is not None and not model.orientation:
            rows.notes.append(f"warning: --update: {update} fitted no orientation, so a_meas,b_meas,c_meas are not "
                              "used (the updated model has no rotation_error output)")
            rotation_errors = None
        elif refit.old.lever is not None and rotation_errors is None:
            rows.notes.append(f"warning: --update: {update} fitted the orientation, these rows measured none "
                              "(a_meas,b_meas,c_meas): the updated model has no rotation_error output "
                              "(compensate --orientation needs it)")
    else:
        model = HybridModel(description, **{**SETTINGS[method], **params})
        try:
            model.fit(poses[t], rows.errors[t], _take(previous, t), _take(q_deg, t), _take(rows.tools, t),
                      _take(rotation_errors, t), _take(inputs.q_previous, t), campaigns=_take(rows.campaigns, t),
                      loads=_take(loads, t))
        except PostprocError as exc:  # (the estimator knows rows, not files: its findings are the data's)
            if not exc.path:
                exc.path = str(getattr(rows.data, "path", "") or "")
            raise
        if rows.campaigns is not None and len(rows.campaign_names) > 1:
            model.days_var_ = _other_days_variance(rows, description, {**SETTINGS[method], **params}, inputs,
                                                   loads)
        if model.kinematic_.campaign_frames_ is not None:  # (every row in the frame the model predicts in)
            rows.errors = model.kinematic_.to_base(poses, rows.errors, rows.campaigns, q_deg)
    card = _identified_card(model, description, rows, inputs, rotation_errors, refit, name)
    return TrainedModel(model, card, rows.train, rows.val, rows.notes, update=refit)


def _loads_apart_from_campaigns(rows: _Rows, loads: np.ndarray) -> None:
    """Warn where campaigns' loads are hard to tell from their frames: the data hold two loads or
    more, and each campaign one — a campaign's own frame and zero offsets then take up part of
    what its load does (on the simulated KR 500, 0 and 300 kg in two campaigns: 0.118 mm mean
    after compensation at both loads, against 0.081 mm with one campaign at both). One campaign
    measured at two loads or more fixes what loads do for all."""
    t = rows.train
    mass, camp = np.round(loads[t, 0]), rows.campaigns[t]
    if len(np.unique(mass)) < 2:
        return
    if any(len(np.unique(mass[camp == k])) > 1 for k in np.unique(camp).tolist()):
        return
    each = ", ".join(f"{rows.campaign_names[k]} {mass[camp == k][0]:g} kg" for k in np.unique(camp).tolist())
    rows.notes.append(f"warning: each campaign was measured at one load ({each}): a campaign's own frame and zero "
                      "offsets take up part of what its load does, so the model knows loads less well than its "
                      "residual says; measure at two loads or more in one campaign (plan --load M1 --load M2)")


def _other_days_variance(rows: _Rows, description, settings: dict, inputs: _Inputs, loads) -> float:
    """The residual variance (mm² per coordinate) a model of these data leaves on another day:
    each campaign predicted by the model fitted on the other campaigns' training rows, after the
    campaign's own rigid fit (as a user scores a new set-up: its frame is its own), the mean over
    the campaigns. The graph's ``error_std`` takes it where it is larger than the residual at the
    training rows (``HybridModel.days_var_``): a campaign differs from another by more than its
    frame (the tracker's set-up, re-mastering, temperature), and so does the next day."""
    from ...core.registration import fit_rigid
    from .hybrid import HybridModel

    poses, t = rows.data.poses, rows.train
    camp = rows.campaigns[t]
    out = []
    for k in np.unique(camp).tolist():
        others, mine = t[camp != k], t[camp == k]
        left = np.unique(rows.campaigns[others], return_inverse=True)[1]
        loo = HybridModel(description, **settings)
        loo.fit(poses[others], rows.errors[others], _take(inputs.previous, others), _take(inputs.q_deg, others),
                _take(rows.tools, others), None, _take(inputs.q_previous, others),
                campaigns=left if left.max() > 0 else None, loads=_take(loads, others))
        predicted = loo.predict(poses[mine], _take(inputs.previous, mine), _take(inputs.q_deg, mine),
                                _take(rows.tools, mine), _take(inputs.q_previous, mine), loads=_take(loads, mine))
        measured, actual = poses[mine, :3] - rows.errors[mine], poses[mine, :3] - predicted
        rotation, shift = fit_rigid(measured, actual)
        residual = actual - (measured @ rotation.T + shift)
        out.append(float(np.mean(residual ** 2)))
    return float(np.mean(out))


def _update(rows: _Rows, description, old_path, q_deg: np.ndarray | None, rotation_errors: np.ndarray | None):
    """OLD's identification re-fitted on the training rows (``update.Update``), with their
    orientation errors where OLD fitted the orientation."""
    from .features import previous_poses
    from .update import read_old_model, update_model

    if rows.tools is not None and not np.allclose(rows.tools, description.tool):
        raise PostprocError("--update re-fits a model at the tool it was measured with; these rows name "
                            "other tools (# tool: / tool_x..tool_c / --tool): train a new model", rows.source,
                            code=P317)
    old = read_old_model(old_path, description)
    if isinstance(old.card.get("loads"), dict) and old.card["loads"].get("aware"):
        raise PostprocError(f"--update re-fits a model measured at one load; {old_path} takes the load (its card's "
                            "loads): train a new model on the old and the new rows", str(old_path), code=P317)
    poses, t = rows.data.poses, rows.train
    try:
        return update_model(old, description, poses[t], rows.errors[t], _take(previous_poses(poses), t),
                            _take(q_deg, t), rotation_errors=_take(rotation_errors, t))
    except PostprocError as exc:
        exc.path = exc.path or rows.source  # too few rows: say which file
        raise


def _identified_card(model, description, rows: _Rows, inputs: _Inputs, rotation_errors, refit, name) -> dict:
    """The card of a fitted or updated HybridModel (+ notes on rows left out, another IK branch)."""
    from .estimator import accuracy_card

    data, train, val = rows.data, rows.train, rows.val
    if len(model.dropped_):
        lines = data.lines[train][model.dropped_]
        rows.notes.append(f"warning: {len(lines)} training row(s) left out, out of reach of the nominal "
                          f"{description.name} or singular (or their q1..q6 not of that pose): line(s) "
                          f"{', '.join(str(int(n)) for n in lines[:10])}{' ...' if len(lines) > 10 else ''}")
    ident = model.kinematic_.identifiability() if model.kinematic_.layout_.n and refit is None else None
    share = model.kinematic_.branch_share_
    if share == share and share < 0.99:  # (NaN: no joint angles to compare with)
        rows.notes.append(f"warning: {100 * (1 - share):.1f} % of the training rows were reached on another IK "
                          f"branch than {list(model.kinematic_.ik_.branch)}: the model assumes that one everywhere")
    poses = data.poses
    loads = rows.data.loads if getattr(model.kinematic_, "load_reference_", None) is not None else None
    predicted = model.predict(poses[val], _take(inputs.previous, val), _take(inputs.q_deg, val),
                              _take(rows.tools, val), _take(inputs.q_previous, val), loads=_take(loads, val))
    accuracy = accuracy_card(rows.errors[val], predicted, model.train_stats_["mean"], len(train))
    blocked = model.kinematic_.blocked_figures()
    if blocked is not None:  # beside the random held-out rows': each region predicted without it
        accuracy["blocked"] = blocked
    if model.orientation and len(val):
        from ...core.stats import table2

        before = np.linalg.norm(rotation_errors[val], axis=1)
        after = np.linalg.norm(rotation_errors[val] - model.predict_rotation(
            poses[val], _take(inputs.previous, val), _take(inputs.q_deg, val)), axis=1)
        accuracy["val_rotation_deg"] = {"uncompensated": table2(before), "residual": table2(after)}
    found = model.describe()
    found["identifiability"] = ident
    metadata = {
        "name": name,
        "data_sha256": data.sha256,
        "accuracy": accuracy,
        "iterations": card_iterations(model.fixed_point_iterations(poses[train])),
        "identified": found,
    }
    if refit is not None:
        metadata["update"] = refit.card()
    if rows.campaigns is not None:
        metadata["campaigns"] = _campaigns_card(model.kinematic_, rows)
    metadata.update(arm_metadata(description))
    metadata.update(demonstration_metadata(data.meta))
    if rows.tools is not None or model.kinematic_.layout_.n:
        own = model.description_.tool
        same = np.allclose(own, description.tool)
        metadata["tool"] = model.tool_card(description.tool_name if same else tool_name(own))
    if data.loads is not None and loads is None:  # (measured at loads it does not take)
        metadata["loads"] = blind_loads_card(data.loads)
    return model.card(**metadata)


def _campaigns_card(km, rows: _Rows) -> list[dict]:
    """The card's ``campaigns``: each campaign's name, file, rows, and its tracker → base frame —
    the registration (rotation vector deg, offset mm, the matrix; rms) and the identification's
    refinement of it (the first campaign's is the model's own base: none) and its tool offset
    (mm along the TCP's axes, against the first campaign's tool), with their std."""
    out = []
    frames = km.campaign_frames_
    codes = [] if frames is None else list(km.campaign_codes_)
    for k, name in enumerate(rows.campaign_names):
        info = rows.data.campaign_files.get(name, {})
        entry = {"name": name, "file": info.get("path", rows.source), "rows": int((rows.campaigns == k).sum()),
                 "train_rows": int((rows.campaigns[rows.train] == k).sum())}
        if name in rows.registrations:
            transform, rms = rows.registrations[name]
            from ...core.frames import rotation_vector

            entry["registration"] = {"rotation_deg": [round(float(v), 6) for v in np.degrees(
                rotation_vector(transform[:3, :3]))], "offset_mm": [round(float(v), 4) for v in transform[:3, 3]],
                "rms_mm": round(float(rms), 4), "tracker_to_base": np.round(transform, 9).tolist()}
        if k in codes:
            i = codes.index(k)
            f, sd = frames[i], km.campaign_std_[i]
            entry["frame"] = {"reference": i == 0, "rotation_deg": [round(float(v), 6) for v in np.degrees(f[:3])],
                              "offset_mm": [round(float(v), 4) for v in f[3:6]],
                              "rotation_std_deg": [round(float(v), 6) for v in np.degrees(sd[:3])],
                              "offset_std_mm": [round(float(v), 4) for v in sd[3:6]],
                              "tool_mm": [round(float(v), 4) for v in f[6:9]],
                              "tool_std_mm": [round(float(v), 4) for v in sd[6:9]],
                              "zero_deg": [round(float(v), 6) for v in np.degrees(f[9:15])],
                              "zero_std_deg": [round(float(v), 6) for v in np.degrees(sd[9:15])]}
        out.append(entry)
    return out


# -- pose-only networks ------------------------------------------------------------------------


def _network(rows: _Rows, method: str, robot_meta: dict, search: bool, search_engine, name, params) -> TrainedModel:
    from .data import check_size, envelope_of
    from .estimator import ErrorModel, accuracy_card
    from .network import Structure, parse_hidden

    if rows.tools is not None:  # a pose → error map learns one TCP's error
        _require_one_tool(rows, method)
        robot_meta["tool"] = tool_metadata(rows.tools[0])
    if rows.data.loads is not None:  # a pose → error map learns the error at the loads it saw
        rows.notes.append(f"warning: --method {method} does not identify what loads do: load_mass..load_cz not used "
                          "(a load-blind model: the card states the loads measured; train --method hybrid)")
        robot_meta["loads"] = blind_loads_card(rows.data.loads)
    model = ErrorModel(method=method, **params)
    poses, errors, train, val = rows.data.poses, rows.errors, rows.train, rows.val
    found = _search(model, rows, search_engine) if search else None
    if found is not None:
        model.set_params(hidden=found.best)
    structure = Structure(parse_hidden(model.hidden))
    check_size(len(train), structure.n_params, str(structure), rows.source)
    model.fit(poses[train], errors[train])
    accuracy = accuracy_card(errors[val], model.predict(poses[val]), model.train_stats_["mean"], len(train))
    # c = P + Ê(c): iterations after which one more moves no training command by > 0.001 mm
    settled = model.fixed_point_iterations(poses[train])
    metadata = {
        "name": name,
        "robot": "",
        "envelope": envelope_of(poses),
        "data_sha256": rows.data.sha256,
        "accuracy": accuracy,
        "iterations": card_iterations(settled),
    }
    metadata.update(robot_meta)
    metadata.update(demonstration_metadata(rows.data.meta))
    return TrainedModel(model, model.card(**metadata), train, val, rows.notes, settled=settled, search=found)


def _search(model, rows: _Rows, search_engine):
    """The structure search (``search.SearchResult``) for ``model``'s method on the training rows."""
    from contextlib import nullcontext

    from .search import search_structure

    t = rows.train
    try:
        with (search_engine() if search_engine is not None else nullcontext(None)) as map_fn:
            return search_structure(rows.data.poses[t], rows.errors[t], model.method, model.optimizer, model.epochs,
                                    model.seed, progress=model.progress, map_fn=map_fn)
    except PostprocError as exc:
        exc.path = exc.path or rows.source  # too few points for every candidate: say which file
        raise
