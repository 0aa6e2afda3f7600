"""`postproc export` (issue 27): a model's identified arm as a calibrated URDF that Pinocchio loads
back to the model's geometric part (to 1 µm), for the description's own URDF and for a URDF of the
same arm in other frame conventions; robot_calibration's offsets YAML applied to the nominal URDF
gives the same; the JSON of parameters with their std; a URDF of another arm is refused."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from postproc.core import frames
from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.calibration.export import calibrated_urdf, calibration_yaml, identified_geometry
from postproc.core.frames import MM
from postproc.robot.urdf import nominal_urdf, origin_of, read_urdf, xyz_rpy
from postproc.core.diagnostics import PostprocError
from postproc.robot.description import load_description
from postproc.settings import Settings

pin = pytest.importorskip("pinocchio")
GEOMETRIC = {"groups": ("placement", "base", "tool", "zero"), "ripple": []}


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A kinematic model of the simulated KR500 with only geometric groups (its Ê is P − the
    identified chain's FK at the nominal IK: nothing a URDF cannot hold) and a full hybrid one."""
    from postproc.model.training.fitting import fit

    folder = tmp_path_factory.mktemp("export")
    assert main(["plan", "-n", "80", "--seed", "4", "-o", str(folder / "plan.csv"), "-q"]) == 0
    assert main(["measure", str(folder / "plan.csv"), "-o", str(folder / "m.csv"), "-q"]) == 0
    geometric = fit(str(folder / "m.csv"), Settings().override(method="kinematic", pose_only=True, val_fraction=0.1), kinematic=GEOMETRIC)
    path = geometric.export(folder / "geometric.onnx")
    full = folder / "full.onnx"
    assert main(["train", str(folder / "m.csv"), "-o", str(full), "--method", "kinematic", "-q",
                 "--val-fraction", "0.1"]) == 0
    return path, full


def _targets(model, n=30, seed=5):
    """Poses in the model's envelope, their nominal IK (the graph's ik_joints) and P − Ê."""
    env = model.envelope
    rng = np.random.default_rng(seed)
    poses = np.c_[rng.uniform(env.box[0::2], env.box[1::2], (n, 3)), env.attitude + rng.uniform(-5, 5, (n, 3))]
    poses = poses.astype(np.float32).astype(float)  # (the poses the graph sees: its input is float32)
    error, q = model.predict(poses, with_joints=True)
    return _refined(load_description(), poses, q), poses[:, :3] - error


def _refined(description, poses: np.ndarray, q_deg: np.ndarray) -> np.ndarray:
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


def _pin_tcp(urdf_text: str, q_deg: np.ndarray, frame: str = "postproc_tcp", tmp=None) -> np.ndarray:
    path = tmp / "calibrated.urdf"
    path.write_text(urdf_text)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    fid = model.getFrameId(frame)
    out = []
    for q in np.radians(q_deg):
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[fid].homogeneous.copy())
    out = np.array(out)
    out[:, :3, 3] /= MM
    return out


@pytest.mark.slow
def test_the_calibrated_urdf_is_the_models_geometry_to_a_micrometre(trained, tmp_path):
    model = load_model(trained[0])
    description = load_description()
    out = tmp_path / "cal.urdf"
    assert main(["export", str(trained[0]), "-o", str(out), "--yaml", str(tmp_path / "o.yaml"),
                 "--json", str(tmp_path / "p.json"), "-q"]) == 0
    q, reached = _targets(model)
    tcp = _pin_tcp(out.read_text(), q, tmp=tmp_path)
    assert np.abs(tcp[:, :3, 3] - reached).max() < 1e-3  # mm: Pinocchio's FK of the URDF = P − Ê of the ONNX
    # the nominal URDF is not (the test can fail): the model corrects ~mm
    nominal = _pin_tcp(nominal_urdf(description), q, frame="tcp", tmp=tmp_path)
    assert np.abs(nominal[:, :3, 3] - reached).max() > 0.1
    # the URDF's own flange chain ends at the identified TCP too (tool correction in the flange joint)
    np.testing.assert_allclose(_pin_tcp(out.read_text(), q, frame="tcp", tmp=tmp_path)[:, :3, 3], tcp[:, :3, 3],
                               atol=1e-6)
    card = json.loads((tmp_path / "p.json").read_text())
    assert {p["group"] for p in card["parameters"]} == {"placement", "base", "tool", "zero"}
    assert all(p["std"] is not None and p["std"] > 0 for p in card["parameters"])


def test_robot_calibration_offsets_give_the_same_urdf(trained, tmp_path):
    """The YAML applied as robot_calibration's updateURDF does (origin · offset) = the URDF written."""
    model = load_model(trained[1])
    geometry = identified_geometry(model, load_description())
    nominal = nominal_urdf(load_description())
    calibrated, offsets = calibrated_urdf(nominal, geometry)
    values = dict(line.split(": ") for line in calibration_yaml(offsets).splitlines()[1:])
    want = {j.get("name"): origin_of(j) for j in ET.fromstring(calibrated).findall("joint")}
    for joint in ET.fromstring(nominal).findall("joint"):
        name = joint.get("name")
        if f"{name}_x" not in values:
            continue
        v = {k: float(values[f"{name}_{k}"]) for k in "xyzabc"}
        offset = np.eye(4)
        offset[:3, :3] = frames.rotation_from_rotvec(np.array([v["a"], v["b"], v["c"]]))
        offset[:3, 3] = np.array([v["x"], v["y"], v["z"]]) / MM
        np.testing.assert_allclose(origin_of(joint) @ offset, want[name], atol=1e-6)
    assert "compliance, coupling, backlash" in calibrated  # the comment names what a URDF cannot hold


def _foreign(description, seed=7) -> str:
    """The description's arm in other conventions: a base B, each joint frame changed by a
    rotation and a shift along its axis (C_j), the axis written in the new frame."""
    rng = np.random.default_rng(seed)
    b = frames.frame_to_matrix(np.r_[rng.uniform(-200, 200, 3), rng.uniform(-180, 180, 3)])
    cs = []
    for a in description.axes:
        c = frames.frame_to_matrix(np.r_[0, 0, 0, rng.uniform(-180, 180, 3)])
        c[:3, 3] = a * rng.uniform(-100, 100)
        cs.append(c)
    robot = ET.Element("robot", name="foreign")
    ET.SubElement(robot, "link", name="world_link")
    parent, previous = "world_link", b
    for j, (placement, c) in enumerate(zip(description.placements, cs)):
        origin = (previous if j == 0 else np.linalg.inv(cs[j - 1])) @ placement @ c
        previous = None
        joint = ET.SubElement(robot, "joint", name=f"j{j}", type="revolute")
        xyz, rpy = xyz_rpy(origin)
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=f"l{j}")
        ET.SubElement(joint, "axis", xyz=" ".join(f"{v:.15g}" for v in c[:3, :3].T @ description.axes[j]))
        ET.SubElement(joint, "limit", lower="-3", upper="3", effort="1", velocity="1")
        ET.SubElement(robot, "link", name=f"l{j}")
        parent = f"l{j}"
    for name, m in (("flange", np.linalg.inv(cs[5]) @ description.flange_matrix), ("tool0", description.tool_matrix)):
        joint = ET.SubElement(robot, "joint", name=f"{name}_joint", type="fixed")
        xyz, rpy = xyz_rpy(m)
        ET.SubElement(joint, "origin", xyz=xyz, rpy=rpy)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=name)
        ET.SubElement(robot, "link", name=name)
        parent = name
    return ET.tostring(robot, encoding="unicode"), b


def test_a_urdf_in_other_conventions_is_mapped(trained, tmp_path):
    model = load_model(trained[0])
    description = load_description()
    text, b = _foreign(description)
    nominal = tmp_path / "foreign.urdf"
    nominal.write_text(text)
    out = tmp_path / "foreign_cal.urdf"
    assert main(["export", str(trained[0]), "--urdf", str(nominal), "-o", str(out), "-q"]) == 0
    q, reached = _targets(model)
    tcp = _pin_tcp(out.read_text(), q, tmp=tmp_path)
    want = reached @ b[:3, :3].T + b[:3, 3]  # the URDF's root frame
    assert np.abs(tcp[:, :3, 3] - want).max() < 1e-3
    assert np.abs(_pin_tcp(out.read_text(), q, frame="tool0", tmp=tmp_path)[:, :3, 3] - want).max() < 1e-3


def test_a_urdf_of_another_arm_is_refused(trained, tmp_path):
    description = load_description()
    text = nominal_urdf(description)
    tree = ET.fromstring(text)
    joint = next(j for j in tree.findall("joint") if j.get("name") == "joint_3")
    joint.find("origin").set("rpy", "0 1.5707963 0")  # A3's zero turned by 90°: another arm at q = 0
    bad = tmp_path / "bad.urdf"
    bad.write_text(ET.tostring(tree, encoding="unicode"))
    assert main(["export", str(trained[0]), "--urdf", str(bad), "-o", str(tmp_path / "x.urdf")]) == 2
    with pytest.raises(PostprocError, match="not KR500-sim's joint A4") as info:
        calibrated_urdf(bad.read_text(), identified_geometry(load_model(trained[0]), description), str(bad))
    assert info.value.code == "P533"
    with pytest.raises(PostprocError, match="six revolute"):
        read_urdf('<robot name="r"><link name="a"/></robot>')
    with pytest.raises(PostprocError, match="not XML") as info:
        read_urdf("<robot>\n<link", "x.urdf")
    assert info.value.line == 2


def test_a_network_model_has_nothing_to_export(tmp_path, affine):
    path = affine()
    assert main(["export", str(path), "-o", str(tmp_path / "x.urdf")]) == 2
    assert not (tmp_path / "x.urdf").exists()


def test_the_ur_layout_holds_the_identified_joint_geometry(tmp_path):
    """A UR model: DH deltas (calibration.conf) whose DH chain is the identified joint geometry (in
    the base its first axis defines) to well below 1 µm; the nominal rows are UR's published DH."""
    from postproc.calibration.export import ur_calibration
    from postproc.robot.kinematics.dh import dh_transforms
    from postproc.model.training.fitting import fit

    from helpers import REPO

    data = tmp_path / "ipa.csv"
    assert main(["import", "ipa", str(REPO / "samples" / "ipa" / "series_c_excerpt.csv"), "-o", str(data),
                 "--register", "-q"]) == 0
    ur10 = REPO / "models" / "ur10.toml"
    path = fit(str(data), Settings().override(method="kinematic", robot=str(ur10), pose_only=True, val_fraction=0.1), kinematic=GEOMETRIC).export(tmp_path / "ur.onnx")
    conf = tmp_path / "calibration.conf"
    assert main(["export", str(path), "--robot", str(ur10), "--ur", str(conf), "-q"]) == 0
    text = conf.read_text()
    assert "[mounting]" in text and "delta_theta = [" in text
    geometry = identified_geometry(load_model(path), load_description(ur10))
    _, ur = ur_calibration(geometry)
    np.testing.assert_allclose(ur["nominal_dh"][:, 1:3].T, [[127.3, 0, 0, 163.941, 115.7, 92.2],
                                                           [0, -612, -572.3, 0, 0, 0]], atol=1e-9)
    np.testing.assert_allclose(ur["nominal_dh"][:, 3], np.radians([90, 0, 0, 90, -90, 0]), atol=1e-12)
    assert np.abs(ur["delta"]).max() > 1e-4 and ur["residual_mm"] < 1e-3
    # the deltas as a UR applies them (nominal + delta) against the identified chain, read independently
    q = np.random.default_rng(3).uniform(-3, 3, (50, 6))
    controller = frames.frame_to_matrix(np.array([0, 0, 0, 180.0, 0, 0]))
    chain = geometry.tcp(np.degrees(q))  # (base and TCP: take them out)
    flange = (np.linalg.inv(ur["mounting"]) @ np.linalg.inv(controller) @ np.linalg.inv(geometry.base) @ chain
              @ np.linalg.inv(geometry.end) @ load_description(ur10).flange_matrix)
    dh = dh_transforms(ur["nominal_dh"] + ur["delta"], q)
    assert np.abs(dh[:, :3, 3] - flange[:, :3, 3]).max() < 1e-3
    # a KUKA-type arm is no DH chain in its base (A1 turns about -Z): refused
    kuka = tmp_path / "k.conf"
    assert main(["export", str(REPO / "models" / "default.onnx"), "--ur", str(kuka)]) == 2
    assert not kuka.exists()
