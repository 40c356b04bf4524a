"""The line's switches, as its users set them (the e-stop, `SimControl`'s pause, speed and snapshot) and as its
start sets them (the clock's mode, who answers, whether every process has answered yet), and what they decide:
whether answers wait for their due tick."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class LineControls:
    """One sim server's switches, read by its inputs, outputs and lockstep, set by its inputs."""

    mode: str  # lockstep | realtime
    controllers: bool  # every arm has a controller that answers its states (False: goals from whoever sends them)
    coordinator: bool  # a coordinator answers the line's frames
    speed: float = 1.0  # realtime: sim seconds per wall second
    estop: bool = False
    paused: bool = False
    started: bool = False  # every controller answered once (realtime paces from then on)
    snapshot_asked_by: str = ""  # who asked for a snapshot now (`SimControl.snapshot`): taken at the next tick
    pause_at_ticks: set[int] = field(default_factory=set)  # `--pause-at`: the line pauses once one of these has run

    def __post_init__(self) -> None:
        if self.mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode {self.mode!r}: valid modes are lockstep, realtime")

    def pause_if_due(self, tick: int) -> bool:
        """Pause the line if `tick`, just run, is one it was told to pause after (once each: a resume goes on)."""
        if tick not in self.pause_at_ticks:
            return False
        self.pause_at_ticks.discard(tick)
        self.paused = True
        return True

    @property
    def lockstep(self) -> bool:
        return self.mode == "lockstep"

    @property
    def deferred(self) -> bool:
        """Answers and goals wait for their arm's due tick (lockstep, or until every process is up)."""
        return self.controllers and (self.lockstep or not self.started)

    @property
    def deferred_coord(self) -> bool:
        """The coordinator's ticks are awaited and take effect when due (lockstep, or until every process is up)."""
        return self.coordinator and (self.lockstep or not self.started)
