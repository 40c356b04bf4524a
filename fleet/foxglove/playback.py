"""The Foxglove app's playback controls (its `PlaybackControl` capability: play, pause, speed, seek) on a recording
played back onto the bus (`fleet replay FILE.mcap --foxglove`): each request acts on the `Player`, and the answer
says where playback stands."""

from __future__ import annotations

from foxglove.websocket import PlaybackCommand, PlaybackControlRequest, PlaybackState, PlaybackStatus

from fleet.record.replay import Player
from fleet.record.ros_types import sim_ns


class RecordingPlayback:
    """A recording's player as the app drives it; `time_range_ns` is what its timeline spans."""

    def __init__(self, player: Player) -> None:
        self.player = player
        self._ended = False

    @property
    def time_range_ns(self) -> tuple[int, int]:
        return sim_ns(self.player.clock.start_s), sim_ns(self.player.clock.end_s)

    def on_request(self, request: PlaybackControlRequest) -> PlaybackState:
        """Seek first (the newest message of each topic up to then goes out), then play or pause at the speed."""
        if request.seek_time is not None:
            self.player.seek(request.seek_time / 1e9)
        self.player.control(request.playback_command == PlaybackCommand.Play, float(request.playback_speed))
        self._ended = False
        return self.state(request.request_id, did_seek=request.seek_time is not None)

    def state(self, request_id: str | None = None, did_seek: bool = False) -> PlaybackState:
        clock = self.player.clock
        if clock.position_s >= clock.end_s:
            status = PlaybackStatus.Ended
        else:
            status = PlaybackStatus.Playing if clock.playing else PlaybackStatus.Paused
        return PlaybackState(status, sim_ns(clock.position_s), clock.speed, did_seek, request_id)

    def ended_now(self) -> bool:
        """Whether playback reached the recording's end since last asked (the app is then told so, once)."""
        clock = self.player.clock
        if clock.position_s >= clock.end_s and not self._ended:
            self._ended = True
            return True
        return False
