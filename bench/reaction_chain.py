"""From a box placed in front of the driving robot to the first command that slows it: the chain of stages, read
from the live loops' stage stamps (`app/runtime/stage_stamps.py`) after the fact.

The reaction is the first command after the placement whose velocity towards the box has dropped by at least
`DROP_MPS` below the command at the placement. It is a real reaction only if the plan it came from was solved on
an EDF that holds the box (its face towards the robot within one EDF voxel), so a slowdown for any other reason
(the end of the path, a re-plan) is never counted. Its parts, consecutive on the wall clock, so that they add up
to the whole by construction and each is >= 0 only if the stages really happened in that order:

- `frame_wait`: placement → exposure of the first frame that has the box in view (the physics step that rendered
  it);
- `exposure_to_stamp`: → the frame's stamp (the camera's latency: it is delivered then);
- `mapping`: → the map process has integrated it (I/O pickup, the mapping thread's queue, the hand-over to the
  process, the integration), up to the EDF built after it;
- `edf`: → that EDF handed back (its build time in the map process);
- `control_wait`: → the first control step holding an EDF with the box has it in hand;
- `references`: → the sequencer's references (and any re-plan of the base path) are made;
- `solve`: → the HTMPC's plan is ready;
- `command`: → the first command that has slowed by `DROP_MPS` (the I/O loop's next tick, and the plan's own
  deceleration until it has dropped that much; a later plan when the first one slowed less).

`processing` is the part after the frame's stamp (mapping to command). Times are wall-clock (the live loops run on
it; the simulation's physics is paced to it); the same reaction in simulated time is `sim_ms` (the robot time of
the reacting command minus the placement's), which equals the wall figure only while the physics keeps pace.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.runtime.stage_stamps import CommandStamp, ControlStamp, FrameStamp, IntegrationStamp, StageStamps
from core.types import LocalEDF

DROP_MPS = 0.05
"""A command has reacted once its velocity towards the box is this much below the one at the placement."""
PARTS = ("frame_wait", "exposure_to_stamp", "mapping", "edf", "control_wait", "references", "solve", "command")
PROCESSING = PARTS[2:]
"""The parts after the frame's stamp."""


@dataclass(frozen=True)
class Placement:
    """A box put in the robot's way: when (wall and robot s), where (points on it, and the point of its face towards
    the robot), the unit direction from the base to it, the commanded velocity towards it then and its barrier."""

    wall: float
    t: float
    points: np.ndarray
    """Points on the box (its centre, the corners of its faces: P×3): a frame that has any in view sees it."""
    face: np.ndarray
    towards: np.ndarray
    v_before_mps: float
    h_m: float
    """The base's true distance to the box minus delta_safe (the CBF's h when it appears)."""


@dataclass(frozen=True)
class Reaction:
    """One measured reaction: its parts (ms, in `PARTS` order), the whole on the wall clock and in robot time."""

    parts_ms: dict[str, float]
    total_ms: float
    sim_ms: float
    v_before_mps: float
    v_after_mps: float
    h_m: float
    camera: str
    later_plans: int
    """Control steps between the first that held the box and the one whose plan's command reacted (0: itself)."""
    unseen_frames: int
    """Frames with the box in view integrated before the one that brought it into the EDF (0: the first did)."""
    mapping_queue_ms: float = float("nan")
    """Of `mapping`: the frame's stamp → the integration's start (I/O pickup and the mapping thread's queue); the
    rest is the hand-over to the map process and the integration."""

    @property
    def processing_ms(self) -> float:
        return sum(self.parts_ms[k] for k in PROCESSING)


def towards_mps(command: CommandStamp, towards: np.ndarray) -> float:
    return float(np.dot(command.base_v, towards))


def holds_box(edf: LocalEDF | None, face: np.ndarray, voxel_m: float) -> bool:
    """Whether `edf` has the box: its face towards the robot within one voxel of a surface."""
    return edf is not None and float(edf.distance(face)) <= voxel_m


def reacting_command(stamps: StageStamps, placement: Placement) -> CommandStamp | None:
    """The first command after the placement slowed by `DROP_MPS` towards the box (None: none yet)."""
    for command in list(stamps.commands):
        slowed = towards_mps(command, placement.towards) <= placement.v_before_mps - DROP_MPS
        if command.wall > placement.wall and slowed:
            return command
    return None


def _seeing(frames: tuple[FrameStamp, ...], placement: Placement, range_m: float) -> list[FrameStamp]:
    """The frames exposed after the placement with the box in view."""
    return [f for f in frames if f.exposure_t > placement.t + 1e-9 and f.sees(placement.points, range_m)]


def carrying_integration(stamps: StageStamps, placement: Placement, voxel_m: float, range_m: float
                         ) -> tuple[IntegrationStamp, FrameStamp] | None:
    """The first integration after the placement whose EDF holds the box, and its earliest frame with the box in
    view (None: the EDF holds it, but no frame of it saw the box: a box the map had before, not a reaction)."""
    for integration in list(stamps.integrations):
        if integration.wall_end > placement.wall and holds_box(integration.edf, placement.face, voxel_m):
            seen = _seeing(integration.frames, placement, range_m)
            return (integration, min(seen, key=lambda f: f.exposure_t)) if seen else None
    return None


def first_control_holding(stamps: StageStamps, placement: Placement, voxel_m: float) -> ControlStamp | None:
    """The first control step after the placement whose EDF holds the box and that made a plan."""
    for step in list(stamps.controls):
        if step.wall_wake > placement.wall and step.plan is not None and holds_box(step.edf, placement.face, voxel_m):
            return step
    return None


def analyse(stamps: StageStamps, placement: Placement, voxel_m: float, range_m: float) -> Reaction | str:
    """The reaction to `placement`, or why there is none (yet) or it is no real reaction."""
    command = reacting_command(stamps, placement)
    if command is None:
        return "no command has slowed yet"
    controls = list(stamps.controls)
    source = next((s for s in controls if s.plan is not None and s.plan is command.plan), None)
    if source is None:
        return "the reacting command's plan is not in the history"
    if source.wall_wake <= placement.wall or not holds_box(source.edf, placement.face, voxel_m):
        when = "before the box appeared" if source.wall_wake <= placement.wall else "without the box in its EDF"
        return (f"not a reaction: the command slowed from {placement.v_before_mps:.2f} to "
                f"{towards_mps(command, placement.towards):.2f} m/s {(command.wall - placement.wall) * 1e3:.0f} ms "
                f"after the placement, on a plan made {when}")
    carried = carrying_integration(stamps, placement, voxel_m, range_m)
    first = first_control_holding(stamps, placement, voxel_m)
    if carried is None or first is None:
        return ("the map held something at the box's face before any frame saw the box (an earlier box's remains)"
                if first is not None else "no control step holds the box")
    integration, frame = carried
    exposed, stamped = stamps.wall_at(frame.exposure_t), stamps.wall_at(frame.stamp_t)
    if exposed is None or stamped is None:
        return "the frame's physics steps are not in the history"
    edf_ready = integration.wall_end
    points = [placement.wall, exposed, stamped, edf_ready - integration.edf_ms / 1e3, edf_ready, first.wall_edf,
              first.wall_solve_start, first.wall_solve_end, command.wall]
    parts = {name: (b - a) * 1e3 for name, a, b in zip(PARTS, points[:-1], points[1:], strict=True)}
    earlier = [f for i in list(stamps.integrations) if placement.wall < i.wall_end < integration.wall_end
               for f in _seeing(i.frames, placement, range_m)]
    return Reaction(parts, (command.wall - placement.wall) * 1e3, (command.t - placement.t) * 1e3,
                    placement.v_before_mps, towards_mps(command, placement.towards), placement.h_m, frame.camera,
                    sum(1 for s in controls if first.wall_wake < s.wall_wake <= source.wall_wake), len(earlier),
                    (integration.wall_start - stamped) * 1e3)
