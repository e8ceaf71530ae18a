"""The reaction's chain through the hardware bridge: the embedded chain (`bench/reaction_chain.py`) read from the
same stage stamps, with the two hops the bridge adds.

The physics and the cameras run in the driver's process (`bench/reaction_driver.py`); it places the box, stamps
its own cycles and the commands it applies, on the wall clock both processes share. The parts, consecutive so that
they add up to the whole:

- `frame_wait`, `exposure_to_stamp`: as embedded, on the driver's cycles (its physics steps, 10 ms apart: the
  embedded figure reads the runtime's physics loop, 10 ms apart too);
- `link`: the frame's stamp → its arrival at the bridge (the driver encodes and sends it, the bridge's event loop
  receives and validates it: `RobotLink.accept_frame`);
- `mapping`: → the EDF built after it starts (the runtime's I/O loop picks it up, the mapping thread and process
  integrate it): the embedded `mapping` minus `link`;
- `edf`, `control_wait`, `references`, `solve`, `command`: as embedded; `command` ends when the runtime hands the
  first slowed command to the bridge;
- `delivery`: → the driver applies it (the bridge's outbox, the WebSocket, the driver's next control cycle; the
  first command the driver applied computed from that state or a later one: commands are latest-wins).

`total` (placement → the robot obeys) is the bridge's reaction; `issued` stops at the command handed to the bridge
(the embedded figure's end: there the command reaches the simulated robot at once). `processing` is everything
after the frame's stamp: `link` to `delivery`. The driver's camera stamps its frames 20 ms after their exposure
(`SensorParams.camera_time_offset_s`) as the embedded one does; the runtime is told that latency
(`MappingParams.camera_latency_s`, as docs/bridge.md asks of a real driver).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from app.runtime.stage_stamps import StageStamps
from bench.reaction_chain import Placement, Reaction, carrying_integration, reacting_command

BRIDGE_PARTS = ("frame_wait", "exposure_to_stamp", "link", "mapping", "edf", "control_wait", "references", "solve",
                "command", "delivery")
BRIDGE_PROCESSING = BRIDGE_PARTS[2:]
"""The parts after the frame's stamp."""
MATCH_S = 1e-6
"""Robot times closer than this are the same moment (a frame's stamp as the driver sent it and as the map has it)."""


@dataclass(frozen=True)
class BridgeReaction:
    """One reaction through the bridge: its parts (ms, in `BRIDGE_PARTS` order), the whole to the robot obeying,
    the whole to the command handed to the bridge, and the embedded chain's reading of it."""

    parts_ms: dict[str, float]
    total_ms: float
    issued_ms: float
    chain: Reaction

    @property
    def processing_ms(self) -> float:
        return sum(self.parts_ms[k] for k in BRIDGE_PROCESSING)


@dataclass
class LinkStamps:
    """What the bridge's stamps do not hold: frames' arrival at the bridge (camera, robot time, wall) and the
    commands the driver applied (robot time, wall)."""

    arrivals: deque[tuple[str, float, float]]
    applied: deque[tuple[float, float]]

    @staticmethod
    def keeping(n: int) -> LinkStamps:
        return LinkStamps(deque(maxlen=n), deque(maxlen=n))

    def arrival(self, camera: str, t: float) -> float | None:
        """Wall time the frame of `camera` stamped `t` arrived at the bridge (None: not in the history)."""
        return next((wall for cam, ft, wall in list(self.arrivals) if cam == camera and abs(ft - t) < MATCH_S), None)

    def obeyed(self, t: float, wall: float) -> float | None:
        """Wall time the driver applied the first command of robot time >= `t` after `wall` (None: not yet)."""
        return next((w for ct, w in list(self.applied) if ct + MATCH_S >= t and w >= wall), None)


def bridge_analyse(stamps: StageStamps, link: LinkStamps, placement: Placement, chain: Reaction, voxel_m: float,
                   range_m: float) -> BridgeReaction | str:
    """The reaction to `placement` through the bridge, from its embedded reading `chain`; or why it cannot be read
    (yet)."""
    command = reacting_command(stamps, placement)
    carried = carrying_integration(stamps, placement, voxel_m, range_m)
    if command is None or carried is None:
        return "the reacting command or frame left the history"
    frame = carried[1]
    arrived = link.arrival(frame.camera, frame.stamp_t)
    obeyed = link.obeyed(command.t, command.wall)
    if arrived is None or obeyed is None:
        return "the frame's arrival is not in the history" if arrived is None else "the driver has not applied it yet"
    stamped = placement.wall + (chain.parts_ms["frame_wait"] + chain.parts_ms["exposure_to_stamp"]) / 1e3
    link_ms = (arrived - stamped) * 1e3
    parts = dict(chain.parts_ms)
    parts |= {"link": link_ms, "mapping": parts["mapping"] - link_ms, "delivery": (obeyed - command.wall) * 1e3}
    return BridgeReaction({k: parts[k] for k in BRIDGE_PARTS}, (obeyed - placement.wall) * 1e3, chain.total_ms, chain)
