"""The model file as an outside caller opens it (issue 34, item 5): a plain
``onnxruntime.InferenceSession(model)`` prints nothing at the default log level, lists every
optional input with the standard API (``get_inputs()``; the C API's input count and types), runs
with ``pose`` alone, and equals ``Compensator.predict`` when fed everything; a model's ``joints``
input decides the arm configuration, and ``model info`` / ``compensate -v`` say so.

Each plain session runs in a subprocess of its own, its stderr (onnxruntime's C++ log) captured:
a file of contract 2 (each default an initializer of the input's name) makes onnxruntime warn
there and hides its optional inputs from ``get_inputs()`` — the contrast the tests check too."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import onnx
import pytest
from helpers import REPO

from postproc.cli import main
from postproc.model.compensator import load_model
from postproc.model.contract import CONTRACT_VERSION, OPTIONAL_INPUTS, upgrade
from postproc.testing.models import affine_model, as_contract_2, joint_model

SHIPPED = sorted((REPO / "models").glob("*.onnx"))
TINY = ["--hidden", "4", "--epochs", "5", "--val-fraction", "0.1", "-q"]

# What an integrator's Python does with the file: onnxruntime's defaults, nothing of postproc.
# It prints the inputs get_inputs() lists, and the error for `pose` alone and for every input
# it finds there fed from the arrays given (the test's), as JSON on stdout.
PLAIN = r"""
import json, sys
import numpy as np
import onnxruntime as ort
path, given = sys.argv[1], np.load(sys.argv[2])
session = ort.InferenceSession(path)
inputs = [(i.name, i.type, i.shape) for i in session.get_inputs()]
pose = given["pose"]
alone = session.run(["error"], {"pose": pose})[0]
found = {name: given[name] for name, _, _ in inputs if name in given.files}
fed = session.run(["error"], found)[0]
json.dump({"inputs": inputs, "fed": sorted(found), "alone": alone.tolist(), "everything": fed.tolist(),
           "overridable": [i.name for i in session.get_overridable_initializers()]}, sys.stdout)
"""

# The same through onnxruntime's C API (what the C++ and C# bindings wrap), with ctypes on the
# wheel's libonnxruntime: the OrtApi table by its indices, which ONNX Runtime only ever appends
# to. An environment at ORT_LOGGING_LEVEL_WARNING (the level the C++ API's Ort::Env defaults to).
C_API = r"""
import ctypes as C, glob, json, os, sys
import numpy as np
import onnxruntime
found = glob.glob(os.path.join(os.path.dirname(onnxruntime.__file__), "capi", "libonnxruntime.so*"))
if not found:
    print(json.dumps({"skip": "no libonnxruntime in this onnxruntime wheel"}))
    sys.exit(0)
lib = C.CDLL(found[0])
lib.OrtGetApiBase.restype = C.POINTER(C.c_void_p * 2)
get_api = C.CFUNCTYPE(C.c_void_p, C.c_uint32)(lib.OrtGetApiBase().contents[0])
api = C.cast(get_api(16), C.POINTER(C.c_void_p * 70)).contents
P = C.c_void_p
def call(index, *types):
    return C.CFUNCTYPE(P, *types)(api[index])
message = C.CFUNCTYPE(C.c_char_p, P)(api[2])
def ok(status):
    if status:
        raise RuntimeError(message(status).decode())
path, given = sys.argv[1], np.load(sys.argv[2])
env, options, session, memory = P(), P(), P(), P()
ok(call(3, C.c_int, C.c_char_p, C.POINTER(P))(2, b"integrator", C.byref(env)))          # CreateEnv, WARNING
ok(call(10, C.POINTER(P))(C.byref(options)))                                             # CreateSessionOptions
data = open(path, "rb").read()
ok(call(8, P, C.c_char_p, C.c_size_t, P, C.POINTER(P))(env, data, len(data), options, C.byref(session)))
count = C.c_size_t()
ok(call(30, P, C.POINTER(C.c_size_t))(session, C.byref(count)))                          # SessionGetInputCount
kinds = []
for i in range(count.value):
    info, kind = P(), C.c_int()
    ok(call(33, P, C.c_size_t, C.POINTER(P))(session, i, C.byref(info)))                # SessionGetInputTypeInfo
    ok(call(56, P, C.POINTER(C.c_int))(info, C.byref(kind)))                             # GetOnnxTypeFromTypeInfo
    kinds.append(kind.value)                                                             # 1 tensor, 6 optional
ok(call(69, C.c_int, C.c_int, C.POINTER(P))(1, 0, C.byref(memory)))                      # CreateCpuMemoryInfo
def run(feed):
    keep = [np.ascontiguousarray(v, np.float32) for v in feed.values()]
    values = []
    for a in keep:
        value, shape = P(), (C.c_int64 * 2)(*a.shape)
        ok(call(49, P, P, C.c_size_t, P, C.c_size_t, C.c_int, C.POINTER(P))(            # CreateTensorWithDataAsOrtValue
            memory, a.ctypes.data, a.nbytes, shape, 2, 1, C.byref(value)))
        values.append(value)
    names = (C.c_char_p * len(feed))(*[k.encode() for k in feed])
    out, out_name = (P * 1)(), (C.c_char_p * 1)(b"error")
    ok(call(9, P, P, P, P, C.c_size_t, P, C.c_size_t, P)(                                # Run
        session, None, names, (P * len(values))(*values), len(values), out_name, 1, out))
    data = P()
    ok(call(51, P, C.POINTER(P))(out[0], C.byref(data)))                                 # GetTensorMutableData
    return np.ctypeslib.as_array(C.cast(data, C.POINTER(C.c_float)), (len(keep[0]), 3)).tolist()
print(json.dumps({"kinds": kinds, "alone": run({"pose": given["pose"]}),
                  "joints": run({"pose": given["pose"], "joints": given["joints"]})}))
"""


def _outside(script: str, path, tmp_path, **arrays) -> tuple[dict, str]:
    """Run ``script`` on the model ``path`` with ``arrays`` (float32) in a process of its own:
    (its JSON result, its stderr)."""
    feeds = tmp_path / "feeds.npz"
    np.savez(feeds, **{k: np.asarray(v, np.float32) for k, v in arrays.items()})
    done = subprocess.run([sys.executable, "-c", script, str(path), str(feeds)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout), done.stderr


def _everything(model, poses: np.ndarray, rng) -> dict[str, np.ndarray]:
    """Every input a caller with all of it feeds: the joints on the model's own branch, other
    approach signs, another tool (what the defaults are not)."""
    n = len(poses)
    _, q = model.predict(poses, with_joints=True) if model.has_joints else (None, rng.uniform(-90, 90, (n, 6)))
    return {"pose": poses, "previous_pose": np.roll(poses, 1, axis=0), "joints": q,
            "approach": np.sign(rng.normal(size=(n, 6))), "tool": np.tile([260.0, 15.0, 90.0, 0.0, 0.0, 5.0], (n, 1)),
            "previous_joints": np.roll(q, 1, axis=0)}


def _poses(model, n: int = 24, seed: int = 0) -> np.ndarray:
    """Poses over the model's envelope (its card's box and attitude): the correction varies."""
    rng = np.random.default_rng(seed)
    env = model.envelope
    box = env.box.reshape(3, 2)
    xyz = rng.uniform(box[:, 0], box[:, 1], (n, 3))
    abc = env.attitude + rng.uniform(-0.5, 0.5, (n, 3)) * env.range
    return np.hstack([xyz, abc]).astype(np.float32).astype(float)


def _check_plain(path, tmp_path) -> dict:
    """The item's description, for the model file ``path``: no warning at the default log level,
    every optional input listed by ``get_inputs()``, ``pose`` alone runs, and fed every input
    it lists equals ``Compensator.predict`` fed the same."""
    model = load_model(path)
    poses = _poses(model)
    given = _everything(model, poses, np.random.default_rng(1))
    result, stderr = _outside(PLAIN, path, tmp_path, **given)
    assert stderr == "", f"{path.name}: onnxruntime said at the default log level:\n{stderr}"
    types = {name: kind for name, kind, _ in result["inputs"]}
    taken = {name for name, wanted in (("previous_pose", model.wants_previous), ("joints", model.wants_joints),
                                       ("tool", model.wants_tool), ("approach", model.wants_approach),
                                       ("previous_joints", model.wants_previous_joints)) if wanted}
    assert types.pop("pose") == "tensor(float)"
    assert set(types) == taken and taken <= set(OPTIONAL_INPUTS), (path.name, types)
    assert set(types.values()) <= {"optional(tensor(float))"}, types  # (each marked optional by its type)
    assert all(shape == ["N", 6] for _, _, shape in result["inputs"]), result["inputs"]
    assert result["overridable"] == [] and set(result["fed"]) == taken | {"pose"}
    alone, everything = np.asarray(result["alone"], np.float32), np.asarray(result["everything"], np.float32)
    np.testing.assert_array_equal(alone, model.predict(poses).astype(np.float32))
    fed = {k: given[k] for k in taken}
    want = model.predict(poses, fed.get("previous_pose"), joints=fed.get("joints"), tool=fed.get("tool"),
                         approach=fed.get("approach"), previous_joints=fed.get("previous_joints"))
    np.testing.assert_array_equal(everything, want.astype(np.float32))
    assert np.isfinite(everything).all() and np.ptp(everything, axis=0).max() > 1e-3  # (a correction that varies)
    if taken - {"joints", "previous_joints"}:  # the inputs matter: the defaults are not what this caller fed
        differ = np.abs(everything - alone)  # (NaN where the model gives NaN without them: joint_model's sin(NaN))
        assert np.isnan(differ).any() or differ.max() > 1e-3
    return result


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_a_shipped_model_opens_quietly_and_lists_every_optional_input(path, tmp_path):
    _check_plain(path, tmp_path)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A model `postproc train` exports now (the hybrid method, tiny settings, on a small
    simulated measurement)."""
    folder = tmp_path_factory.mktemp("quiet")
    assert main(["plan", "-n", "60", "--seed", "3", "-o", str(folder / "plan.csv"), "-q"]) == 0
    assert main(["measure", str(folder / "plan.csv"), "-o", str(folder / "m.csv"), "-q"]) == 0
    path = folder / "hybrid.onnx"
    assert main(["train", str(folder / "m.csv"), "-o", str(path), "--method", "hybrid", *TINY]) == 0
    return path


def test_a_freshly_exported_model_opens_quietly_and_lists_every_optional_input(exported, tmp_path):
    result = _check_plain(exported, tmp_path)
    assert "joints" in dict((n, t) for n, t, _ in result["inputs"])  # (a hybrid model takes the configuration)
    assert load_model(exported).metadata["postproc_contract"] == int(CONTRACT_VERSION)


@pytest.mark.parametrize("kind", ["affine", "previous", "joints"])
def test_a_small_model_opens_quietly_with_its_own_inputs(kind, tmp_path):
    """postproc.testing's graphs go through the same with_defaults: pose-only, previous_pose, and
    joints + tool (each with a correction that varies over space)."""
    path = tmp_path / f"{kind}.onnx"
    if kind == "joints":
        joint_model(path, np.eye(3, 6) * 0.8, tool_gain=np.eye(3, 6) * 0.01,
                    envelope={"box": [1700, 2300, -600, 600, 500, 1300], "attitude": [0, 90, 0], "range": 10})
    else:
        affine_model(path, gain=np.diag([0.01, -0.02, 0.03]), previous_gain=0.05 if kind == "previous" else None)
    _check_plain(path, tmp_path)


def test_a_contract_2_file_warns_and_hides_its_inputs_and_upgrade_makes_it_quiet(exported, tmp_path):
    """The contrast the checks above rest on: the same graph as contract 2 wrote it makes
    onnxruntime warn at each session and list only `pose`; `postproc model upgrade` gives the
    quiet form with the same numbers."""
    old = as_contract_2(exported, tmp_path / "old.onnx")
    model = load_model(old)
    assert model.metadata["postproc_contract"] == 2 and "joints" in model.defaults
    poses = _poses(model)
    result, stderr = _outside(PLAIN, old, tmp_path, **_everything(model, poses, np.random.default_rng(1)))
    assert "appears in graph inputs and will not be treated as constant" in stderr
    assert [name for name, _, _ in result["inputs"]] == ["pose"] and "joints" in result["overridable"]
    new = tmp_path / "new.onnx"
    assert main(["model", "upgrade", str(old), "-o", str(new), "-q"]) == 0
    _check_plain(new, tmp_path)
    again = load_model(new)
    given = _everything(model, poses, np.random.default_rng(2))
    feed = {k: given[k] for k in model.defaults}
    np.testing.assert_array_equal(model.predict(poses, feed.get("previous_pose"), joints=feed.get("joints"),
                                                tool=feed.get("tool"), approach=feed.get("approach"),
                                                previous_joints=feed.get("previous_joints")),
                                  again.predict(poses, feed.get("previous_pose"), joints=feed.get("joints"),
                                                tool=feed.get("tool"), approach=feed.get("approach"),
                                                previous_joints=feed.get("previous_joints")))
    graph, upgraded = onnx.load(exported), onnx.load_from_string(upgrade(old.read_bytes()))
    assert len(upgraded.graph.node) == len(graph.graph.node)  # 2 → 3: the nodes of a freshly exported graph


def _flipped(q: np.ndarray) -> np.ndarray:
    """The same TCP pose in the other wrist: A4 + 180°, A5 negated, A6 + 180° (wrapped)."""
    out = q.copy()
    out[:, 3] = (q[:, 3] + 360.0) % 360.0 - 180.0
    out[:, 4] = -q[:, 4]
    out[:, 5] = (q[:, 5] + 360.0) % 360.0 - 180.0
    return out


def test_joints_decides_the_configuration_in_a_plain_session(tmp_path):
    """What `model info` says of a model with `joints`: fed the joint angles of the other wrist,
    the shipped model's correction is another arm's (mm apart); left out it is the branch the
    model identified — what a caller who never found `joints` got."""
    path = REPO / "models" / "default.onnx"
    model = load_model(path)
    poses = _poses(model, n=12, seed=4)
    poses[:, 4] = 60.0  # (A5 well away from 0: the two wrists are two configurations)
    _, own = model.predict(poses, with_joints=True)
    other = _flipped(own)
    assert np.abs(other - own)[:, 3:].max() > 90  # (the other wrist: another configuration of the same poses)
    result, stderr = _outside(PLAIN, path, tmp_path, pose=poses, joints=other)
    assert stderr == ""
    alone, flipped = np.asarray(result["alone"]), np.asarray(result["everything"])
    np.testing.assert_array_equal(alone, model.predict(poses, joints=np.full((len(poses), 6), np.nan)).astype(np.float32))
    np.testing.assert_array_equal(flipped, model.predict(poses, joints=other).astype(np.float32))
    assert np.linalg.norm(flipped - alone, axis=1).max() > 0.5  # the configuration decides the correction


def test_the_c_api_lists_the_optional_inputs_and_runs_without_them(tmp_path):
    """A C/C++/C# caller (the C API the bindings wrap): no warning with a WARNING-level
    environment, six inputs of which five are ONNX_TYPE_OPTIONAL, `pose` alone runs, and a plain
    float tensor fed as `joints` is taken — the numbers of Compensator.predict."""
    path = REPO / "models" / "default.onnx"
    model = load_model(path)
    poses = _poses(model, n=6, seed=5)
    poses[:, 4] = 60.0
    _, own = model.predict(poses, with_joints=True)
    result, stderr = _outside(C_API, path, tmp_path, pose=poses, joints=_flipped(own))
    if "skip" in result:
        pytest.skip(result["skip"])
    assert stderr == ""
    assert result["kinds"] == [1, 6, 6, 6, 6, 6]  # ONNX_TYPE_TENSOR, then ONNX_TYPE_OPTIONAL × 5
    np.testing.assert_array_equal(np.float32(result["alone"]), model.predict(poses).astype(np.float32))
    np.testing.assert_array_equal(np.float32(result["joints"]),
                                  model.predict(poses, joints=_flipped(own)).astype(np.float32))
    assert np.abs(np.float32(result["joints"]) - np.float32(result["alone"])).max() > 0.1


def test_model_info_says_that_joints_decides_the_configuration(capsys, tmp_path):
    assert main(["model", "info", str(REPO / "models" / "default.onnx")]) == 0
    out = capsys.readouterr().out
    assert "joints [N, 6]: optional" in out
    assert "the input joints decides the arm configuration" in out
    assert "on the branch it identified from its training data (kuka branch [+1, -1, +1])" in out
    affine = affine_model(tmp_path / "pose_only.onnx", gain=np.diag([0.01, -0.02, 0.03]))
    assert main(["model", "info", str(affine)]) == 0
    assert "decides the arm configuration" not in capsys.readouterr().out  # (a model without joints)
    old = as_contract_2(REPO / "models" / "default.onnx", tmp_path / "old.onnx")
    assert main(["model", "info", str(old)]) == 0
    out = capsys.readouterr().out
    assert "contract: 2" in out and "get_overridable_initializers(), not get_inputs()" in out


def test_compensate_v_says_that_joints_decides_the_configuration_and_what_it_feeds(capsys, tmp_path):
    src = tmp_path / "p.src"
    src.write_text("DEF p()\n  PTP {X 2015.074,Y -315.396,Z 1235.422,A -60.2269,B 70.0575,C -75.3419,S 2,T 2}\n"
                   "  LIN {X 2005.124,Y -415.386,Z 1230.742,A -69.9472,B 68.4106,C -82.2409}\nEND\n")
    common = ["--base", "0", "--tool", "300,0,75,0,0,0"]
    assert main(["compensate", str(src), "-o", str(tmp_path / "v.src"), *common, "-v"]) == 0
    err = capsys.readouterr().err
    assert "model default: the input joints decides the arm configuration" in err
    assert "compensate feeds it each target's joint angles" in err and "the configuration its S/T state" in err
    assert main(["compensate", str(src), "-o", str(tmp_path / "q.src"), *common]) == 0
    assert "decides the arm configuration" not in capsys.readouterr().err  # (said with -v only)
    affine = affine_model(tmp_path / "pose_only.onnx", gain=np.diag([0.01, -0.02, 0.03]))
    poses = tmp_path / "p.csv"
    poses.write_text("x,y,z,a,b,c\n2000,0,900,0,90,0\n2100,50,950,0,90,0\n")
    assert main(["compensate", str(poses), "-o", str(tmp_path / "o.csv"), "--model", str(affine), "-v"]) == 0
    assert "decides the arm configuration" not in capsys.readouterr().err


def test_the_example_script_runs_quietly_and_feeds_what_get_inputs_lists(tmp_path):
    """examples/onnxruntime_only.py as an integrator runs it: no warning on stderr, and it
    finds the optional inputs (joints among them) with get_inputs()."""
    done = subprocess.run([sys.executable, str(REPO / "examples" / "onnxruntime_only.py"),
                           str(REPO / "models" / "default.onnx")], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert "command" in done.stdout and "optional inputs: previous_pose, joints, approach, tool, previous_joints" in done.stdout
    assert "joints decides the arm configuration" in done.stdout


def test_postproc_s_own_large_runs_use_a_graph_without_the_if(tmp_path):
    """Compensator's cut graph takes the optional inputs as plain tensors (it feeds each): no If
    runs there, and its numbers are the file's."""
    from postproc.model import session as ps

    data = (REPO / "models" / "default.onnx").read_bytes()
    whole = onnx.load_from_string(data)
    assert sum(n.op_type == "If" for n in whole.graph.node) == 5
    cut = onnx.load_from_string(ps._cut(data, ("error", "ik_joints")))
    assert not [n for n in cut.graph.node if n.op_type in ("If", "OptionalHasElement")]
    assert all(i.type.HasField("tensor_type") for i in cut.graph.input)
    model = load_model(REPO / "models" / "default.onnx")
    rng = np.random.default_rng(3)
    poses = np.repeat(_poses(model, n=50, seed=6), 200, axis=0) + rng.normal(0, 5, (10000, 6)) * [1, 1, 1, 0, 0, 0]
    q = _everything(model, poses, rng)["joints"]
    model.cut_rows = 10**9
    want = model.predict(poses, np.roll(poses, 1, axis=0), joints=q, with_joints=True)
    model.cut_rows = 1000
    got = model.predict(poses, np.roll(poses, 1, axis=0), joints=q, with_joints=True)
    assert model._cut and all(s is not model.session for s in model._cut.values())
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
