"""Sessions from the cached optimised graph (postproc.model.session) give the outputs of a fresh
session bit for bit, and a cache file that is not the one written for this model is not used."""
import numpy as np
import pytest

from postproc.model import session as ps
from postproc.core.resources import model_path
from postproc.robot.arm import Robot


def _feeds(sess, n=500, seed=0):
    robot = Robot()
    rng = np.random.default_rng(seed)
    q = rng.uniform([-150, -120, 10, -180, -100, -300], [150, -30, 140, 180, 100, 300], (n, 6))
    poses = robot.fk(q).astype(np.float32)  # a spread of the workspace: the correction varies
    feeds = {}
    for i in (*sess.get_inputs(), *sess.get_overridable_initializers()):  # (the optional inputs too)
        feeds[i.name] = {"pose": poses, "joints": q.astype(np.float32)}.get(
            i.name, np.roll(poses, 1, axis=0) if "previous" in i.name else np.zeros((n, 6), np.float32))
    return feeds


def _run(sess, feeds):
    return [np.asarray(o) for o in sess.run(None, feeds)]


@pytest.fixture()
def model_bytes():
    return model_path().read_bytes()


def test_the_cached_graph_gives_the_same_outputs_bit_for_bit(tmp_path, monkeypatch, model_bytes):
    monkeypatch.setenv("POSTPROC_CACHE_DIR", "")
    fresh = ps.inference_session(model_bytes)
    feeds = _feeds(fresh)
    want = _run(fresh, feeds)
    assert np.ptp(want[0], axis=0).max() > 0.01  # the correction varies over the workspace
    monkeypatch.setenv("POSTPROC_CACHE_DIR", str(tmp_path))
    first = ps.inference_session(model_bytes)  # writes the cache
    assert len(list(tmp_path.glob("*.onnx"))) == 1 and len(list(tmp_path.glob("*.sha256"))) == 1
    assert not list(tmp_path.glob(".*"))  # no temporary left
    cached = ps.inference_session(model_bytes)  # reads it
    for sess in (first, cached):
        for got, exp in zip(_run(sess, feeds), want):
            np.testing.assert_array_equal(got, exp)


def test_a_changed_or_foreign_cache_file_is_not_used(tmp_path, monkeypatch, model_bytes):
    monkeypatch.setenv("POSTPROC_CACHE_DIR", str(tmp_path))
    want = _run(ps.inference_session(model_bytes), _feeds(ps.inference_session(model_bytes)))
    cached = next(tmp_path.glob("*.onnx"))
    for bad in (b"not a graph", cached.read_bytes()[:-100]):  # garbage, a partial write
        cached.write_bytes(bad)
        sess = ps.inference_session(model_bytes)
        for got, exp in zip(_run(sess, _feeds(sess)), want):
            np.testing.assert_array_equal(got, exp)
        assert cached.read_bytes() != bad  # made again



def test_a_changed_model_does_not_use_the_graph_cached_for_the_old_one(tmp_path, monkeypatch, model_bytes):
    onnx = pytest.importorskip("onnx")
    monkeypatch.setenv("POSTPROC_CACHE_DIR", str(tmp_path))
    ps.inference_session(model_bytes)
    model = onnx.load_from_string(model_bytes)
    out = model.graph.output[0].name
    node = onnx.helper.make_node("Mul", [out, "two"], [out + "_x2"])  # another model: the correction doubled
    model.graph.node.append(node)
    model.graph.initializer.append(onnx.numpy_helper.from_array(np.array(2.0, np.float32), "two"))
    model.graph.output[0].name = out + "_x2"
    changed = model.SerializeToString()
    sess = ps.inference_session(changed)
    assert len(list(tmp_path.glob("*.onnx"))) == 2  # its own cache entry
    base = ps.inference_session(model_bytes)
    feeds = _feeds(base)
    np.testing.assert_array_equal(_run(sess, feeds)[0], 2.0 * _run(base, feeds)[0])


def test_no_cache_dir_or_an_unwritable_one_still_gives_a_session(tmp_path, monkeypatch, model_bytes):
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    for where in ("", str(blocked / "cache")):
        monkeypatch.setenv("POSTPROC_CACHE_DIR", where)
        sess = ps.inference_session(model_bytes)
        assert _run(sess, _feeds(sess, n=5))[0].shape[0] == 5


@pytest.mark.parametrize("cache", [False, True])
def test_a_graph_cut_to_some_outputs_gives_their_numbers_bit_for_bit(tmp_path, monkeypatch, model_bytes, cache):
    """onnxruntime runs every node whichever outputs are asked: the cut graph keeps only what
    ``error`` and ``ik_joints`` need (no error_std Jacobian) and gives the same numbers; cached
    apart from the whole graph, read back on the next use."""
    monkeypatch.setenv("POSTPROC_CACHE_DIR", str(tmp_path) if cache else "")
    whole = ps.inference_session(model_bytes)
    names = ("error", "ik_joints")
    cut = ps.inference_session(model_bytes, names)
    assert [o.name for o in cut.get_outputs()] == list(names)
    assert ({i.name for i in (*cut.get_inputs(), *cut.get_overridable_initializers())}
            == {i.name for i in (*whole.get_inputs(), *whole.get_overridable_initializers())})
    feeds = _feeds(whole)
    want = whole.run(list(names), feeds)
    for got, expected in zip(cut.run(list(names), feeds), want):
        assert np.array_equal(got, expected)
    if cache:
        assert len(list(tmp_path.glob("*.onnx"))) == 2  # the whole graph and the cut one
        again = ps.inference_session(model_bytes, names)
        assert all(np.array_equal(g, w) for g, w in zip(again.run(list(names), feeds), want))
    assert ps.inference_session(model_bytes, ("error", "no such output")) is None


def test_a_large_predict_runs_the_cut_graph_with_the_same_numbers():
    from postproc.model.compensator import load_model

    model = load_model()
    feeds = _feeds(model.session, n=3000, seed=2)
    poses, q = feeds["pose"].astype(np.float64), feeds["joints"].astype(np.float64)
    model.cut_rows = 10**9
    want = model.predict(poses, np.roll(poses, 1, axis=0), joints=q, with_joints=True)
    model.cut_rows = 1000
    got = model.predict(poses, np.roll(poses, 1, axis=0), joints=q, with_joints=True)
    assert all(np.array_equal(g, w) for g, w in zip(got, want))
    (cut,) = model._cut.values()
    assert cut is not model.session and len(cut.get_outputs()) == 2
    with_std = model.predict(poses, np.roll(poses, 1, axis=0), joints=q, with_joints=True, std=True)
    assert np.array_equal(with_std[0], want[0]) and len(model._cut) == 2
