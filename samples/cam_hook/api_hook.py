"""A CAM post-processor step that compensates through postproc's Python API.

    python samples/cam_hook/api_hook.py OUT_DIR [--model MODEL.onnx] [--csv]

Posts three programs of a job (the same toolpath at three sizes here). The model is loaded
once — loading creates the onnxruntime session — and reused for every program: each
``compensate_text`` call is then one batched model call and a text rewrite. The API imports
neither torch, Pinocchio nor matplotlib: about 0.15 s of imports and 0.17 s to create the
shipped model's session, then a few ms per program.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import postproc

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fake_cam_post import post  # noqa: E402  (the CAM side of the example)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--model", help="ONNX compensator (default: the shipped model)")
    parser.add_argument("--csv", action="store_true", help="post pose lists instead of KRL")
    args = parser.parse_args()
    suffix = ".csv" if args.csv else ".src"
    try:
        model = postproc.load_model(args.model)  # once per job, not once per program
        for name, points in (("roughing", 100), ("semi", 250), ("finishing", 1000)):
            text = post(name, points, as_csv=args.csv)
            # name= tells postproc the dialect and is where its messages point
            new_text, report = postproc.compensate_text(text, model, name=name + suffix, strict=True)
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / (name + suffix)).write_bytes(new_text.encode("latin-1"))  # programs are latin-1
            print(f"{name}{suffix}: {report.summary()}", file=sys.stderr)
    except postproc.PostprocError as exc:  # `path:line:col: CODE message`; nothing written for it
        print(f"post-processor: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
