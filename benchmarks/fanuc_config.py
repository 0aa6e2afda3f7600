"""A program that states its arm configurations in its controller's form compensates on the
simulated robot as accurately as the same targets as a pose list (issue 25's gate: within 1.2×).

FANUC: fresh Latin-hypercube targets in the R-2000iC-class workspace (models/r2000ic.toml), half
of them in the flipped wrist (as `postproc plan --wrist both` draws them), written as an LS
program whose positions state `CONFIG : 'F U T, t1, t4, t6'` (conventions.fanuc_configs of their
joint angles) in a user frame turned and shifted on the table (UF 1, the frame file), J motions;
the same targets in the robot base as a pose list with the configuration in postproc's portable
form (s,t columns); and, as the control, that pose list without s,t (the model evaluated on the
branch nearest HOME) while the robot runs the stated configurations. Each is compensated with the shipped demonstration model models/r2000ic.onnx
and run, original and compensated, on the simulated robot (the default R2000iC-sim) in the
configuration it states — what `postproc verify` does: the error |target − where the TCP goes|,
with the tracker's noise. ABB the same way (`--family abb`): a RAPID module with confdata in a
work object, models/irb6700.onnx on the IRB6700-sim.

    python benchmarks/fanuc_config.py                 # both families, 300 targets each, seed 7
    python benchmarks/fanuc_config.py --family fanuc --targets 100

Writes benchmarks/results/fanuc_config.json.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from _common import load, record

from postproc.robot import configuration, conventions
from postproc.core import frames
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.calibration.planning import latin_hypercube, plan_configurations, round_poses
from postproc.core.resources import model_path
from postproc.calibration.simulator import SimulatedRobot

# the program's frame on the table, in the robot base: X,Y,Z,A,B,C
FRAMES = {"fanuc": np.array([1650.0, 0.0, -450.0, -90.0, 0.0, 0.0]),
          "abb": np.array([1850.0, -100.0, 600.0, 10.0, 0.0, 0.0])}
MODELS = {"fanuc": ("r2000ic.toml", "r2000ic.onnx"), "abb": ("irb6700.toml", "irb6700.onnx")}


def _targets(sim: SimulatedRobot, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Fresh targets [n, 6] in the description's workspace (robot base) and their joint angles,
    half of them (rows 2, 3 of every four) in the flipped wrist."""
    ws = sim.description.workspace
    poses = round_poses(latin_hypercube(n, ws["box"], ws["attitude"], ws["range"], seed))
    st, ok = plan_configurations(sim.robot, poses, "both")
    poses, st = poses[ok], st[ok]
    q, found = configuration.stated_joints(sim.robot, poses, st[:, 0], st[:, 1])
    return poses[found], q[found]


def _local(frame: np.ndarray, poses: np.ndarray) -> np.ndarray:
    return frames.matrix_to_frame(frames.inverse(frames.frame_to_matrix(frame)) @ frames.frame_to_matrix(poses))


def fanuc_program(poses: np.ndarray, configs: list[str], frame: np.ndarray, tool: np.ndarray) -> tuple[str, str]:
    """(LS text, frame file) of J motions to ``poses`` (robot base) written in UF 1 = ``frame``."""
    local = _local(frame, poses)
    mn = [f"{k:4d}:J P[{k}] 100% FINE    ;" for k in range(1, len(local) + 1)]
    pos = [f"P[{k}]{{\n   GP1:\n\tUF : 1, UT : 1,\t\tCONFIG : '{c}',\n"
           f"\tX = {p[0]:10.3f}  mm,\tY = {p[1]:10.3f}  mm,\tZ = {p[2]:10.3f}  mm,\n"
           f"\tW = {p[5]:10.3f} deg,\tP = {p[4]:10.3f} deg,\tR = {p[3]:10.3f} deg\n}};"
           for k, (p, c) in enumerate(zip(local, configs), start=1)]
    text = "\n".join(["/PROG  BENCH", "/ATTR", "/MN", "   1:  UFRAME_NUM=1 ;", "   2:  UTOOL_NUM=1 ;",
                      *[line.replace(f"{k:4d}:", f"{k + 2:4d}:", 1) for k, line in enumerate(mn, start=1)],
                      "/POS", *pos, "/END", ""])
    wpr = lambda f: [*f[:3], f[5], f[4], f[3]]  # noqa: E731  (A, B, C = R, P, W)
    frames_text = (f"[uframe.1]\nxyzwpr = {[round(float(v), 6) for v in wpr(frame)]}\n"
                   f"[utool.1]\nxyzwpr = {[round(float(v), 6) for v in wpr(tool)]}\n")
    return text, frames_text


def rapid_program(poses: np.ndarray, confdata: np.ndarray, frame: np.ndarray, tool: np.ndarray) -> str:
    """A RAPID module of MoveJ to ``poses`` (robot base) written in a work object = ``frame``."""
    local = _local(frame, poses)
    quat = lambda abc: ",".join(f"{v:.9f}" for v in frames.quaternion_from_rotation(frames.rotation_from_abc(abc)))  # noqa: E731
    lines = ["MODULE bench",
             f"  PERS tooldata tBench:=[TRUE,[[{tool[0]},{tool[1]},{tool[2]}],[{quat(tool[3:])}]],[20,[0,0,100],[1,0,0,0],0,0,0]];",
             f'  PERS wobjdata wBench:=[FALSE,TRUE,"",[[{frame[0]},{frame[1]},{frame[2]}],[{quat(frame[3:])}]],'
             "[[0,0,0],[1,0,0,0]]];", "  PROC main()"]
    for p, c in zip(local, confdata):
        lines.append(f"    MoveJ [[{p[0]:.3f},{p[1]:.3f},{p[2]:.3f}],[{quat(p[3:])}],[{c[0]},{c[1]},{c[2]},{c[3]}],"
                     "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],v500,fine,tBench\\WObj:=wBench;")
    return "\n".join(lines + ["  ENDPROC", "ENDMODULE", ""])


def pose_list(poses: np.ndarray, st: np.ndarray | None) -> str:
    """The targets as a pose list, with their configuration (s,t) or without (each row on the
    branch nearest HOME, as the model's own IK)."""
    if st is None:
        return "x,y,z,a,b,c\n" + "\n".join(",".join(f"{v:.6f}" for v in p) for p in poses) + "\n"
    rows = [",".join([f"{v:.6f}" for v in p] + [str(int(s)), str(int(t))]) for p, (s, t) in zip(poses, st)]
    return "x,y,z,a,b,c,s,t\n" + "\n".join(rows) + "\n"


def _run(sim, model, text, name, config=None, seed=0, run_as: configuration.Stated | None = None) -> dict:
    """Compensate ``text`` and run original and compensated on ``sim`` in their stated
    configurations (``run_as``: in these instead — the robot's, where the program did not say)."""
    import tempfile
    from pathlib import Path

    config_texts = [config] if config else None
    with tempfile.TemporaryDirectory() as folder:
        frames_file = None
        if config:
            frames_file = Path(folder) / "frames.toml"
            frames_file.write_text(config)
        t0 = time.perf_counter()
        out, report = compensate_text(text, model, name=name, config=frames_file)
        seconds = time.perf_counter() - t0
    before, after = (parse_program_text(t, name, config_texts=config_texts) for t in (text, out))
    assert report.compensated == len(before.targets) and report.left == 0, report.summary()
    base = lambda p: frames.matrix_to_frame(  # noqa: E731  (each target in the robot base)
        np.stack([p.frames[f].base for f in p.targets.frame]) @ frames.frame_to_matrix(p.targets.poses))
    rows = np.arange(len(before.targets))
    stated, unmapped, _ = configuration.stated_configuration(before, sim.description, rows)
    assert not unmapped.any()
    stated = stated if run_as is None else run_as
    tools = np.tile(sim.robot.tool, (len(rows), 1))
    result = sim.verify(base(before), base(after), rng_seed=seed, config=stated, tools=tools,
                        motions=before.targets.motion)
    return {"before": result["before"], "after": result["after"], "compensate_s": round(seconds, 3),
            "warnings": len(report.warnings)}


def family(kind: str, n: int, seed: int) -> dict:
    description, model_file = MODELS[kind]
    sim = SimulatedRobot.from_file(model_path(description))
    model = load_model(model_path(model_file))
    poses, q = _targets(sim, n, seed)
    st = np.stack(conventions.status_turn_of(sim.robot, q), axis=1)
    tool = sim.robot.tool
    if kind == "fanuc":
        configs = conventions.fanuc_configs(sim.robot, q)
        text, frames_text = fanuc_program(poses, configs, FRAMES[kind], tool)
        program = _run(sim, model, text, "bench.ls", frames_text)
        forms = sorted(set(c.split(",")[0] for c in configs))
    else:
        conf = conventions.abb_confdata(sim.robot, q)
        program = _run(sim, model, rapid_program(poses, conf, FRAMES[kind], tool), "bench.mod")
        forms = sorted({f"cfx {int(c)}" for c in conf[:, 3]})
    listed = _run(sim, model, pose_list(poses, st), "bench.csv")
    ratio = program["after"]["mean"] / listed["after"]["mean"]
    # the control: the model not told the configuration (each row on the branch nearest HOME)
    # while the robot runs the one the program states: what reading the form is worth
    blind = _run(sim, model, pose_list(poses, None), "bench.csv", run_as=configuration.Stated(st[:, 0], st[:, 1]))
    flipped = int((q[:, 4] <= 0).sum() if kind == "fanuc" else (q[:, 4] < 0).sum())
    print(f"{kind}: {len(poses)} targets ({', '.join(forms)}; {flipped} with J5 ≤ 0 / < 0), robot {sim.robot.name} "
          f"seed {sim.seed}, model {model_file}")
    for label, r in (("program", program), ("pose list", listed), ("unstated", blind)):
        print(f"  {label:10s} before {r['before']['mean']:.4f} mean / {r['before']['max']:.4f} max  →  after "
              f"{r['after']['mean']:.4f} / {r['after']['max']:.4f} mm ({r['warnings']} warnings)")
    print(f"  program / pose list (mean after): {ratio:.3f}  (gate ≤ 1.2: {'met' if ratio <= 1.2 else 'NOT met'})")
    return {"targets": len(poses), "forms": forms, "program": program, "pose_list": listed, "ratio": round(ratio, 4),
            "unstated": blind}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--family", choices=("fanuc", "abb", "both"), default="both")
    parser.add_argument("--targets", type=int, default=300)
    parser.add_argument("--seed", type=int, default=7, help="Latin hypercube seed of the targets (training: 0)")
    args = parser.parse_args()
    print(f"load {load()}")
    figures = {"seed": args.seed}
    for kind in (("fanuc", "abb") if args.family == "both" else (args.family,)):
        figures[kind] = family(kind, args.targets, args.seed)
    print(f"wrote {record('fanuc_config', figures)}")


if __name__ == "__main__":
    main()
