"""Trained joint ranges as arcs on the circle (``compensator.joint_arcs``): a joint whose
training angles cross ±180° (a UR10 with q1 from −308° to −180°, i.e. 52°…180°) has a narrow
arc across the seam, not the whole circle; P301 (``Envelope.outside_joints``) and the graph's
learned parts (``features.inside_ranges`` on ``hybrid.learned_ranges``) decide alike."""
import numpy as np
import torch

from postproc.model.envelope import Envelope, joint_arcs, widened_arcs
from postproc.model.training.features import inside_ranges
from postproc.model.training.hybrid import learned_ranges


def _envelope(arcs):
    return Envelope(box=np.zeros(6), attitude=np.zeros(3), range=180.0, joints=np.asarray(arcs, float))


def test_an_arc_across_the_seam_is_the_smallest_one():
    rng = np.random.default_rng(0)
    q = np.c_[rng.uniform(-308, -180, 500), rng.uniform(-40, 60, 500), rng.uniform(150, 230, 500)]
    arcs = joint_arcs(q)
    # 52…180 (the turn of −308…−180), −40…60, and 150…230 across the seam (not −180…180)
    assert np.allclose(arcs[0], [52, 180], atol=1.0)
    assert np.allclose(arcs[1], [-40, 60], atol=1.0)
    assert np.allclose(arcs[2], [150, 230], atol=1.0)
    env = _envelope(arcs)
    assert not env.outside_joints(q).any()  # every training angle is on its arc
    assert not env.outside_joints(q + 360.0).any()  # in any turn
    # the far side of each joint's circle is outside; the seam itself is not
    for joint, far in ((0, -60.0), (1, 180.0), (2, 10.0)):
        probe = np.array([[116.0, 10.0, 190.0]])
        assert not env.outside_joints(probe).any()
        probe[0, joint] = far
        assert env.outside_joints(probe).all()


def test_the_graph_and_compensate_draw_the_same_line():
    rng = np.random.default_rng(1)
    train = np.c_[rng.uniform(-308, -180, 300), rng.uniform(-170, 170, 300), rng.uniform(0, 130, 300),
                  rng.uniform(100, 440, 300), rng.uniform(0, 147, 300), rng.uniform(-150, 160, 300)]
    arcs = joint_arcs(train)
    q = rng.uniform(-400, 400, (4000, 6))
    outside = _envelope(arcs).outside_joints(q)
    inside = inside_ranges(torch.as_tensor(np.radians(q)), torch.as_tensor(learned_ranges(arcs))).numpy() > 0
    assert 0.05 < inside.mean() < 0.5  # (both kinds occur)
    assert np.array_equal(inside, ~outside)


def test_ranges_within_180_keep_their_meaning_and_margin():
    """A card's [lo, hi] inside ±180 (the older cards) is the same range, widened by 5 % + 0.5°."""
    arcs = np.array([[-100.0, 100.0]] * 6)
    wide = widened_arcs(arcs)
    assert np.allclose(wide[0], [-110.5, 110.5])
    env = _envelope(arcs)
    q = np.zeros((3, 6))
    q[1, 2], q[2, 2] = 110.0, 111.0
    assert env.outside_joints(q).tolist() == [False, False, True]
    # an arc widened past a full turn holds every angle
    assert not _envelope([[-179.0, 179.0]] * 6).outside_joints(np.full((1, 6), 180.0)).any()
