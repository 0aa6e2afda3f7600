"""ErrorModel: training lowers the error, every method and optimiser runs, ONNX round trip."""
from __future__ import annotations

import os

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch

from postproc.model.compensator import load_model
from postproc.core.diagnostics import PostprocError
from postproc.model.training import ErrorModel
from postproc.model.training.data import split_indices
from postproc.model.training.search import format_table, search_structure
from postproc.model.training.synthetic import synthetic_measurements

# small budgets: the point is behaviour, not the method's full figures (benchmarks/ has those)
SMALL = dict(generations=8, epochs=25)


@pytest.fixture(scope="module")
def data():
    poses, measured = synthetic_measurements(600, seed=11)
    errors = poses[:, :3] - measured
    train, val = split_indices(len(poses), 0.2, 0)
    return poses, errors, train, val


@pytest.fixture(scope="module")
def fitted(data):
    poses, errors, train, _ = data
    return ErrorModel(seed=0, **SMALL).fit(poses[train], errors[train])


def _val_ratio(model, data) -> float:
    poses, errors, _, val = data
    residual = np.linalg.norm(errors[val] - model.predict(poses[val]), axis=1)
    return residual.mean() / np.linalg.norm(errors[val], axis=1).mean()


def test_default_method_lowers_the_error_clearly(fitted, data):
    assert _val_ratio(fitted, data) < 0.5
    assert fitted.structure_.sizes == (6, 20, 10, 5, 3) and fitted.n_weights_ == 423
    assert len(fitted.history_) == SMALL["generations"] and np.all(np.diff(fitted.history_) <= 0)
    assert fitted.losses_[-1] < fitted.init_.fitness  # backprop improved on the searched start


@pytest.mark.parametrize("method", ["ga", "pso", "plain"])
def test_baseline_methods_train(method, data):
    poses, errors, train, _ = data
    model = ErrorModel(method=method, seed=1, **SMALL).fit(poses[train], errors[train])
    assert len(model.history_) == (0 if method == "plain" else SMALL["generations"])
    assert _val_ratio(model, data) < 0.8


@pytest.mark.parametrize("optimizer", ["gd", "momentum", "adam", "lbfgs", "lm"])
def test_every_optimizer_lowers_the_training_loss(optimizer, data):
    poses, errors, train, _ = data
    model = ErrorModel(hidden=(8, 4), optimizer=optimizer, generations=3, epochs=15, seed=2)
    model.fit(poses[train], errors[train])
    assert model.losses_[-1] < model.init_.fitness
    assert model.label.endswith(optimizer)


def test_same_seed_same_model_other_seed_other_model(data):
    poses, errors, train, _ = data
    kw = dict(hidden=(6, 4), generations=3, epochs=5)
    a = ErrorModel(seed=3, **kw).fit(poses[train], errors[train])
    b = ErrorModel(seed=3, **kw).fit(poses[train], errors[train])
    c = ErrorModel(seed=4, **kw).fit(poses[train], errors[train])
    assert np.array_equal(a.params_, b.params_) and not np.array_equal(a.params_, c.params_)


def test_too_few_points_and_unfitted_use(data):
    poses, errors, _, _ = data
    with pytest.raises(PostprocError) as info:
        ErrorModel().fit(poses[:100], errors[:100])  # 423 weights need 141 rows
    assert info.value.code == "P505"
    with pytest.raises(RuntimeError):
        ErrorModel().predict(poses)


def test_onnx_round_trip_matches_torch_and_meets_the_contract(fitted, data, tmp_path):
    poses, _, train, _ = data
    path = fitted.export_onnx(tmp_path / "m.onnx", name="synthetic", robot="KR500-sim", data_sha256="ab" * 32,
                              accuracy={"val_mean_mm": 0.1})
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    (onnx_out,) = session.run(["error"], {"pose": poses[train].astype(np.float32)})
    # torch in float64 on the same float32-rounded poses that the ONNX graph received
    torch_out = fitted.predict(poses[train].astype(np.float32).astype(np.float64))
    assert np.max(np.abs(onnx_out - torch_out)) <= 1e-5  # mm
    model = onnx.load(path)
    assert model.opset_import[0].version == 17
    assert model.graph.input[0].type.tensor_type.shape.dim[0].dim_param  # dynamic batch axis
    comp = load_model(path)
    assert comp.name == "synthetic" and comp.robot == "KR500-sim"
    assert comp.metadata["structure"] == "6-20-10-5-3" and comp.metadata["method"] == "GPSO-DNN + lm"
    assert comp.metadata["iterations"] == 2 and comp.metadata["postproc_contract"] == 3
    assert comp.metadata["data_sha256"] == "ab" * 32 and comp.metadata["accuracy"]["val_mean_mm"] == 0.1
    env = comp.envelope
    assert env is not None and not env.outside(poses[train]).any()
    assert np.allclose(comp.predict(poses[:5]), fitted.predict(poses[:5]), atol=1e-4)
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask  # readable like any file, not mkstemp's 0600


def test_float64_internal_export(fitted, data, tmp_path):
    poses, _, train, _ = data
    path = fitted.export_onnx(tmp_path / "m64.onnx", float64=True)
    comp = load_model(path)  # still float32 at the edges, as the contract wants
    p32 = poses[train].astype(np.float32).astype(np.float64)
    assert np.max(np.abs(comp.predict(p32) - fitted.predict(p32))) <= 1e-6


def test_export_creates_a_missing_folder_and_refuses_a_directory(fitted, tmp_path):
    # one output rule (postproc.core.outputs) for every subcommand: missing folders are created
    assert fitted.export_onnx(tmp_path / "absent" / "m.onnx").stat().st_size > 1000
    (tmp_path / "dir.onnx").mkdir()
    with pytest.raises(PostprocError) as info:
        fitted.export_onnx(tmp_path / "dir.onnx")
    assert info.value.code == "P110" and list((tmp_path / "dir.onnx").iterdir()) == []


def test_fixed_point_iterations_of_a_smooth_model(fitted, data):
    poses, _, train, _ = data
    k = fitted.fixed_point_iterations(poses[train])
    assert 1 <= k <= 4  # |dÊ/dP| ≪ 1 for a ~1 mm field over a 600 mm box: fast contraction


def test_structure_search_on_a_few_candidates(data):
    poses, errors, train, _ = data
    result = search_structure(poses[train], errors[train], structures=[(3,), (8, 8), (300, 300)],
                              keep=2, final_seeds=1, epochs=15, screen_epochs=30, seed=0)
    by_hidden = {c.hidden: c for c in result.candidates}
    assert "skipped" in by_hidden[(300, 300)].note  # too many weights for 384 rows
    finalists = [c for c in result.candidates if c.final_mm is not None]
    assert len(finalists) == 2 and result.best in {c.hidden for c in finalists}
    assert by_hidden[result.best].final_mm == min(c.final_mm for c in finalists)
    table = format_table(result)
    assert "← chosen" in table and "8,8" in table


def test_search_candidates_cover_the_methods_grid_families():
    from postproc.model.training.search import candidates

    c = candidates()
    assert len(c) == len(set(c)) == 150
    assert all((n,) * k in c for k in range(1, 7) for n in range(3, 17))  # every equal-width net
    assert (20, 10, 5) in c and (16, 8, 4) in c and (9, 4, 3) in c
    assert all(1 <= len(h) <= 6 and min(h) >= 3 for h in c if h != (20, 10, 5))


def test_torch_stays_single_threaded_only_during_fit(data):
    poses, errors, train, _ = data
    before = torch.get_num_threads()
    ErrorModel(hidden=(4,), generations=1, epochs=1).fit(poses[train], errors[train])
    assert torch.get_num_threads() == before


def test_prediction_depends_on_the_rotation_not_on_its_abc_triple(fitted, data, tmp_path):
    # compensate (like a controller) may hand the model (A+180, 180−B, C+180) for (A, B, C):
    # the same rotation, so it must get the same Ê — also in the exported graph
    from postproc.core import frames

    poses = data[0][:50]
    alt = poses.copy()
    alt[:, 3:6] = (poses[:, 3:6] + [180.0, 0.0, 180.0] + 180.0) % 360.0 - 180.0
    alt[:, 4] = 180.0 - poses[:, 4]
    assert np.allclose(frames.rotation_from_abc(alt[:, 3:6]), frames.rotation_from_abc(poses[:, 3:6]))
    assert np.allclose(fitted.predict(alt), fitted.predict(poses), atol=1e-9)
    comp = load_model(fitted.export_onnx(tmp_path / "m.onnx"))
    assert np.allclose(comp.predict(alt), comp.predict(poses), atol=2e-5)
    canonical = frames.matrix_to_frame(frames.frame_to_matrix(poses))  # B in [−90, 90]
    assert np.allclose(comp.predict(canonical), comp.predict(poses), atol=2e-5)


def test_envelope_of_a_tool_pointing_down_holds_its_poses_in_either_abc_triple(tmp_path):
    # the default robot's working attitude is B = 90: half of its poses have B > 90, which
    # compensate re-expresses as (A+180, 180−B, C+180); the model card's envelope must still hold them
    from postproc.core import frames

    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(1700, 2300, 400), rng.uniform(-600, 600, 400), rng.uniform(500, 1300, 400),
                             rng.uniform(-10, 10, 400), rng.uniform(80, 100, 400), rng.uniform(-10, 10, 400)])
    errors = 0.3 * np.sin(poses[:, :3] / 200.0)
    model = ErrorModel(hidden=(6,), generations=2, epochs=3).fit(poses, errors)
    comp = load_model(model.export_onnx(tmp_path / "down.onnx"))
    assert comp.metadata["envelope"]["attitude"] == pytest.approx([0, 90, 0], abs=0.5)
    canonical = frames.matrix_to_frame(frames.frame_to_matrix(poses))
    assert (canonical[:, 4] <= 90).all() and (np.abs(canonical[:, 3]) > 90).any()
    assert not comp.envelope.outside(canonical).any() and not comp.envelope.outside(poses).any()
    assert np.allclose(comp.predict(canonical), comp.predict(poses), atol=2e-5)
    tilted = canonical.copy()
    tilted[:, 4] -= 15.0  # 15° further from the working attitude than any training pose
    assert comp.envelope.outside(tilted).all()
