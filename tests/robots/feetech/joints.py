"""A servo joint for tests of the servos' side alone (`robots.feetech.servos.ServoJoint`)."""


class StiffJoint:
    """A joint that stands wherever it was last driven (a servo with infinite stiffness), free when not driven."""

    def __init__(self, ticks: int) -> None:
        self.ticks, self.goal = ticks, None

    def position_ticks(self) -> int:
        return self.ticks

    def velocity_ticks_per_s(self) -> int:
        return 0

    def drive(self, goal_ticks: int | None) -> None:
        self.goal = goal_ticks
        if goal_ticks is not None:
            self.ticks = goal_ticks
