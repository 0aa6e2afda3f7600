"""The contract as an integrator uses it: plain onnxruntime, feeding only `pose`, `pose` + `joints`,
or every input, gives what `Compensator.predict` gives (issue 27) — for the shipped model and a
model of every training method, freshly trained on a small simulated measurement; the card
holds to its JSON Schema; an older contract is read (and upgraded), a newer one refused."""
from __future__ import annotations

import json

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from helpers import REPO

from postproc.cli import main
from postproc.model.contract import CONTRACT_VERSION
from postproc.model.compensator import load_model
from postproc.model.contract import OPTIONAL_INPUTS, upgrade
from postproc.core.diagnostics import PostprocError
from postproc.measurements.csv import read_measurements
from postproc.model.card import card_problems
from postproc.testing.models import affine_model, joint_model
from postproc.model.training.methods import METHODS

SHIPPED = sorted((REPO / "models").glob("*.onnx"))
TINY = ["--hidden", "4", "--epochs", "5", "--val-fraction", "0.1", "-q"]


def _plain(path):
    """A session as an integrator opens it: onnxruntime's defaults, nothing of postproc."""
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("contract")
    assert main(["plan", "-n", "60", "--seed", "3", "-o", str(folder / "plan.csv"), "-q"]) == 0
    assert main(["measure", str(folder / "plan.csv"), "-o", str(folder / "m.csv"), "-q"]) == 0
    return folder / "m.csv"


@pytest.fixture(scope="module")
def trained(measured):
    """One freshly trained model per method of `postproc train --method` (tiny settings)."""
    out = {}
    for method in METHODS:
        path = measured.parent / f"{method}.onnx"
        assert main(["train", str(measured), "-o", str(path), "--method", method, *TINY]) == 0, method
        out[method] = path
    return out


def _feeds(model, poses, joints, rng):
    """Every input the model takes, as a caller with all of it would feed it."""
    n = len(poses)
    feed = {"pose": poses}
    if model.wants_previous:
        feed["previous_pose"] = np.roll(poses, 1, axis=0)
    if model.wants_joints:
        feed["joints"] = joints
    if model.wants_approach:
        feed["approach"] = np.sign(rng.normal(size=(n, 6))).astype(np.float32)
    if model.wants_tool:
        feed["tool"] = np.tile(np.float32([260.0, 15.0, 90.0, 0.0, 0.0, 5.0]), (n, 1))
    if model.wants_previous_joints:
        feed["previous_joints"] = np.roll(joints, 1, axis=0)
    return feed


def _check_contract(path, data):
    model = load_model(path)
    plain = _plain(path)
    required = [i.name for i in plain.get_inputs() if not i.type.startswith("optional")]
    assert required == ["pose"], f"{path.name}: required inputs {required}"
    assert set(model.defaults) <= set(OPTIONAL_INPUTS)
    assert [i.name for i in plain.get_inputs()] == ["pose", *model.defaults]  # (every one listed: contract 3)
    poses = data.poses[:24].astype(np.float32)
    joints = data.joints[:24].astype(np.float32)
    names = [o.name for o in plain.get_outputs()]

    def same(feed, **given):
        got = plain.run(["error"], feed)[0]
        want = model.predict(poses, **given)
        np.testing.assert_array_equal(got, want.astype(np.float32), err_msg=f"{path.name}: {sorted(feed)}")
        return got

    alone = same({"pose": poses})
    assert np.isfinite(alone).all()
    if "ik_joints" in names:  # the pose alone: the model's own branch, as predict without joints
        np.testing.assert_array_equal(plain.run(["ik_joints"], {"pose": poses})[0], model.predict(poses, with_joints=True)[1])
    if model.wants_joints:
        same({"pose": poses, "joints": joints}, joints=joints)
    feed = _feeds(model, poses, joints, np.random.default_rng(0))
    everything = same(feed, previous=feed.get("previous_pose"), joints=feed.get("joints"), tool=feed.get("tool"),
                      approach=feed.get("approach"), previous_joints=feed.get("previous_joints"))
    if len(feed) > 2:  # the inputs matter: the defaults are not what this caller fed
        assert np.abs(everything - alone).max() > 1e-3
    return model


@pytest.mark.slow
def test_every_method_runs_in_plain_onnxruntime_with_pose_alone(trained, measured):
    data = read_measurements(measured)
    for method, path in trained.items():
        model = _check_contract(path, data)
        assert model.metadata["postproc_contract"] == int(CONTRACT_VERSION)
        assert card_problems(model.metadata) == [], method


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_models_run_in_plain_onnxruntime_with_pose_alone(path, measured):
    model = _check_contract(path, read_measurements(measured))
    assert card_problems(model.metadata) == []


def test_the_example_script_runs_the_shipped_model(capsys, monkeypatch):
    """examples/onnxruntime_only.py: the integrator's example runs as written (onnxruntime + numpy)."""
    import runpy

    monkeypatch.setattr("sys.argv", ["onnxruntime_only.py", str(REPO / "models" / "default.onnx")])
    runpy.run_path(str(REPO / "examples" / "onnxruntime_only.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "command" in out and "mm" in out


def test_a_contract_1_file_is_read_and_upgraded(tmp_path):
    old = joint_model(tmp_path / "old.onnx", np.eye(3, 6) * 0.5, tool_gain=np.eye(3, 6) * 0.01, defaults=False)
    model = load_model(old)
    assert model.metadata["postproc_contract"] == 1 and model.defaults == ()
    with pytest.raises(Exception, match="joints"):  # an older graph needs every input
        _plain(old).run(None, {"pose": np.zeros((2, 6), np.float32)})
    new = tmp_path / "new.onnx"
    assert main(["model", "upgrade", str(old), "-o", str(new), "-q"]) == 0
    upgraded = load_model(new)
    assert upgraded.metadata["postproc_contract"] == 3 and set(upgraded.defaults) == {"joints", "tool"}
    rng = np.random.default_rng(1)
    poses = rng.uniform(-100, 100, (5, 6)).astype(np.float32)
    q, tool = rng.uniform(-90, 90, (5, 6)), rng.uniform(-50, 50, (5, 6))
    np.testing.assert_array_equal(model.predict(poses, joints=q, tool=tool), upgraded.predict(poses, joints=q, tool=tool))
    # the same nodes: onnx.load of both differs only in the defaults' initializers and nodes
    a, b = onnx.load(old), onnx.load(new)
    assert len(b.graph.node) - len(a.graph.node) == 7  # Shape, and per optional input Expand, OptionalHasElement, If
    again = onnx.load_from_string(upgrade(new.read_bytes()))  # (upgrading twice changes nothing more)
    assert len(again.graph.node) == len(b.graph.node) and len(again.graph.initializer) == len(b.graph.initializer)


def test_previous_pose_omitted_is_the_pose_itself(tmp_path):
    """The contract's "nothing known before it": an omitted previous_pose (or a NaN row) gives what
    feeding the pose itself gives, row by row."""
    path = affine_model(tmp_path / "prev.onnx", gain=np.diag([0.01, -0.02, 0.03]), previous_input=True)
    plain = _plain(path)
    poses = np.float32([[2000, 0, 900, 0, 90, 0], [2100, 50, 950, 0, 90, 0]])
    prev = poses.copy()
    prev[1, 0] = np.nan  # one row unknown, one row given
    a = plain.run(None, {"pose": poses})[0]
    b = plain.run(None, {"pose": poses, "previous_pose": poses})[0]
    c = plain.run(None, {"pose": poses, "previous_pose": prev})[0]
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)


def test_a_newer_contract_is_refused_naming_its_version(tmp_path):
    path = affine_model(tmp_path / "new.onnx")
    model = onnx.load(path)
    next(p for p in model.metadata_props if p.key == "postproc_contract").value = "4"
    onnx.save(model, path)
    with pytest.raises(PostprocError, match="version '4'.*newer than this postproc reads"):
        load_model(path)
    assert main(["model", "info", str(path)]) == 2


def test_the_card_schema_refuses_a_malformed_card(tmp_path):
    card = dict(load_model(REPO / "models" / "default.onnx").metadata)
    assert card_problems(card) == []
    broken = json.loads(json.dumps(card))
    broken["envelope"]["box"] = [0, 1, 2]
    broken["tool"]["frame"] = "300,0,75"
    del broken["name"]
    problems = card_problems(broken)
    assert len(problems) == 3 and any(p.startswith("envelope.box") for p in problems)
    assert any(p.startswith("tool.frame") for p in problems)


def test_model_info_prints_the_interface_and_the_card(capsys):
    assert main(["model", "info", str(REPO / "models" / "default.onnx")]) == 0
    out = capsys.readouterr().out
    assert "pose [N, 6]: required" in out
    assert "previous_pose [N, 6]: optional, omitted = the pose itself" in out
    assert "error_std [N, 1]" in out and "trained joint arcs" in out
    assert main(["model", "info", str(REPO / "models" / "default.onnx"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["name"] == "default"
