"""Models fixed once built pickle as what they were built from: a run's snapshot stays small, and read back in a
process that built the same model it is that very object; anywhere else it is built anew, equal."""

import dataclasses
import pickle

import numpy as np

from coordinator.geometry import ArmGeometry, separation_m
from robots.frames import yaw_transform
from robots.kinematics import KinematicModel, PlacedFrames
from robots.registry import get_robot
from robots.top_down import TopDownIK

BASE = yaw_transform((0.3, -0.2, 0.0), 0.6)


def test_a_model_pickles_as_its_robot_and_reads_back_as_the_one_this_process_built():
    km = KinematicModel(get_robot("so101"))
    blob = pickle.dumps(km)
    assert len(blob) < 500  # the robot's name, not its Pinocchio model
    again = pickle.loads(blob)
    # one this process built for the robot (this one, or one built before it): found, not built anew
    assert again is pickle.loads(blob) and again.spec is km.spec and isinstance(again, KinematicModel)
    ik = TopDownIK(km.spec, BASE, km)
    link = next(iter(km.link_poses(km.full_q(np.asarray(km.spec.home_q, float)))))
    placed = PlacedFrames(km, BASE, [(link, np.eye(4))])
    assert pickle.loads(pickle.dumps(ik)) is ik and pickle.loads(pickle.dumps(placed)) is placed  # placed here only


def test_one_not_built_here_is_built_from_the_same_inputs_and_answers_alike():
    spec = dataclasses.replace(get_robot("openclaw"), uid="openclaw_variant")  # not registered: found by no one
    ik = TopDownIK(spec, BASE)
    again = pickle.loads(pickle.dumps(ik))
    assert again is not ik and again.km is not ik.km
    spot = (BASE @ np.array([0.18, 0.0, 0.05, 1.0]))[:3]
    want, got = ik.reach_pose(spot), again.reach_pose(spot)
    assert (want is None) == (got is None)
    if want is not None:
        np.testing.assert_allclose(got[1], want[1])


def test_an_arm_s_geometry_read_back_measures_as_before():
    spec = get_robot("openclaw")
    a = ArmGeometry("arm_0", spec, yaw_transform((0.0, 0.0, 0.0), np.pi / 2))
    b = ArmGeometry("arm_1", spec, yaw_transform((0.45, 0.0, 0.0), np.pi / 2))
    rng = np.random.default_rng(3)
    km = a.km
    lower, upper = km.lower[km.arm_q_index], km.upper[km.arm_q_index]
    for _ in range(5):
        a.place(rng.uniform(lower, upper))
        b.place(rng.uniform(lower, upper))
        a2, b2 = pickle.loads(pickle.dumps((a, b)))
        assert separation_m(a2, b2) == separation_m(a, b)
    assert len(pickle.dumps(a)) < 10_000  # its shapes and models by reference (48 kB when pickled whole)
