import numpy as np
import pytest

from postproc.core import frames


def rz(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def ry(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rx(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def test_rotation_is_z_then_new_y_then_new_x():
    abc = np.array([30.0, -20.0, 75.0])
    assert np.allclose(frames.rotation_from_abc(abc), rz(30) @ ry(-20) @ rx(75))


def test_hand_computed_base_a90_moves_x_onto_y():
    # base at (100, 200, 300) turned 90° about Z: a point 10 mm along the base's X
    # lies 10 mm along the robot's Y
    base = frames.frame_to_matrix([100, 200, 300, 90, 0, 0])
    assert np.allclose(frames.transform_points(base, [10, 0, 0]), [100, 210, 300])


def test_hand_computed_b90_points_x_down():
    tool = frames.frame_to_matrix([0, 0, 0, 0, 90, 0])
    assert np.allclose(frames.rotate_vectors(tool, [1, 0, 0]), [0, 0, -1])


def test_composition_is_krl_colon():
    # F1:F2 = F2 expressed in F1
    f1, f2 = [500, 0, 0, 90, 0, 0], [0, 100, 0, 0, 0, 0]
    t = frames.compose(frames.frame_to_matrix(f1), frames.frame_to_matrix(f2))
    # F2's origin is 100 mm along F1's Y, which is the robot's −X
    assert np.allclose(frames.matrix_to_frame(t), [400, 0, 0, 90, 0, 0])


@pytest.mark.parametrize("abc", [[10, 20, 30], [-170, 80, 5], [179, -45, -179], [0, 0, 0]])
def test_abc_round_trip(abc):
    assert np.allclose(frames.abc_from_rotation(frames.rotation_from_abc(abc)), abc)


def test_gimbal_lock_keeps_the_rotation():
    r = frames.rotation_from_abc([30, 90, 10])
    assert np.allclose(frames.rotation_from_abc(frames.abc_from_rotation(r)), r)


def test_inverse_and_vectorised():
    rng = np.random.default_rng(1)
    f = np.c_[rng.uniform(-1000, 1000, (50, 3)), rng.uniform(-179, 179, (50, 3))]
    t = frames.frame_to_matrix(f)
    assert t.shape == (50, 4, 4)
    assert np.allclose(frames.compose(t, frames.inverse(t)), np.eye(4))
