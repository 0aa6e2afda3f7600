"""A model whose frame is not the controller's base (``controller_base`` in the robot
description and the model card): a UR10 description in ROS's base_link, where the UR
controller's base — the frame of a URScript program's p[...] poses — is turned 180° about Z.

A program's targets go through it into the model's frame and their corrections come back;
a pose list's rows are in the model's frame already. The model's correction varies over
space, so evaluating it at the program's numbers instead (the bug this guards against:
(−x, −y) in base_link) gives other commands.
"""
import numpy as np
import pytest

from postproc.core import frames
from postproc.compensation.api import compensate_text
from postproc.programs.io import parse_program_text
from postproc.model.compensator import load_model
from postproc.robot.description import load_description
from postproc.testing.models import affine_model
from postproc.model.training.card import arm_metadata

from helpers import REPO

TURN = frames.frame_to_matrix(np.array([0.0, 0.0, 0.0, 180.0, 0.0, 0.0]))
GAIN = 0.4 * np.array([[0.004, -0.002, 0.001], [0.003, 0.002, -0.004], [-0.001, 0.005, 0.003]])
CENTRE = (700.0, 300.0, 600.0)
REACH = {"center": [0.0, 0.0, 127.3], "radius_min": 0.0, "radius_max": 1500.0}


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("controller_base")
    meta = arm_metadata(load_description(REPO / "models" / "ur10.toml"))
    assert meta["controller_base"] == [0.0, 0.0, 0.0, 180.0, 0.0, 0.0]
    common = dict(offset=(0.2, -0.1, 0.3), gain=GAIN, centre=CENTRE, robot="UR10", tool=meta["tool"],
                  envelope=None, reach=REACH)
    turned = load_model(affine_model(d / "ur.onnx", controller_base=meta["controller_base"], **common))
    plain = load_model(affine_model(d / "plain.onnx", **common))
    return turned, plain


def _script(positions_m: np.ndarray, tool) -> str:
    """movel to each position (m), the TCP ``tool`` (X,Y,Z mm, A,B,C deg) set first."""
    turn = frames.rotvec_from_rotation(frames.rotation_from_abc(np.asarray(tool[3:], float)))
    values = ", ".join(f"{v:.9f}" for v in np.r_[np.asarray(tool[:3], float) / 1000.0, turn])
    lines = ["def cell():", f"  set_tcp(p[{values}])"]
    for k, p in enumerate(positions_m):
        pose = ", ".join(f"{v:.6f}" for v in p) + ", 0.0, 3.1416, 0.0"
        lines += [f"  global wp{k} = p[{pose}]", f"  movel(wp{k}, a=1.2, v=0.25)"] if k % 2 else \
                 [f"  movel(p[{pose}], a=1.2, v=0.25)"]
    return "\n".join(lines + ["end", ""])


def test_urscript_targets_are_taken_into_the_models_frame(models):
    turned, plain = models
    rng = np.random.default_rng(3)
    model_frame = rng.uniform([500, 100, 300], [900, 500, 900], (12, 3))  # base_link, mm
    program = frames.transform_points(np.linalg.inv(TURN), model_frame)  # the controller's base: (−x, −y, z)
    text = _script(program / 1000.0, turned.tool["frame"])
    assert turned.controller_base.round(12).tolist() == TURN.round(12).tolist()

    out, report = compensate_text(text, turned, name="cell.script")
    assert report.compensated == 12 and report.left == 0
    got = parse_program_text(out, "cell.script").targets.poses[:, :3]
    # the fixed point in the model's frame, c = P + Ê(c), mapped back into the controller's base
    c = model_frame.copy()
    for _ in range(30):
        c = model_frame + (np.array([0.2, -0.1, 0.3]) + (c - CENTRE) @ GAIN.T)
    expected = frames.transform_points(np.linalg.inv(TURN), c)
    assert np.abs(got - expected).max() < 2e-3  # mm (µm written as metres with 6 decimals)
    # a model without controller_base evaluates the program's numbers as base_link ones: other commands
    wrong, _ = compensate_text(text, plain, name="cell.script")
    off = np.abs(parse_program_text(wrong, "cell.script").targets.poses[:, :3] - expected).max()
    assert off > 1.0


def _rows(frame_line: str | None, rows: np.ndarray) -> str:
    head = ([frame_line] if frame_line else []) + ["x,y,z,a,b,c"]
    return "\n".join(head) + "\n" + "".join(",".join(f"{v:.6f}" for v in r) + "\n" for r in rows)


def test_a_pose_list_states_its_frame_where_the_model_is_not_in_the_controllers_base(models):
    """A pose list's rows could be in either frame: unstated, with a model whose frame is not the
    controller's base, every row is left as written (P218); '# frame: model' takes them as the
    model's, '# frame: controller' through controller_base (as a URScript program's); a model in
    the controller's base needs no statement."""
    from postproc.core.diagnostics import PostprocError

    turned, plain = models
    rng = np.random.default_rng(4)
    model_frame = rng.uniform([500, 100, 300], [900, 500, 900], (5, 3))
    rows = np.c_[model_frame, np.zeros((5, 2)), np.full(5, 180.0)]
    out, report = compensate_text(_rows(None, rows), turned, name="targets.csv")
    assert report.compensated == 0 and report.left_codes == {"P218": 5}
    assert [d.code for d in report.warnings] == ["P218"] and report.warnings[0].line == 2
    assert out == _rows(None, rows)  # (nothing changed: written as it was)

    as_model, report = compensate_text(_rows("# frame: model", rows), turned, name="targets.csv")
    assert report.compensated == 5 and not report.warnings
    unstated_plain, _ = compensate_text(_rows(None, rows), plain, name="targets.csv")
    body = lambda text: text.split("x,y,z,a,b,c\n", 1)[1]  # noqa: E731
    assert body(as_model) == body(unstated_plain)

    controller = frames.transform_points(np.linalg.inv(TURN), model_frame)  # the same points, the controller's base
    as_controller, report = compensate_text(_rows("# frame: controller", np.c_[controller, rows[:, 3:]]), turned,
                                            name="targets.csv")
    assert report.compensated == 5
    got = parse_program_text(as_controller, "targets.csv").targets.poses[:, :3]
    c = model_frame.copy()
    for _ in range(30):
        c = model_frame + (np.array([0.2, -0.1, 0.3]) + (c - CENTRE) @ GAIN.T)
    assert np.abs(got - frames.transform_points(np.linalg.inv(TURN), c)).max() < 2e-3
    with pytest.raises(PostprocError) as bad:
        compensate_text(_rows("# frame: tracker", rows), turned, name="targets.csv")
    assert bad.value.code == "P101" and bad.value.line == 1
