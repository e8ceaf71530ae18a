"""The replay timeline: a slider over the recorded run's time (robot, map with E[v], plans and plots at that
time), play/pause and speed. Shown when the studio replays a recording (`app.recording.replay.ReplaySource`)."""

from __future__ import annotations

import viser

from app.recording.replay import ReplaySource
from app.runtime.snapshot import Snapshot
from app.ui.monitor_panel import MonitorPanel
from app.ui.notify import guarded

SPEEDS = ("0.25", "0.5", "1", "2", "4", "8")


class TimelinePanel:
    """A 'Replay' folder at the top of the sidebar; slider and buttons drive the source."""

    def __init__(self, server: viser.ViserServer, source: ReplaySource, monitor: MonitorPanel) -> None:
        self.source, self.monitor = source, monitor
        with server.gui.add_folder("Replay", order=0.5):
            self.time = server.gui.add_slider("Replay time (s)", min=round(source.start_time, 1),
                                              max=max(round(source.end_time, 1), round(source.start_time, 1) + 0.1),
                                              step=0.1, initial_value=round(source.start_time, 1))
            self.buttons = server.gui.add_button_group("Playback", ("Play", "Pause", "Step", "Rewind"))
            self.speed = server.gui.add_dropdown("Replay speed (×)", SPEEDS, initial_value="1")
        self.time.on_update(guarded(server, "seek")(self._on_time))
        self.buttons.on_click(guarded(server, "playback")(lambda e: self._on_button(e.target.value)))
        self.speed.on_update(guarded(server, "replay speed")(lambda _: source.set_speed(float(self.speed.value))))

    def _on_time(self, event: viser.GuiEvent) -> None:
        if event.client is None:  # the slider following playback (`update`), not the operator
            return
        self.source.pause()
        self.seek(float(self.time.value))

    def seek(self, t: float) -> None:
        """Show the run at sim time t: the plots start over from the recorded history up to t."""
        self.source.pause()
        index = int(min(max(self.source.times.searchsorted(t, side="right") - 1, 0), len(self.source.times) - 1))
        self.monitor.load_history(self.source.snapshots[:index])
        self.source.seek(t)

    def _on_button(self, action: str) -> None:
        if action == "Play":
            self.source.start()
        elif action == "Pause":
            self.source.pause()
        elif action == "Step":
            self.source.step()
        else:
            self.seek(self.source.start_time)

    def update(self, snap: Snapshot) -> None:
        """Move the slider with playback."""
        t = round(snap.state.t, 1)
        if abs(self.time.value - t) >= 0.05:
            self.time.value = min(max(t, self.time.min), self.time.max)
