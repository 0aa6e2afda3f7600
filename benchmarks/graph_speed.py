"""Speed of a compensator graph alone in onnxruntime: µs per row and run (issue 13).

    python benchmarks/graph_speed.py [MODEL.onnx ...] [--rows 2048] [--repeat 20] [--record]

Feeds the rows a CAM program gives compensate (``compensate_speed.make_cam_program``'s poses,
in program order: ``previous_pose`` = the row before, ``joints`` = the model's own IK of each
pose, ``previous_joints`` = the row before's, ``tool`` = the program's $TOOL, ``approach`` NaN)
in batches of ``--rows`` and times the three runs compensate makes per target: the first
fixed-point iteration (``error`` + ``ik_joints``), the second (``error``) and the approach
settling's run at the commands (``error`` + ``ik_joints`` + ``error_std``), on one thread and
on two. Several models are timed interleaved (model by model within each repeat), so their
ratios come from the same run; the best of the repeats is printed (one thread: the CPU time of the
thread that runs the graph, two: wall time). With ``--record`` the figures go to
benchmarks/results/graph_speed.json: the first model's, and the second's under ``before``
(e.g. ``git show main:models/default.onnx > /tmp/before.onnx``).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort

from _common import ROOT, load, record  # (benchmarks/ is on sys.path when a benchmark runs as a script)
from compensate_speed import cam_poses

PASSES = {"first": ("error", "ik_joints"), "iterate": ("error",), "settle": ("error", "ik_joints", "error_std")}


def session(path: Path, threads: int) -> ort.InferenceSession:
    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    options.inter_op_num_threads = 1
    return ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])


def feeds(sess: ort.InferenceSession, poses: np.ndarray) -> dict[str, np.ndarray]:
    """The inputs compensate gives the graph for ``poses`` in program order."""
    n = len(poses)
    pose = poses.astype(np.float32)
    nan = np.full((n, 6), np.nan, np.float32)
    tool = np.tile(np.array([300, 0, 75, 0, 0, 0], np.float32), (n, 1))
    names = [i.name for i in (*sess.get_inputs(), *sess.get_overridable_initializers())]  # (optional inputs too)
    base = {"pose": pose, "previous_pose": np.vstack([pose[:1], pose[:-1]]), "joints": nan, "approach": nan,
            "tool": tool, "previous_joints": nan}
    base = {k: v for k, v in base.items() if k in names}
    if "joints" in names:  # the model's own IK on its branch: the controller's joints compensate passes
        joints = sess.run(["ik_joints"], base)[0]
        base["joints"] = joints
        if "previous_joints" in names:
            base["previous_joints"] = np.vstack([nan[:1], joints[:-1]])
    return base


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", type=Path, default=[ROOT / "models" / "default.onnx"])
    parser.add_argument("--rows", type=int, default=2048)
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--record", action="store_true")
    args = parser.parse_args(argv)
    poses = cam_poses(100_000)[20_000:20_000 + args.rows]
    per_model: list[dict] = [{"model": str(m)} for m in args.models]
    for threads in (1, 2):
        # one thread: the calling thread's CPU time (onnxruntime runs there; other jobs' load does not
        # count); two: wall time
        clock = time.thread_time if threads == 1 else time.perf_counter
        sessions = [session(m, threads) for m in args.models]
        inputs = [feeds(s, poses) for s in sessions]
        best = {(i, name): np.inf for i in range(len(sessions)) for name in PASSES}
        for _ in range(args.repeat):
            for i, (s, f) in enumerate(zip(sessions, inputs)):
                have = {o.name for o in s.get_outputs()}
                for name, outs in PASSES.items():
                    outs = [o for o in outs if o in have]
                    s.run(outs, f)
                    t0 = clock()
                    s.run(outs, f)
                    best[i, name] = min(best[i, name], clock() - t0)
        for i, m in enumerate(args.models):
            us = {name: best[i, name] / args.rows * 1e6 for name in PASSES}
            print(f"{m}: {threads} thread(s): " + ", ".join(f"{k} {v:.2f}" for k, v in us.items())
                  + f" µs/row; the three runs {sum(us.values()):.2f} µs/row")
            per_model[i][f"threads_{threads}"] = {k: round(v, 3) for k, v in us.items()} | {
                "three_runs": round(sum(us.values()), 3)}
    for i, m in enumerate(args.models):
        per_model[i]["nodes"] = len(onnx.load(str(m)).graph.node)
        print(f"{m}: {per_model[i]['nodes']} nodes")
    figures = per_model[0] | {"rows": args.rows}
    if len(args.models) > 1:
        figures["before"] = per_model[1]
        figures["speedup_1_thread"] = round(per_model[1]["threads_1"]["three_runs"]
                                            / per_model[0]["threads_1"]["three_runs"], 2)
        print(f"one thread: {figures['speedup_1_thread']}x faster than {args.models[1]}")
    print("load:", load())
    if args.record:
        print("wrote", record("graph_speed", figures))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
