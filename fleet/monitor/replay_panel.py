"""The monitor's replay controls: a sim-time slider to scrub, play / pause, and the speed, over a `Player`.

The page's own Pause / Resume / Speed controls act on the playback too (the player listens on
`world/control` as a sim would); the slider moves with the playback and jumps it when dragged.
"""

from __future__ import annotations

import viser

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
        self.seeks = 0
        self._shown_s = round(clock.position_s, 1)  # the slider's value as `show` last set it
        self.time.on_update(self._on_time)
        self.play.on_click(lambda _: self._toggle())
        self.speed.on_update(self._on_speed)

    def _on_time(self, event: viser.GuiEvent) -> None:
        if event.client is None:  # the slider moved by `show`, not by a person
            return
        self.seeks += 1
        self.player.seek(float(self.time.value))

    def _toggle(self) -> None:
        clock = self.player.clock
        if not clock.playing and clock.position_s >= clock.end_s:
            self.player.seek(clock.start_s)  # play again from the start
        clock.playing = not clock.playing

    def _on_speed(self, event: viser.GuiEvent) -> None:
        if event.client is not None:
            self.player.clock.speed = float(self.speed.value)

    def show(self) -> None:
        clock = self.player.clock
        position = round(clock.position_s, 1)
        if position != self._shown_s:  # only when the replay moved: rewriting it always could undo a person's seek
            self.time.value = self._shown_s = position  # between their move arriving and `_on_time` reading it
        state = "playing" if clock.playing else "paused"
        text = f"{state} at **{clock.position_s:.1f}** of {clock.end_s:.1f} sim s, x{clock.speed:g}"
        if self.info.content != text:
            self.info.content = text
