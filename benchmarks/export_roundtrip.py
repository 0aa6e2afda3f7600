"""The model as others use it (issue 27): how exactly the exported descriptions hold the model.

    python benchmarks/export_roundtrip.py            # -> benchmarks/results/export_roundtrip.json

* URDF: a geometric kinematic model of the simulated KR500 (groups placement, base, tool, zero;
  1000 poses planned and measured on the simulated robot), exported as a calibrated URDF;
  Pinocchio's FK of its ``postproc_tcp`` at the graph's own joint angles (its float32 ``ik_joints``
  refined to float64 on the nominal FK) against P − Ê of the
  ONNX model over 2000 fresh poses in the envelope (mm: max, mean), for the description's URDF;
  and how far the nominal URDF is (what the export corrects);
* UR layout: a geometric model of the IPA UR10 (Series C, all rows, registered by import; the
  data at $POSTPROC_IPA_DATA, default /work/shared/datasets/ipa-robot-accuracy), its DH deltas'
  chain against the identified joint geometry (mm, the largest over 200 joint angle sets);
* contract: the largest |plain onnxruntime with pose alone − Compensator.predict| over the
  shipped model's rows (mm).
"""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from _common import record
from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.calibration.export import calibrated_urdf, identified_geometry, ur_calibration
from postproc.core.frames import MM
from postproc.robot.urdf import nominal_urdf
from postproc.robot.description import load_description
from postproc.model.training.fitting import fit
from postproc.settings import Settings

GEOMETRIC = {"groups": ("placement", "base", "tool", "zero"), "ripple": []}
IPA = Path(os.environ.get("POSTPROC_IPA_DATA", "/work/shared/datasets/ipa-robot-accuracy"))


def refined_joints(description, poses: np.ndarray, q_deg: np.ndarray) -> np.ndarray:
    """The nominal IK's joint angles in float64: the graph's ``ik_joints`` (float32 deg, ~1e-7 rad)
    refined by Newton steps on the nominal FK to the poses themselves (the angles the graph used)."""
    from postproc.core import frames
    from postproc.robot.arm import Robot

    robot = Robot(description)
    target = frames.frame_to_matrix(poses)
    q = np.radians(np.asarray(q_deg, float))
    for _ in range(3):
        now = robot.fk_matrix(np.degrees(q))
        residual = np.c_[target[:, :3, 3] - now[:, :3, 3],
                         frames.rotvec_from_rotation(target[:, :3, :3] @ np.swapaxes(now[:, :3, :3], 1, 2)) * 1000.0]
        jac = np.empty((len(q), 6, 6))
        for k in range(6):
            step = np.zeros(6)
            step[k] = 1e-7
            moved = robot.fk_matrix(np.degrees(q + step))
            jac[:, :, k] = np.c_[moved[:, :3, 3] - now[:, :3, 3], frames.rotvec_from_rotation(
                moved[:, :3, :3] @ np.swapaxes(now[:, :3, :3], 1, 2)) * 1000.0] / 1e-7
        q = q + np.linalg.solve(jac, residual[..., None])[..., 0]
    return np.degrees(q)


def pin_tcp(text: str, q_deg: np.ndarray, frame: str, folder: Path) -> np.ndarray:
    import pinocchio as pin

    path = folder / f"{frame}.urdf"
    path.write_text(text)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    fid = model.getFrameId(frame)
    out = []
    for q in np.radians(q_deg):
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[fid].translation / MM)
    return np.array(out)


def main_() -> None:
    figures = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        assert main(["plan", "-n", "1000", "--seed", "11", "-o", str(folder / "plan.csv"), "-q"]) == 0
        assert main(["measure", str(folder / "plan.csv"), "-o", str(folder / "m.csv"), "-q"]) == 0
        path = fit(str(folder / "m.csv"), Settings().override(method="kinematic", pose_only=True), kinematic=GEOMETRIC).export(
            folder / "geo.onnx")
        model = load_model(path)
        description = load_description()
        env = model.envelope
        rng = np.random.default_rng(12)
        poses = np.c_[rng.uniform(env.box[0::2], env.box[1::2], (2000, 3)), env.attitude + rng.uniform(-8, 8, (2000, 3))]
        poses = poses.astype(np.float32).astype(float)  # (the poses the graph sees: its input is float32)
        error, q = model.predict(poses, with_joints=True)
        q = refined_joints(description, poses, q)
        reached = poses[:, :3] - error
        geometry = identified_geometry(model, description)
        urdf, offsets = calibrated_urdf(nominal_urdf(description), geometry)
        tcp = pin_tcp(urdf, q, "postproc_tcp", folder)
        d = np.linalg.norm(tcp - reached, axis=1)
        # the URDF against the identified chain itself (the training code's, float64): what the
        # URDF writing loses; the rest of d is the ONNX graph's float32 output
        exact = float(np.abs(tcp - geometry.tcp(q)[:, :3, 3]).max())
        nominal = np.linalg.norm(pin_tcp(nominal_urdf(description), q, "tcp", folder) - reached, axis=1)
        figures["urdf"] = {"poses": len(poses), "max_mm": float(d.max()), "mean_mm": float(d.mean()),
                           "vs_identified_chain_max_mm": exact,
                           "nominal_urdf_mean_mm": float(nominal.mean()), "nominal_urdf_max_mm": float(nominal.max())}
        print(f"URDF round trip over {len(poses)} poses: max {d.max():.2e} mm, mean {d.mean():.2e} mm against the "
              f"ONNX model's P - Ê, {exact:.1e} mm against the identified chain "
              f"(the nominal URDF: mean {nominal.mean():.3f} mm)", file=sys.stderr)

        series = IPA / "Series_C" / "measurements_random_poses.csv"
        if series.is_file():
            assert main(["import", "ipa", str(series), "-o", str(folder / "ipa.csv"), "--register", "-q",
                         "--val-fraction", "0"]) == 0
            ur10 = Path(__file__).resolve().parent.parent / "models" / "ur10.toml"
            ur_model = load_model(fit(str(folder / "ipa.csv"), Settings().override(method="kinematic", robot=str(ur10), pose_only=True), kinematic=GEOMETRIC).export(folder / "ur.onnx"))
            _, ur = ur_calibration(identified_geometry(ur_model, load_description(ur10)))
            figures["ur"] = {"rows": "Series C, all", "dh_residual_mm": ur["residual_mm"],
                             "largest_delta_d_m": float(np.abs(ur["delta"][:, 1]).max() * MM)}
            print(f"UR layout (IPA Series C): the DH chain is {ur['residual_mm']:.2e} mm from the identified joint "
                  "geometry at most", file=sys.stderr)

        import onnxruntime as ort

        shipped = load_model()
        options = ort.SessionOptions()
        options.log_severity_level = 3
        plain = ort.InferenceSession(str(shipped.path), options, providers=["CPUExecutionProvider"])
        rows = poses.astype(np.float32)
        gap = np.abs(plain.run(["error"], {"pose": rows})[0] - shipped.predict(rows)).max()
        figures["contract"] = {"rows": len(rows), "pose_alone_vs_predict_max_mm": float(gap)}
        print(f"shipped model, pose alone in plain onnxruntime vs Compensator.predict: {gap:.1e} mm", file=sys.stderr)
    print(record("export_roundtrip", figures))


if __name__ == "__main__":
    main_()
