"""``postproc train``: measurement CSV → a compensator ONNX file. The arguments map to
``postproc.model.training.fit`` (training/fitting.py), which fits and makes the model card; this
module writes the model and prints what the fit found."""
from __future__ import annotations

import sys

from ..model.training.methods import (  # (no numpy, no torch: see EXAMPLES)
    IDENTIFIED,
    METHODS,
    OPTIMIZERS,
)
from .settings import ROBOT_HELP, add, settings_of

EXAMPLES = """\
Data: a CSV with the header x,y,z,a,b,c,x_meas,y_meas,z_meas (mm, deg, robot base frame):
the commanded TCP pose and the measured TCP position, one row per visited pose. The model
learns E = P_target − P_measured. Optional columns: a_meas,b_meas,c_meas (a 6-DOF probe's
TCP orientation: hybrid/kinematic then fit the orientation error too and the model outputs
rotation_error, for compensate --orientation), q1..q6 (the controller's joint angles) or,
without them, s,t (KUKA Status/Turn: the joint angles of that configuration), campaign (the
measurement set-up of each row: a tracker placement, a day). Several files given together are
one fit of several campaigns, each file its own (with its own '# frame:' / '# tool:' lines):
each campaign gets its own tracker → base frame in the identification, the robot's parameters
are shared, and the model predicts in the first campaign's frame. `--val-fraction` of the rows (drawn with --split-seed;
default 5 %, none below 100 rows) are held out and only scored on.

Methods: hybrid (the default: the robot's kinematics, compliance, backlash and gear ripple
identified on its nominal description --robot FILE.toml, default models/kr500.toml, plus
residual networks on the joint angles when they help on held-back rows; the optional groups
and how many ripple orders are kept chosen on held-out joint-space regions; the visiting order
of the rows gives the approach directions, and the model takes previous_pose), kinematic
(the identification alone), dnn-joints (no identification: an ensemble of MLPs on the
nominal joint angles and approach directions), gpso (the method of Hu, Hua & Tian: GPSO-searched initial weights
of a pose-only MLP, then backprop), ga, pso, plain (random initial weights). Backprop
optimiser of the pose-only MLPs: lm (Levenberg–Marquardt, the default, as MATLAB's trainlm),
lbfgs, adam, momentum, gd (the method's lr 0.01).

Examples:
  postproc train measured.csv -o models/cell3.onnx --robot models/kr500.toml --name cell3
  postproc train measured.csv -o m.onnx --method gpso --seed 1
  postproc train ipa.csv --register --robot models/ur10.toml -o ur10.onnx --val-fraction 0.2
  postproc train day1.csv day2.csv --register --robot models/ur10.toml -o ur10.onnx  # two set-ups, one fit
  postproc train measured.csv -o m.onnx --search        # pick the hidden layers first (minutes)
  postproc train new30.csv -o new.onnx --update old.onnx --robot models/ur10.toml  # re-calibrate
"""


def add_parser(sub, common, formatter) -> None:
    p = sub.add_parser(
        "train",
        parents=[common],
        formatter_class=formatter,
        help="learn an error model from measurements and write it as ONNX",
        description="Train the error model (identified kinematics + residual networks by default) on a measurement "
        "CSV and export it as a compensator.",
        epilog=EXAMPLES,
    )
    p.add_argument("data", metavar="DATA.csv", nargs="+",
                   help="measurement CSV; several: one fit, each file a measurement campaign (its own tracker frame)")
    p.add_argument("-o", "--output", required=True, metavar="MODEL.onnx", help="model file to write")
    add(p, "method", "hidden", "optimizer", "search", "scheduler", "seed", "split_seed", "val_fraction", "epochs",
        "name", "robot", "tcp", "pose_only", "update", "register",
        helps={"robot": ROBOT_HELP + " (adds reach and tool to the card; hybrid/kinematic: the nominal description to "
               "identify, default models/kr500.toml)"},
        choices={"method": METHODS, "optimizer": OPTIMIZERS})
    p.set_defaults(run=run)


def run(args) -> int:
    from functools import partial

    from ..core.outputs import check_outputs
    from ..fleet.tasks import task_map
    from ..model.training.fitting import fit
    from . import show_progress

    settings = settings_of(args)
    t = settings.training
    check_outputs([args.output], [*args.data, settings.robot or "-", t.update or "-"])  # before the fit, not after it
    data = args.data[0] if len(args.data) == 1 else list(args.data)
    trained = fit(data, settings, progress=show_progress(args), search_engine=partial(task_map, t.scheduler))
    if trained.search is not None and not args.quiet:
        from ..model.training.search import format_table

        print(format_table(trained.search))
    trained.export(args.output)
    if not args.quiet:
        for note in trained.notes:
            print(note, file=sys.stderr)
        (_print_identified if t.method in IDENTIFIED else _print_network)(args, trained)
        print(f"postproc train: wrote {args.output}", file=sys.stderr)
    return 0


def _print_network(args, trained) -> None:
    """What train prints (stdout) about a pose-only network."""
    model, card = trained.model, trained.card
    structure = model.structure_
    print(f"model     {args.output}  ({model.label}, structure {structure}, {structure.n_params} weights, "
          f"{model.fit_seconds_['total']:.1f} s, backprop stopped: {model.stopped_} after {len(model.losses_)} epochs)")
    print(f"data      {' + '.join(args.data)}: {len(trained.train_rows)} training rows, {len(trained.val_rows)} validation rows; "
          f"fixed point settles after {trained.settled} iteration(s), model card says {card['iterations']}")
    print_figures(card["accuracy"], model.train_stats_)


def _print_identified(args, trained) -> None:
    """What train prints (stdout) about an identified model (hybrid, kinematic, dnn-joints, --update)."""
    model, card = trained.model, trained.card
    found, accuracy = card["identified"], card["accuracy"]
    order = "backlash from the visiting order" if model.uses_previous else "no visiting order"
    took = f"; {model.fit_seconds_['total']:.1f} s" if hasattr(model, "fit_seconds_") else ""
    print(f"model     {args.output}  ({model.label}; {model.structure}; {order}{took})")
    if trained.update is not None:
        print_update(trained.update)
    ident = found["identifiability"]
    if ident:
        apart = "; ".join("+".join(g) for g in ident["unseparated"][:6]) or "none"
        apart += " ..." if len(ident["unseparated"]) > 6 else ""
        print(f"identify  rank {ident['rank']} of {ident['parameters']} parameters, condition "
              f"{ident['condition']:.3g}; groups the data cannot "
              f"separate (settled by the prior): {apart}")
    tool = card["tool"]
    if "unseparated" in tool:
        print(f"tools     measured {len(tool['measured'])}: valid for {tool['valid']}")
    if found["ripple"]:
        print(f"ripple    joint:order {' '.join(f'A{j}:{n}' for j, n in found['ripple'])}")
    chosen = found.get("selection")
    if chosen:
        ripple = chosen.get("ripple") or {}
        ways = " and ".join(f"{k} {name}" for name, k in chosen["regions"].items())
        print(f"select    blocked CV over joint-space regions ({ways}, each held out): "
              f"{'left out ' + ', '.join(chosen['dropped']) if chosen['dropped'] else 'every physical group kept'}"
              + (f"; {ripple['kept']} of {ripple['searched']} ripple orders kept" if ripple.get("searched") else ""))
    print(f"data      {' + '.join(args.data)}: {len(trained.train_rows)} training rows, {len(trained.val_rows)} "
          "validation rows")
    for c in card.get("campaigns") or []:
        f = c.get("frame")
        frame = ("the model's own frame (reference)" if f is None or f["reference"] else
                 "frame " + ", ".join(f"{v:+.4f}±{e:.4f}°" for v, e in zip(f["rotation_deg"], f["rotation_std_deg"]))
                 + "; " + ", ".join(f"{v:+.3f}±{e:.3f}" for v, e in zip(f["offset_mm"], f["offset_std_mm"])) + " mm; tool "
                 + ", ".join(f"{v:+.3f}±{e:.3f}" for v, e in zip(f["tool_mm"], f["tool_std_mm"])) + " mm")
        reg = c.get("registration")
        print(f"campaign  {c['name']}: {c['train_rows']} training rows; "
              + (f"registered (rms {reg['rms_mm']:.3f} mm); " if reg else "") + frame)
    spread = card.get("uncertainty") or {}
    if "other_days_std_mm" in spread:
        print(f"std       error_std with another day's spread: {spread['other_days_std_mm']:.3f} mm per coordinate "
              "(each campaign predicted by the model of the others, after its own rigid fit)")
    elif spread and trained.update is None:
        print(f"std       error_std of this set-up (residual {spread['residual_std_mm']:.3f} mm per coordinate): one "
              "campaign cannot tell what another day adds (a tracker set up again, re-mastering); measure a second "
              "campaign and train on both to know it")
    print_figures(accuracy, model.train_stats_)
    if "val_rotation_deg" in accuracy:
        r = accuracy["val_rotation_deg"]
        print(f"{'angle deg (validation)':<26} {'mean':>7} {'max':>7} {'std':>7}")
        for label, key in (("uncompensated", "uncompensated"), ("residual", "residual")):
            print(f"{label:<26} {r[key]['mean']:7.4f} {r[key]['max']:7.4f} {r[key]['std']:7.4f}")


def print_figures(accuracy: dict, train_stats: dict) -> None:
    """The validation table train prints at the end (stdout), from the model card's figures."""
    if accuracy["n_val"]:
        a = accuracy
        print(f"{'|E| mm (validation)':<26} {'mean':>7} {'max':>7} {'std':>7}")
        print(f"{'uncompensated':<26} {a['val_uncompensated_mean_mm']:7.4f} {a['val_uncompensated_max_mm']:7.4f} "
              f"{a['val_uncompensated_std_mm']:7.4f}")
        print(f"{'residual |E − Ê|':<26} {a['val_mean_mm']:7.4f} {a['val_max_mm']:7.4f} {a['val_std_mm']:7.4f}")
    b = accuracy.get("blocked")
    if b:  # (each training row predicted by the identified arm fitted without its joint-space region)
        print(f"{'residual (blocked, arm)':<26} {b['mean_mm']:7.4f} {b['max_mm']:7.4f} {'':>7}  "
              f"({b['rows']} training rows, each predicted with its region held out)")
    s = train_stats
    print(f"{'residual |E − Ê| (train)':<26} {s['mean']:7.4f} {s['max']:7.4f} {s['std']:7.4f}")


def print_update(update) -> None:
    """What ``--update`` re-fitted and which parameters moved (stdout)."""
    card = update.card()
    moved = update.moved
    print(f"update    from {update.old.path} ({card['from']}): {update.rows} rows; re-fitted {', '.join(card['groups'])} "
          f"({len(update.parameters)} parameters), everything else kept; {len(moved)} moved "
          f"(|change| > {card['moved_at_sigmas']:g} std)")
    choice = card.get("choice")
    if choice and len(choice["candidates"]) > 1:
        scores = "; ".join(f"{'+'.join(c['groups'])}: {'-' if c['gcv'] is None else format(c['gcv'], '.4g')}"
                           for c in choice["candidates"])
        print(f"choice    the groups the new rows ask for, in turn (GCV score on the new rows: {scores})")
    region = card.get("region")
    if region:
        chosen = region["chosen"]
        rad, mm = region["spread_rad_mm"]
        what = f"re-fitted, prior spread {chosen * rad * 1e3:g} mrad / {chosen * mm:g} mm" if chosen else "kept"
        scores = ", ".join(f"{f:g}: {'-' if g is None else f'{g:.4g}'}" for f, g in zip(region["factors"], region["gcv"]))
        print(f"region    joint placements {what} (GCV score on the new rows per spread factor: {scores})")
    for p in moved:
        print(f"moved     {p['name']:<9} old {p['old']:+11.5f}  new {p['new']:+11.5f}  change {p['change']:+10.5f} "
              f"± {p['std']:.5f} {p['unit']}")
