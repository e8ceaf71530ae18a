"""Run control: start, pause, step, skip the active subtask, stop, reset, speed, map and constraint kind,
emergency stop."""

from __future__ import annotations

from typing import TypeVar

import viser

from app.recording.replay import ReplaySource
from app.runtime import CONSTRAINT_KINDS, MAP_KINDS, Runtime
from app.runtime.snapshot import RunState, Snapshot
from app.ui.notify import guarded

T = TypeVar("T")


def _choice(value: str, options: tuple[T, ...]) -> T:
    """A dropdown's value as the option it is (a replay's dropdown shows 'replay', which is none)."""
    for option in options:
        if option == value:
            return option
    raise ValueError(f"{value!r} is not one of {', '.join(map(str, options))}")


ESTOP_HINT = "Zero velocity now; Start resumes the active subtask, Reset starts over"
CONTROL_HINT = ("Start resumes the subtask that was active after Pause, Stop, an emergency stop or a stale-state "
                "pause (a finished or failed sequence runs again); Skip gives up the active subtask for the "
                "next; Reset starts over: scene, map and progress")


class RunPanel:
    """The 'Run' folder; the emergency stop is a red button and the Escape hotkey."""

    def __init__(self, server: viser.ViserServer, runtime: Runtime | ReplaySource) -> None:
        self.server, self.runtime = server, runtime
        with server.gui.add_folder("Run"):
            self.estop = server.gui.add_button("EMERGENCY STOP (Esc)", color="red", icon=viser.Icon.HAND_STOP,
                                               hint=ESTOP_HINT)
            self.buttons = server.gui.add_button_group("Control", ("Start", "Pause", "Step", "Skip", "Stop", "Reset"),
                                                       hint=CONTROL_HINT)
            self.speed = server.gui.add_slider("Speed (×)", min=0.1, max=4.0, step=0.1,
                                               initial_value=runtime.config.speed)
            self.map_kind = server.gui.add_dropdown("Map", MAP_KINDS, initial_value=runtime.config.map_kind)
            self.constraint = server.gui.add_dropdown("Constraint", CONSTRAINT_KINDS,
                                                      initial_value=runtime.config.constraint)
        command = server.gui.add_command("Emergency stop", description="Zero velocity now", hotkey="escape")
        command.on_trigger(lambda _: self._estop())
        self.estop.on_click(lambda _: self._estop())
        self.buttons.on_click(guarded(server, "run control")(lambda e: self._control(e.target.value)))
        self.speed.on_update(guarded(server, "speed")(lambda _: runtime.set_speed(self.speed.value)))
        self.map_kind.on_update(guarded(server, "map kind")(
            lambda _: runtime.configure(map_kind=_choice(self.map_kind.value, MAP_KINDS))))
        self.constraint.on_update(
            guarded(server, "constraint kind")(
                lambda _: runtime.configure(constraint=_choice(self.constraint.value, CONSTRAINT_KINDS))))

    def hide_controls(self) -> None:
        """A replay has its own playback controls (`TimelinePanel`); map and constraint are the recorded ones."""
        for handle in (self.buttons, self.speed, self.map_kind, self.constraint):
            handle.visible = False

    def _estop(self) -> None:
        """The runtime says so to every browser (it also stops from the bridge): one notice, not two."""
        self.runtime.emergency_stop()

    def _control(self, action: str) -> None:
        {"Start": self.runtime.start, "Pause": self.runtime.pause, "Step": self.runtime.step,
         "Skip": self.runtime.skip, "Stop": self.runtime.stop, "Reset": self.runtime.reset}[action]()

    def update(self, snap: Snapshot) -> None:
        self.estop.disabled = snap.run_state == RunState.ESTOP
