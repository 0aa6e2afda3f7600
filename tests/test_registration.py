"""Best-fit rigid registration (Kabsch / Umeyama)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from postproc.core.diagnostics import PostprocError
from postproc.core.registration import apply_rigid, fit_rigid, register_measurements, residuals, transform_matrix


def _rotation_angle(r1: np.ndarray, r2: np.ndarray) -> float:
    return float(np.linalg.norm(Rotation.from_matrix(r1.T @ r2).as_rotvec()))


@pytest.fixture
def scene():
    """A tracker-like setup: 200 points in a 1 m cube, a random pose 3 m away, 0.01 mm noise."""
    rng = np.random.default_rng(7)
    source = rng.uniform(-500.0, 500.0, (200, 3)) + [300.0, -3000.0, 200.0]
    rotation = Rotation.random(random_state=11).as_matrix()
    translation = np.array([-750.0, -3540.0, 1230.0])
    target = source @ rotation.T + translation + rng.normal(0.0, 0.01, source.shape)
    return source, target, rotation, translation


def test_recovers_known_rigid_transform_from_noisy_points(scene):
    source, target, rotation, translation = scene
    r, t = fit_rigid(source, target)
    # expected precision ~ noise / (spread · √N) ≈ 0.01 / (300 · 14) rad ≈ 2e-6 rad
    assert _rotation_angle(r, rotation) < 2e-5
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12) and np.linalg.det(r) == pytest.approx(1.0)
    # t absorbs the rotation error times the distance of the points (~3 m): ≤ 0.06 mm
    assert np.linalg.norm(t - translation) < 0.06
    # what matters for errors: the mapped points sit on the targets to the noise level
    # mean of |3-D normal noise| = σ·√(8/π)
    assert residuals(source, target, r, t).mean() == pytest.approx(0.01 * np.sqrt(8 / np.pi), rel=0.15)


def test_matches_scipy_align_vectors(scene):
    # an independent Kabsch implementation on the centred points
    source, target, _, _ = scene
    r, _ = fit_rigid(source, target)
    reference, _ = Rotation.align_vectors(target - target.mean(0), source - source.mean(0))
    assert _rotation_angle(r, reference.as_matrix()) < 1e-9


def test_scale_recovered_with_umeyama(scene):
    source, target, rotation, translation = scene
    r, t, s = fit_rigid(source, 1.0003 * (target - translation) + translation, scale=True)
    assert s == pytest.approx(1.0003, abs=5e-6)  # ≈ σ / (spread·√3N) ≈ 1.4e-6
    assert _rotation_angle(r, rotation) < 2e-5
    assert np.allclose(transform_matrix(r, t, s)[:3, :3], s * r)


def test_mirrored_target_still_gives_a_rotation(scene):
    source, _, _, _ = scene
    r, _ = fit_rigid(source, source * [1.0, 1.0, -1.0])
    assert np.linalg.det(r) == pytest.approx(1.0)


def test_exact_coplanar_points_are_enough():
    square = np.array([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [100.0, 100.0, 0.0], [0.0, 100.0, 0.0]])
    rotation = Rotation.from_euler("zyx", [30.0, -20.0, 10.0], degrees=True).as_matrix()
    r, t = fit_rigid(square, apply_rigid(square, rotation, [1.0, 2.0, 3.0]))
    assert np.allclose(r, rotation, atol=1e-12) and np.allclose(t, [1.0, 2.0, 3.0], atol=1e-10)


@pytest.mark.parametrize(
    "source",
    [
        np.outer(np.linspace(0.0, 1000.0, 10), [0.3, -0.5, 0.8]) + [10.0, 20.0, 30.0],  # collinear
        np.ones((5, 3)),  # one point repeated
        np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]]),  # < 3 points
    ],
)
def test_degenerate_input_is_a_clear_error(source):
    with pytest.raises(PostprocError) as info:
        fit_rigid(source, source + 5.0)
    assert info.value.code == "P510"
    assert "collinear" in info.value.message or "at least 3" in info.value.message


def test_shape_errors():
    with pytest.raises(PostprocError, match="correspond"):
        fit_rigid(np.zeros((4, 3)), np.zeros((5, 3)))
    with pytest.raises(PostprocError, match=r"\[N, 3\]"):
        fit_rigid(np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(PostprocError, match="NaN"):
        fit_rigid(np.full((4, 3), np.nan), np.zeros((4, 3)))


def test_register_measurements_uses_training_rows_only(scene):
    measured, commanded, rotation, translation = scene  # tracker → base
    train = np.arange(len(measured)) % 5 != 0
    in_base, transform, rms = register_measurements(commanded, measured, train)
    spoiled = measured.copy()
    spoiled[~train] += 1000.0  # the held-out rows must not move the fit
    in_base2, transform2, rms2 = register_measurements(commanded, spoiled, train)
    assert np.array_equal(transform, transform2) and rms == rms2
    assert np.allclose(in_base2[~train] - in_base[~train], transform[:3, :3] @ np.full(3, 1000.0))
    assert _rotation_angle(transform[:3, :3], rotation) < 2e-5
    assert rms < 0.03  # ≈ noise √3 = 0.017 mm
    assert np.allclose(in_base, apply_rigid(measured, transform[:3, :3], transform[:3, 3]))
