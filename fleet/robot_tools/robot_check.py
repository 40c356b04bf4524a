"""Checks of a robot declaration against the physics: what `fleet robots --check` prints, one plain line each.

Kinematics (Pinocchio's link poses against SAPIEN's), the home pose (reached
from the upright pose by the arm's own drives, above the floor, within its
reach), the gripper (closes and opens on nothing within a second), the
reach measured from the kinematics, and a few seeded pick trials in the trial
cell.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import sapien

from fleet.sim.arm import SimArm, yaw_pose
from robots.kinematics import KinematicModel
from robots.measured_reach import HEIGHTS_M, MARGIN_M, reach_m_of
from robots.spec import RobotSpec

CONFIGURATIONS = 50
POSE_TOLERANCE = 1e-5
HOME_TOLERANCE_RAD = 0.02
GRIPPER_TOLERANCE = 0.1
"""Of the gripper's travel: how near its closed (open) position a gripper must come on nothing."""
SETTLE_S = 1.5
PHYSICS_HZ = 200.0


@dataclass(frozen=True)
class Finding:
    """One result of a check: whether it holds, and what it found, in a plain line."""

    ok: bool
    text: str

    def line(self) -> str:
        return f"{'ok' if self.ok else 'problem'}: {self.text}"


def _lone_arm(spec: RobotSpec, base: sapien.Pose | None = None) -> tuple[sapien.Scene, SimArm]:
    """The arm alone in a scene, base at the origin unless given."""
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(1.0 / PHYSICS_HZ)
    return scene, SimArm(scene, spec, "arm_0", base if base is not None else yaw_pose((0.0, 0.0, 0.0), 0.0), 0)


def kinematics_agree(
    spec: RobotSpec, configurations: int = CONFIGURATIONS, seed: int = 42
) -> tuple[float, float, list[str]]:
    """Worst position (m) and orientation (rad) difference between Pinocchio and SAPIEN over every link and random
    configurations, and the SAPIEN links Pinocchio has no frame for. The base stands off the origin, turned, so
    that the base transform is checked too."""
    scene, arm = _lone_arm(spec, yaw_pose((0.2, -0.1, 0.05), 0.7))
    km = KinematicModel(spec)
    base_to_world = arm.base_pose.to_transformation_matrix()
    rng = np.random.default_rng(seed)
    worst_m = worst_rad = 0.0
    missing: set[str] = set()
    for _ in range(configurations):
        q = rng.uniform(km.lower, km.upper)
        arm.set_qpos(q[np.concatenate([km.arm_q_index, km.gripper_q_index])])
        poses = km.link_poses(q)
        for name, link in arm.links.items():
            if name not in poses:
                missing.add(name)
                continue
            expected = base_to_world @ poses[name]
            got = link.entity_pose.to_transformation_matrix()
            worst_m = max(worst_m, float(np.abs(expected[:3, 3] - got[:3, 3]).max()))
            worst_rad = max(worst_rad, float(np.linalg.norm(pin.log3(expected[:3, :3].T @ got[:3, :3]))))
    return worst_m, worst_rad, sorted(missing)


def _settle(scene: sapien.Scene, seconds: float) -> None:
    for _ in range(int(seconds * PHYSICS_HZ)):
        scene.step()


def check_kinematics(spec: RobotSpec) -> Finding:
    worst_m, worst_rad, missing = kinematics_agree(spec)
    if missing:
        return Finding(False, f"SAPIEN has links Pinocchio does not: {', '.join(missing)}")
    if worst_m > POSE_TOLERANCE or worst_rad > POSE_TOLERANCE:
        return Finding(
            False, f"Pinocchio and SAPIEN disagree on link poses by up to {worst_m:.2e} m, {worst_rad:.2e} rad"
        )
    return Finding(
        True,
        f"Pinocchio and SAPIEN agree on every link ({CONFIGURATIONS} random configurations, "
        f"worst {worst_m:.1e} m, {worst_rad:.1e} rad)",
    )


def check_home(spec: RobotSpec) -> Finding:
    """Home reached by the arm's drives from the upright pose, above the floor and within its reach."""
    km = KinematicModel(spec)
    home = np.asarray(spec.home_q, float)
    tool = km.frame_pose(km.full_q(home))[:3, 3]
    if tool[2] < 0.0:
        return Finding(
            False, f"home puts the tool {-tool[2]:.3f} m below its base: it would be in the floor or the table"
        )
    horizontal = float(np.hypot(tool[0], tool[1]))
    if horizontal > reach_m_of(spec):
        return Finding(
            False, f"home puts the tool {horizontal:.2f} m out, beyond its reach ({reach_m_of(spec):.2f} m, measured)"
        )
    scene, arm = _lone_arm(spec)
    start = np.clip(np.zeros(spec.arm_dof), km.lower[km.arm_q_index], km.upper[km.arm_q_index])
    arm.set_qpos(np.concatenate([start, spec.gripper_targets(1.0)]))
    arm.set_targets(home, np.zeros(spec.arm_dof), spec.gripper_targets(1.0))
    _settle(scene, SETTLE_S)
    error = np.abs(arm.qpos()[: spec.arm_dof] - home)
    worst = int(np.argmax(error))
    if error[worst] > HOME_TOLERANCE_RAD:
        return Finding(
            False,
            f"the drives do not reach home in {SETTLE_S:g} s from upright: {spec.arm_joints[worst]} is "
            f"{error[worst]:.3f} off (arm_gains too weak, or a joint blocked)",
        )
    return Finding(
        True,
        f"home reached by the drives in {SETTLE_S:g} s (worst joint {error[worst]:.4f} off), tool "
        f"{tool[2]:.2f} m above the base and {horizontal:.2f} m out",
    )


def check_gripper(spec: RobotSpec) -> Finding:
    """The gripper closes on nothing, then opens again, each within `SETTLE_S`."""
    scene, arm = _lone_arm(spec)
    n = spec.arm_dof
    home = np.asarray(spec.home_q, float)
    closed, opened = np.asarray(spec.gripper_closed), np.asarray(spec.gripper_open)
    travel = np.maximum(np.abs(opened - closed), 1e-9)
    for target, word in ((closed, "close"), (opened, "open")):
        arm.set_targets(home, np.zeros(n), target)
        _settle(scene, SETTLE_S)
        off = np.abs(arm.qpos()[n:] - target) / travel
        worst = int(np.argmax(off))
        if off[worst] > GRIPPER_TOLERANCE:
            at = arm.qpos()[n + worst]
            return Finding(
                False,
                f"the gripper does not {word}: {spec.gripper_joints[worst]} stays at {at:.4f} against "
                f"{target[worst]:.4f} ({off[worst]:.0%} of its travel short; gripper_gains too weak, or "
                "fingers that collide)",
            )
    return Finding(True, f"the gripper closes and opens on nothing within {SETTLE_S:g} s")


def check_reach(spec: RobotSpec) -> Finding:
    """The reach measured from the kinematics (`robots.measured_reach`: scenes check stations against it, the
    coordinator answers "no" past it without IK); an arm that points its claw at no spot is a problem."""
    reach = reach_m_of(spec)
    heights = f"{HEIGHTS_M[0] * 100:.0f} to {HEIGHTS_M[-1] * 100:.0f} cm above its base"
    if reach <= MARGIN_M:
        return Finding(
            False,
            f"points its claw at no spot {heights}, straight down or leaning (check tool_frame, approach_axis_tool "
            "and max_approach_tilt_deg)",
        )
    return Finding(True, f"reaches {reach:.2f} m out from its base (measured {heights}, as the skill reaches)")


def check_trials(uid: str, trials: int, seed: int, on_trial: Callable[[], None] | None = None) -> list[Finding]:
    """Seeded pick trials in the trial cell: one line for the count, one per failure."""
    from fleet.robot_tools.trials import run_trials

    results = run_trials(uid, trials, seed, (lambda _r: on_trial()) if on_trial else None)
    placed = sum(r.success for r in results)
    lines = [
        Finding(
            placed == len(results),
            f"{placed}/{len(results)} seeded pick trials placed their part (seeds {seed}-{seed + trials - 1})",
        )
    ]
    lines += [Finding(False, f"trial seed {r.seed}: {r.phase}: {r.reason}") for r in results if not r.success]
    return lines


def _guarded(check: Callable[[RobotSpec], Finding], spec: RobotSpec) -> Finding:
    """A check's finding; one the physics could not even run is a problem line saying why, not a traceback."""
    try:
        return check(spec)
    except Exception as exc:  # SAPIEN and Pinocchio raise bare RuntimeErrors for a model they cannot load
        first = (str(exc).strip().splitlines() or [""])[0]
        return Finding(
            False, f"{check.__name__.removeprefix('check_')}: could not be checked: {type(exc).__name__}: {first}"
        )


def check_robot(spec: RobotSpec, trials: int = 3, seed: int = 0) -> Iterator[Finding]:
    """Every check in turn (the physics checks first: a robot that fails them is not tried at picking)."""
    physics = [_guarded(check, spec) for check in (check_kinematics, check_home, check_gripper, check_reach)]
    yield from physics
    if trials > 0 and all(f.ok for f in physics):
        yield from check_trials(spec.uid, trials, seed)
