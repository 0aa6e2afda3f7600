"""--orientation in RAPID (quaternions) and URScript (rotation vectors) on the simulated robot.

    python benchmarks/orientation_dialects.py [--targets 60] [--seed 11]

N targets drawn (seeded) in the workspace of the default simulated robot (KR500-sim, the
shipped model's: positions in its box, A,B,C within ±10° of its working attitude), written
three ways: a pose list (robot base), a RAPID module (inline robtargets in a work object
whose user and object frames are both shifted and turned, tooldata = the model's tool,
quaternions with 7 decimals, every other one written as −q) and a URScript script
(`set_tcp` = the model's tool, metres and radians with 6 decimals, movel). Each is
compensated by the shipped model with `--orientation` and without it (`postproc
compensate`, one process per command, as a user runs it) and run through the simulated
robot (`postproc verify --json`, tracker noise on): position error (mm) and orientation
error (deg, the angle between target and reached orientation), mean and max, before and
after. And how far the RAPID / URScript commands, taken back to the robot base, are from
the pose list's (max, mm and deg: the written numbers' rounding).
Writes benchmarks/results/orientation_dialects.json.
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from _common import cli, load, record  # noqa: E402
from postproc.core import frames  # noqa: E402
from postproc.programs.io import load_program  # noqa: E402
from postproc.model.compensator import load_model  # noqa: E402

USER_FRAME = np.array([100.0, -50.0, 20.0, 30.0, 10.0, -5.0])
OBJECT_FRAME = np.array([10.0, 20.0, 30.0, 0.0, 0.0, 15.0])


def targets(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform([1800.0, -400.0, 600.0], [2200.0, 400.0, 1200.0], (n, 3)),
                 np.array([0.0, 90.0, 0.0]) + rng.uniform(-10.0, 10.0, (n, 3))]


def numbers(values, decimals: int) -> str:
    return ",".join(f"{v:.{decimals}f}" for v in values)


def rapid(poses: np.ndarray, tool) -> str:
    """The poses as inline robtargets in the work object wTurned (uframe · oframe)."""
    def orient(frame):
        return numbers(frames.quaternion_from_rotation(frames.rotation_from_abc(frame[3:])), 9)

    wobj = frames.frame_to_matrix(USER_FRAME) @ frames.frame_to_matrix(OBJECT_FRAME)
    local = frames.inverse(wobj) @ frames.frame_to_matrix(poses)
    q = frames.quaternion_from_rotation(local[:, :3, :3])
    q[1::2] *= -1.0  # q and −q are one rotation: the written sign must stay
    head = ["MODULE bench",
            f"  PERS tooldata tModel:=[TRUE,[[{numbers(tool[:3], 3)}],[1,0,0,0]],[5,[0,0,100],[1,0,0,0],0,0,0]];",
            f'  PERS wobjdata wTurned:=[FALSE,TRUE,"",[[{numbers(USER_FRAME[:3], 3)}],[{orient(USER_FRAME)}]],'
            f"[[{numbers(OBJECT_FRAME[:3], 3)}],[{orient(OBJECT_FRAME)}]]];", "  PROC main()"]
    moves = [f"    MoveL [[{numbers(t[:3, 3], 4)}],[{numbers(r, 7)}],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], "
             "v100, z1, tModel\\WObj:=wTurned;" for t, r in zip(local, q)]
    return "\n".join(head + moves + ["  ENDPROC", "ENDMODULE", ""])


def urscript(poses: np.ndarray, tool) -> str:
    vectors = frames.rotvec_from_rotation(frames.rotation_from_abc(poses[:, 3:]))
    lines = ["def bench():", f"  set_tcp(p[{', '.join(f'{v / 1000:.6f}' for v in tool[:3])}, 0.0, 0.0, 0.0])"]
    lines += [f"  movel(p[{', '.join(f'{v:.6f}' for v in np.r_[p[:3] / 1000.0, r])}], a=1.2, v=0.25)"
              for p, r in zip(poses, vectors)]
    return "\n".join(lines + ["end", ""])


def in_base(path: Path) -> np.ndarray:
    """A program's targets in the robot base, X,Y,Z,A,B,C."""
    program = load_program(path)
    t = program.targets
    out = np.empty((len(t), 6))
    for f in frames.frames_used(t.frame):
        here = t.frame == f
        out[here] = frames.matrix_to_frame(program.frames[f].base @ frames.frame_to_matrix(t.poses[here]))
    return out


def verify(original: Path, compensated: Path) -> dict:
    report = json.loads(cli("verify", str(original), str(compensated), "--json")[0])
    keep = ("mean", "max")
    return {"before_mm": {k: report["before"][k] for k in keep}, "after_mm": {k: report["after"][k] for k in keep},
            "orientation_before_deg": {k: report["orientation_before_deg"][k] for k in keep},
            "orientation_after_deg": {k: report["orientation_after_deg"][k] for k in keep}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--targets", type=int, default=60)
    parser.add_argument("--seed", type=int, default=11)
    args = parser.parse_args()
    tool = np.asarray(load_model(None).metadata["tool"]["frame"], float)
    poses = targets(args.targets, args.seed)
    figures: dict = {"targets": args.targets}
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "poses.csv").write_text("x,y,z,a,b,c\n" + "".join(numbers(p, 6) + "\n" for p in poses))
        (d / "bench.mod").write_text(rapid(poses, tool))
        (d / "bench.script").write_text(urscript(poses, tool))
        cli("compensate", str(d / "poses.csv"), "-o", str(d / "poses_o.csv"), "--orientation", "-q")
        listed = in_base(d / "poses_o.csv")
        for dialect, name in (("rapid", "bench.mod"), ("urscript", "bench.script")):
            src, out, plain = d / name, d / f"o_{name}", d / f"p_{name}"
            cli("compensate", str(src), "-o", str(out), "--orientation", "-q")
            cli("compensate", str(src), "-o", str(plain), "-q")
            got = in_base(out)
            turn = np.linalg.norm(frames.rotation_error_deg(listed[:, 3:], got[:, 3:]), axis=-1)
            figures[dialect] = {"orientation": verify(src, out), "position_only": verify(src, plain),
                                "vs_pose_list_mm": float(np.abs(got[:, :3] - listed[:, :3]).max()),
                                "vs_pose_list_deg": float(turn.max())}
    path = record("orientation_dialects", figures)
    for dialect in ("rapid", "urscript"):
        f = figures[dialect]
        o, p = f["orientation"], f["position_only"]
        print(f"{dialect}: orientation {o['orientation_before_deg']['mean']:.4f}° → "
              f"{o['orientation_after_deg']['mean']:.4f}° mean (max {o['orientation_after_deg']['max']:.4f}°; "
              f"position only: {p['orientation_after_deg']['mean']:.4f}°), position {o['before_mm']['mean']:.3f} → "
              f"{o['after_mm']['mean']:.3f} mm (position only: {p['after_mm']['mean']:.3f}); against the pose list "
              f"{f['vs_pose_list_mm']:.4f} mm, {f['vs_pose_list_deg']:.6f}° max")
    print(f"load {load()}; wrote {path}")


if __name__ == "__main__":
    main()
