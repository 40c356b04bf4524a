import numpy as np

from robots.trajectory import JointSegment


def test_segment_respects_velocity_limits_and_ends_at_rest():
    limit = np.array([1.0, 2.0])
    seg = JointSegment.timed(np.zeros(2), np.array([1.0, -1.0]), 2.0, limit, speed_fraction=0.5)
    times = np.linspace(seg.t0_s, seg.t_end_s, 200)
    speeds = np.array([np.abs(seg.sample(t)[1]) for t in times])
    assert np.all(speeds <= 0.5 * limit + 1e-9)
    q_end, dq_end = seg.sample(seg.t_end_s + 1.0)
    np.testing.assert_allclose(q_end, [1.0, -1.0])
    np.testing.assert_allclose(dq_end, 0.0)
