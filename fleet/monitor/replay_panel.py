"""The monitor's replay controls: a sim-time slider to scrub, play / pause, and the speed, over a `Player`.

The page's own Pause / Resume / Speed controls act on the playback too (the player listens on
`world/control` as a sim would); the slider moves with the playback and jumps it when dragged.
"""

from __future__ import annotations

import viser

from fleet.record.mcap_file import Recording
from fleet.record.replay import Player

SPEEDS = ("0.25", "0.5", "1", "2", "5", "10")


class ReplayPanel:
    """A "Replay" folder on the page; `show()` moves the slider with the playback."""

    def __init__(self, server: viser.ViserServer, player: Player) -> None:
        self.player = player
        clock = player.clock
        with server.gui.add_folder("Replay", order=-1):
            self.time = server.gui.add_slider(
                "Sim time (s)",
                min=round(clock.start_s, 1),
                max=round(max(clock.end_s, clock.start_s + 0.1), 1),
                step=0.1,
                initial_value=round(clock.position_s, 1),
            )
            self.play = server.gui.add_button("Play / pause", icon=viser.Icon.PLAYER_PLAY)
            self.speed = server.gui.add_dropdown("Replay speed", SPEEDS, initial_value="1")
            self.info = server.gui.add_markdown("")
            self.branch = server.gui.add_button("Branch from here", icon=viser.Icon.GIT_BRANCH)
            self.branch_info = server.gui.add_markdown("")
        self.seeks = 0
        self._shown_s = round(clock.position_s, 1)  # the slider's value as `show` last set it
        self.time.on_update(self._on_time)
        self.play.on_click(lambda _: self._toggle())
        self.speed.on_update(self._on_speed)
        self.branch.on_click(lambda _: self._offer_branch())

    def _on_time(self, event: viser.GuiEvent) -> None:
        if event.client is None:  # the slider moved by `show`, not by a person
            return
        self.seeks += 1
        self.player.seek(float(self.time.value))

    def _toggle(self) -> None:
        self.player.control(playing=not self.player.clock.playing)  # at the end, play again from the start

    def _offer_branch(self) -> None:
        """The command that starts a line from the newest snapshot the recording carries at or before where the
        replay stands (the recording was made with snapshots: `fleet run --snapshot-every S --out DIR`)."""
        self.branch_info.content = branch_command(self.player.recording, self.player.clock.position_s)

    def _on_speed(self, event: viser.GuiEvent) -> None:
        if event.client is not None:
            self.player.control(speed=float(self.speed.value))

    def show(self) -> None:
        clock = self.player.clock
        position = round(clock.position_s, 1)
        if position != self._shown_s:  # only when the replay moved: rewriting it always could undo a person's seek
            self.time.value = self._shown_s = position  # between their move arriving and `_on_time` reading it
        state = "playing" if clock.playing else "paused"
        text = f"{state} at **{clock.position_s:.1f}** of {clock.end_s:.1f} sim s, x{clock.speed:g}"
        if self.info.content != text:
            self.info.content = text


def branch_command(recording: Recording, at_s: float) -> str:
    """What the page says to branch from `at_s`: the snapshot it would start from and the command, or why none."""
    name = recording.snapshot_name_at(at_s)
    if name is None:
        have = sorted(t / 1e9 for t in recording.snapshot_times_ns.values())
        said = ", ".join(f"{t:g}" for t in have) or "none (record with fleet run --snapshot-every S --out DIR)"
        return f"no snapshot at or before {at_s:.1f} s; snapshots at: {said}"
    taken_s = recording.snapshot_times_ns[name] / 1e9
    return f"from the snapshot at **{taken_s:g} s**: `fleet run --from {recording.path} --at {at_s:.1f}`"
