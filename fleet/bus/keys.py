"""The one naming scheme for key expressions: `clawfleet/<run>/...`, with `<arm>` the arm's id everywhere."""

from __future__ import annotations

from dataclasses import dataclass

from scenes.schema import MAX_NAME_CHARS, is_valid_name

ROOT = "clawfleet"


@dataclass(frozen=True)
class Keys:
    """Key expressions of one run; a run id keeps several lines on one Zenoh network apart."""

    run: str

    def __post_init__(self) -> None:
        if not is_valid_name(self.run):
            shown = repr(self.run) if len(self.run) <= 60 else f"{self.run[:40]!r}... ({len(self.run):,} characters)"
            rule = f"1 to {MAX_NAME_CHARS} lower-case letters, digits and _ (starting with a letter)"
            raise ValueError(f"run id {shown} must be {rule}")

    @property
    def prefix(self) -> str:
        """Every key of the run starts with this (`clawfleet/<run>`)."""
        return f"{ROOT}/{self.run}"

    @property
    def recorder_ready(self) -> str:
        """A recorder says it listens (the sim, told to await one, starts its clock only then)."""
        return f"{ROOT}/{self.run}/recorder/ready"

    def _arm(self, arm: str, leaf: str) -> str:
        if not is_valid_name(arm):
            raise ValueError(f"arm id {arm!r} is not a valid id")
        return f"{ROOT}/{self.run}/arm/{arm}/{leaf}"

    def arm_state(self, arm: str) -> str:
        return self._arm(arm, "state")

    def arm_step(self, arm: str) -> str:
        """The controller's answer to each state it gets (`ControllerStep`)."""
        return self._arm(arm, "step")

    def arm_goal(self, arm: str) -> str:
        """Trajectory and gripper goals for the arm's tracker (`TrajectoryGoalMsg`, `GripperGoalMsg`)."""
        return self._arm(arm, "goal")

    def arm_drive(self, arm: str) -> str:
        """Goals for the arm's tracker from an outside client (ROS front ends): the arm is taken while they run."""
        return self._arm(arm, "drive")

    def arm_result(self, arm: str) -> str:
        """One result per goal (`GoalResultMsg`)."""
        return self._arm(arm, "result")

    def arm_status(self, arm: str) -> str:
        return self._arm(arm, "status")

    def arm_assign(self, arm: str) -> str:
        return self._arm(arm, "assign")

    def env_action(self, arm: str) -> str:
        """PettingZoo env -> the arm's process (`EnvAction`)."""
        return self._arm(arm, "env_action")

    def env_targets(self, arm: str) -> str:
        """The arm's process -> PettingZoo env (`EnvTargets`)."""
        return self._arm(arm, "env_targets")

    def all_arms(self, leaf: str) -> str:
        """Wildcard over every arm's `leaf` (state, step, goal, drive, result, status, assign, env_action or
        env_targets)."""
        return f"{ROOT}/{self.run}/arm/*/{leaf}"

    @property
    def parts(self) -> str:
        return f"{ROOT}/{self.run}/world/parts"

    @property
    def events(self) -> str:
        return f"{ROOT}/{self.run}/world/events"

    @property
    def control(self) -> str:
        """Pause/resume and speed (`SimControl`)."""
        return f"{ROOT}/{self.run}/world/control"

    @property
    def sim_status(self) -> str:
        return f"{ROOT}/{self.run}/world/status"

    @property
    def frame(self) -> str:
        """Every arm and part in one message at the coordinator's decision rate (`LineView`)."""
        return f"{ROOT}/{self.run}/world/frame"

    @property
    def view(self) -> str:
        """Every arm and part in one message, a few times per sim second (`LineView`), for monitors."""
        return f"{ROOT}/{self.run}/world/view"

    @property
    def scene(self) -> str:
        """A queryable: the sim answers with the scene it runs, as JSON (so a monitor needs only an endpoint)."""
        return f"{ROOT}/{self.run}/world/scene"

    @property
    def history(self) -> str:
        """A queryable: the sim answers with every line event so far (`EventLog`), for a coordinator that rejoins."""
        return f"{ROOT}/{self.run}/world/history"

    @property
    def respawn(self) -> str:
        """Requests to the launcher to start a controller again (`RespawnRequest`)."""
        return f"{ROOT}/{self.run}/launcher/respawn"

    @property
    def roster(self) -> str:
        """The launcher's `Roster`: which incarnation of each node it started."""
        return f"{ROOT}/{self.run}/launcher/roster"

    @property
    def snapshot_ask(self) -> str:
        """The sim's `SnapshotAsk`: every node's state for a snapshot of the run (not recorded)."""
        return f"{ROOT}/{self.run}/world/snapshot"

    def snapshot_part(self, node: str) -> str:
        """A node's `SnapshotPart` (`coordinator` or an arm id) for the sim's snapshot (not recorded)."""
        return f"{ROOT}/{self.run}/snapshot/{node}"

    def snapshot_parts(self) -> str:
        return f"{ROOT}/{self.run}/snapshot/*"

    def camera(self, camera: str, kind: str) -> str:
        """One camera's images of one kind (`CameraImage`): `clawfleet/<run>/camera/<camera>/<kind>`."""
        return f"{ROOT}/{self.run}/camera/{camera}/{kind}"

    def detections(self, camera: str) -> str:
        """The parts perception sees through one camera (`PartDetections`): `clawfleet/<run>/perception/<camera>`."""
        return f"{ROOT}/{self.run}/perception/{camera}"

    @property
    def seen_parts(self) -> str:
        """The line's parts as its cameras show them (`PartsState`, perception's, one a frame, `docs/perception.md`):
        `clawfleet/<run>/seen/parts`."""
        return f"{ROOT}/{self.run}/seen/parts"

    @property
    def seen_ready(self) -> str:
        """Perception says it listens, until it hears the line's first image (a sim told to await it starts then)."""
        return f"{ROOT}/{self.run}/seen/ready"

    @property
    def estop(self) -> str:
        return f"{ROOT}/{self.run}/estop"

    def coord(self, leaf: str) -> str:
        return f"{ROOT}/{self.run}/coord/{leaf}"

    def recorded(self) -> list[str]:
        """The key expressions a recorder subscribes to: every key of the run but the monitors' `world/view` (a copy
        of `world/frame` at another rate, built only while someone watches; recording it would make the sim build
        it)."""
        root = self.prefix
        return [
            f"{root}/arm/**",
            self.parts,
            self.events,
            self.control,
            self.sim_status,
            self.frame,
            self.estop,
            f"{root}/coord/**",
            f"{root}/launcher/**",
            f"{root}/camera/**",
            f"{root}/perception/*",
            self.seen_parts,
        ]

    @staticmethod
    def arm_of(key: str) -> str:
        """The arm id in an arm key (`clawfleet/<run>/arm/<arm>/<leaf>`)."""
        parts = key.split("/")
        if len(parts) != 5 or parts[2] != "arm":
            raise ValueError(f"{key!r} is not an arm key")
        return parts[3]
