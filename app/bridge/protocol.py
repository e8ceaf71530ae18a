"""Every message the bridge exchanges, as pydantic models: the robot link and the operator API.

Robot link (`/robot` WebSocket, `docs/bridge.md`): JSON text messages `hello`, `state` and `ack` from
the driver, `welcome`, `command` and `error` to it; depth frames travel as binary messages whose
header is a `DepthFrameHeader` (layout in `depth_framing`). Every model forbids unknown fields and
non-finite numbers, fixes vector lengths and is strict (no booleans or strings for numbers, no 5.0 for
an integer), so a malformed message never reaches the runtime.

Operator API (`/api/...`): requests and responses of the routes in `app.bridge.routes`. Responses
carry `None` where the runtime holds NaN (JSON has no NaN).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError

from app.map_kind import MapKind
from core.params import ConstraintKind
from core.types import NQ

PROTOCOL_VERSION = 1
STALE_AFTER_S = 0.15
"""State older than this (by its arrival at the bridge) is stale: the bridge commands zero velocity. Below
the 200 ms within which a dead driver must get zero: a driver whose connection drops without a close (a
pulled cable, a frozen process, or a kill the server's loop sees late under load) is caught by age
alone, and the last state arrived up to one state period (10–20 ms) before the loss."""
STATE_LIMIT = 1e6
"""Largest magnitude accepted for a joint position or velocity (anything larger is a driver bug)."""

Finite = Annotated[float, Field(allow_inf_nan=False)]
Bounded = Annotated[float, Field(ge=-STATE_LIMIT, le=STATE_LIMIT, allow_inf_nan=False)]
JointVector = Annotated[list[Bounded], Field(min_length=NQ, max_length=NQ)]
Vec3 = Annotated[list[Bounded], Field(min_length=3, max_length=3)]
Row3 = Annotated[list[Finite], Field(min_length=3, max_length=3)]
Row4 = Annotated[list[Finite], Field(min_length=4, max_length=4)]
Matrix3 = Annotated[list[Row3], Field(min_length=3, max_length=3)]
Matrix4 = Annotated[list[Row4], Field(min_length=4, max_length=4)]
Name = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.\-]+$")]


class Message(BaseModel):
    """Base of every message: unknown fields, NaN/inf and loose types are errors; values are immutable."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True, strict=True)


# --- robot link: driver → bridge ------------------------------------------------------------------


class Hello(Message):
    """Optional first message of a driver: who it is and which protocol it speaks."""

    type: Literal["hello"] = "hello"
    driver: Annotated[str, Field(min_length=1, max_length=100)]
    protocol: Annotated[int, Field(ge=PROTOCOL_VERSION, le=PROTOCOL_VERSION)] = PROTOCOL_VERSION
    """An integer (`Literal[1]` would let `true` and `1.0` through: they compare equal to 1)."""


class OdometryIn(Message):
    """Base pose (x, y, yaw) and world-frame twist as the base's odometry reports them."""

    pose: Vec3
    twist: Vec3


PoseSourceIn = Literal["odometry", "localized"]
"""What a driver's base pose is (`core.types.PoseSource`): its wheel odometry (the runtime localizes it when
localization is on) or a pose the robot localized itself (its own SLAM; used as it is)."""


class StateMessage(Message):
    """Joint state at robot time t (s, a steady clock): q[9] = [x, y, yaw, 6 arm joints], v[9] their rates;
    `pose_source` says what the base pose (and the depth frames' poses) are (default: odometry)."""

    type: Literal["state"] = "state"
    t: Bounded
    q: JointVector
    v: JointVector
    odometry: OdometryIn | None = None
    pose_source: PoseSourceIn = "odometry"


class Ack(Message):
    """The driver received command `seq` at its time t (s); the bridge measures the round trip."""

    type: Literal["ack"] = "ack"
    seq: Annotated[int, Field(ge=0)]
    t: Finite


DriverText = Annotated[Hello | StateMessage | Ack, Field(discriminator="type")]
DRIVER_TEXT = TypeAdapter(DriverText)
"""Validates any JSON text message from a driver."""


DepthEncoding = Literal["float32_m", "uint16_mm"]
"""How a depth frame's pixels are sent: float32 metres or uint16 millimetres."""
RejectionCode = Literal["bad_json", "invalid_message", "invalid_state", "invalid_frame", "stale_ack"]
"""Why the bridge rejected a driver's message."""


class DepthFrameHeader(Message):
    """JSON header of a binary depth-frame message; the pixels follow it (see `depth_framing`)."""

    type: Literal["depth"] = "depth"
    t: Bounded
    camera: Name
    width: Annotated[int, Field(ge=1, le=4096)]
    height: Annotated[int, Field(ge=1, le=4096)]
    encoding: DepthEncoding = "float32_m"
    K: Matrix3
    T_world_camera: Matrix4
    range_m: Annotated[float, Field(gt=0.0, le=100.0)] = 3.0


# --- robot link: bridge → driver ------------------------------------------------------------------


class Welcome(Message):
    """First message to an accepted driver: what the bridge expects of it."""

    type: Literal["welcome"] = "welcome"
    protocol: int = PROTOCOL_VERSION
    joints: int = NQ
    state_rate_hz: tuple[float, float] = (50.0, 100.0)
    frame_rate_hz: tuple[float, float] = (5.0, 10.0)
    command_rate_hz: float = 100.0
    stale_after_s: float = STALE_AFTER_S


CommandReason = Literal["runtime", "not_running", "emergency_stop", "stale_state", "invalid_command", "shutdown"]
"""Why a command was sent: `runtime` is the controller's command (it may be zero); every other reason
comes with zero velocity. docs/bridge.md lists them; a test checks that list against this one."""


class Command(Message):
    """Joint velocity command: qdot[9] (base x, y, yaw rates in the world frame; arm joint rates).

    `t` is the robot time of the state it was computed from; `seq` counts up and is acknowledged;
    `reason` says why the bridge sent it ('runtime': the controller's command; anything else: zero).
    """

    type: Literal["command"] = "command"
    seq: Annotated[int, Field(ge=0)]
    t: Finite
    qdot: JointVector
    reason: CommandReason = "runtime"


class ErrorMessage(Message):
    """A message of the driver was rejected (and counted); nothing of it was passed on."""

    type: Literal["error"] = "error"
    code: RejectionCode
    message: str
    count: int


BridgeText = Annotated[Welcome | Command | ErrorMessage, Field(discriminator="type")]
BRIDGE_TEXT = TypeAdapter(BridgeText)
"""Validates any JSON text message from the bridge (drivers use it)."""


def validation_text(err: ValidationError) -> str:
    """The errors of a rejected message on one line: 'field.path: message; ...'."""
    return "; ".join(f"{'.'.join(str(x) for x in e['loc']) or '<message>'}: {e['msg']}" for e in err.errors())


# --- operator API: responses ----------------------------------------------------------------------


def finite_or_none(x: float) -> float | None:
    """JSON has no NaN: a non-finite number becomes None."""
    return float(x) if math.isfinite(x) else None


class Problem(BaseModel):
    """One problem of a rejected file: dotted field, 1-based line (None if unknown), message."""

    field: str
    line: int | None
    message: str


class ErrorOut(BaseModel):
    """An error response: what went wrong, and the problems of a rejected sequence."""

    detail: str
    problems: list[Problem] = []


class LinkCounters(BaseModel):
    """What went through the robot link since the server started."""

    states: int
    frames: int
    frames_dropped: int
    commands_sent: int
    commands_superseded: int
    acks: int
    rejected: dict[str, int]
    stale_events: int


LocalizedBy = Literal["off", "localizer", "driver"]
"""Who localizes the base pose the runtime uses: nobody (odometry as it is), the runtime's localizer (it corrects
the driver's odometry), the driver itself (its `pose_source` is `localized`: used as it is)."""


class Health(BaseModel):
    """Is the bridge alive, is a driver connected and fresh, what was rejected; what its pose is and who localizes
    it."""

    status: Literal["ok"] = "ok"
    protocol: int = PROTOCOL_VERSION
    driver_connected: bool
    driver: str | None
    state_age_ms: float | None
    stale: bool
    hold: str | None
    runtime_attached: bool
    run_state: str | None
    counters: LinkCounters
    command_rtt_median_ms: float | None
    command_rtt_p99_ms: float | None
    pose_source: PoseSourceIn | None = None
    """The `pose_source` of the driver's latest state (None before any)."""
    localized_by: LocalizedBy | None = None
    """Who localizes the pose the runtime uses (None without a runtime attached)."""


class LocalizationOut(BaseModel):
    """Who localizes the base pose the runtime uses, and the health of the runtime's estimate when it is the
    localizer's (`core/localization/health.py`; every number None otherwise)."""

    by: LocalizedBy
    accepted: int | None = None
    """Registrations accepted (corrections) since the start."""
    rejected: int | None = None
    degenerate: int | None = None
    no_reference: int | None = None
    sigma_xy_m: float | None = None
    """The largest position std of the estimate (m)."""
    since_accepted_s: float | None = None
    """Robot time since the last accepted correction (since the start before the first)."""
    untrusted: str | None = None
    """Why the localizer's pose is untrusted now (None: trusted, or not the localizer's)."""


class RobotStateOut(BaseModel):
    """The runtime's robot state (the driver's latest accepted state)."""

    t: float
    q: list[float]
    v: list[float]
    run_state: str
    status: str
    fault: str | None = None
    """Why the run is in the `fault` run state (a loop failed or the state was not finite); null otherwise."""
    pose_source: PoseSourceIn = "odometry"
    """What the robot reports as its base pose (the driver's `pose_source`)."""
    localization: LocalizationOut | None = None
    """Who localizes the pose in `q`, and the localizer's health."""


class PlanOut(BaseModel):
    """The active HTMPC plan: predicted q, v (N+1 × 9), u (N × 9), Cartesian paths, diagnostics."""

    t: float
    dt: float
    q: list[list[float | None]]
    v: list[list[float | None]]
    u: list[list[float | None]]
    base_path: list[list[float | None]]
    ee_path: list[list[float | None]]
    task_errors: list[float | None]
    solve_ms: list[float | None]
    status: str
    message: str
    reason: str
    """Why the plan is what it is, for programs (`core.types.PlanReason`: none, no_task, qp_failed, …)."""
    min_h: float | None


class PlanResponse(BaseModel):
    """The current plan, None when the controller has none (idle, finished, stopped)."""

    run_state: str
    plan: PlanOut | None


class SubtaskProgressOut(BaseModel):
    """How one subtask is going (errors None until measured)."""

    index: int
    name: str
    kind: str
    outcome: str
    elapsed_s: float | None
    held_s: float | None
    position_error_m: float | None
    orientation_error_deg: float | None
    message: str
    no_path: bool = False
    """The planner found no path to the goal on the current map: the robot holds (skip with /api/run/skip)."""
    blocked: bool = False
    """The base has made no progress for `SequencerParams.stall_s`; `message` names the nearest obstacle."""
    anchor_object: str | None = None
    """The named object the subtask's goal is anchored on (null: a world or base-frame goal)."""
    anchor: str = ""
    """The anchor as the studio shows it, e.g. 'top of box_a + (0, -0.25, 0.7)'."""
    anchored_goal: list[float] | None = None
    """Where the anchored goal is placed now (world x, y, z in m: an EE position, or a base goal at z 0); null
    while its object cannot be placed (`message` says why) or when not anchored."""


class ProgressOut(BaseModel):
    """Progress of the sequence: the active subtask and every subtask's outcome."""

    run_state: str
    status: str
    active_index: int
    subtasks: list[SubtaskProgressOut]


class RunStatus(BaseModel):
    """Run state after a run-control request."""

    run_state: str
    status: str
    fault: str | None = None
    """Why the run is faulted (Start is refused until Reset); null otherwise."""


class SequenceOut(BaseModel):
    """The authored sequence: its name, subtasks and YAML text; `warnings` from the target checks."""

    name: str
    version: int
    subtasks: int
    yaml: str
    warnings: list[str] = []


class ValidationOut(BaseModel):
    """Outcome of validating a sequence: valid, or the problems with field and line."""

    valid: bool
    name: str | None = None
    subtasks: int = 0
    problems: list[Problem] = []
    warnings: list[str] = []


class BoxOut(BaseModel):
    """A box of the simulated scene: centre position (m), full size (m), yaw (rad)."""

    id: str
    position: list[float]
    size: list[float]
    yaw: float


class MappedObjectOut(BaseModel):
    """An object the map sees (with the ground-truth map, a scene box): `id` as the API takes it (`object_4`; a
    box id), `label` as the studio shows it ('#4'), the operator's `name` (null: unnamed), centre `position` (m),
    `yaw_deg`, full `extent` (m, along its own axes), E[v] `consistency`, `status`; `size`: its known full size (m)
    if named (declared, or measured while both faces of an axis were seen; null where unknown)."""

    id: str
    label: str
    name: str | None
    position: list[float]
    yaw_deg: float
    extent: list[float]
    consistency: float
    status: str
    size: list[float | None] | None = None


class ObjectsOut(BaseModel):
    """The objects the map sees now, and why a name has no object (`unresolved`: name → reason, e.g. 'box_3 not in
    the map', 'box_3: 2 candidates')."""

    t: float
    map_kind: str
    objects: list[MappedObjectOut]
    unresolved: dict[str, str] = {}


class SceneOut(BaseModel):
    """The simulated scene (only when the runtime simulates)."""

    name: str
    robot_start: list[float]
    boxes: list[BoxOut]


# --- operator API: requests -----------------------------------------------------------------------

Position = Annotated[float, Field(ge=-50.0, le=50.0, allow_inf_nan=False)]
Size = Annotated[float, Field(ge=0.01, le=5.0, allow_inf_nan=False)]
Yaw = Annotated[float, Field(ge=-10.0, le=10.0, allow_inf_nan=False)]


class SequenceIn(Message):
    """A task sequence as YAML text (the format of `tasks/examples/*.yaml`). Its targets are checked against the
    robot and the scene; `scene_may_change` accepts targets too close to today's boxes with a warning."""

    yaml: Annotated[str, Field(max_length=1_000_000)]
    scene_may_change: bool = False


class StepIn(Message):
    """Advance a paused run by `seconds` (default: one control period)."""

    seconds: Annotated[float, Field(gt=0.0, le=10.0)] | None = None


class ConfigIn(Message):
    """Switch the map kind, the constraint kind or the live speed (omitted: unchanged)."""

    map_kind: MapKind | None = None
    constraint: ConstraintKind | None = None
    speed: Annotated[float, Field(ge=0.05, le=20.0)] | None = None


class BoxIn(Message):
    """A box to add: id, centre position (m), full size (m), yaw (rad)."""

    id: Name
    position: Annotated[list[Position], Field(min_length=3, max_length=3)]
    size: Annotated[list[Size], Field(min_length=3, max_length=3)] = [0.6, 0.6, 0.6]
    yaw: Yaw = 0.0


class BoxMoveIn(Message):
    """Where a box goes: centre position (m) and optional yaw (rad; omitted: unchanged)."""

    position: Annotated[list[Position], Field(min_length=3, max_length=3)]
    yaw: Yaw | None = None


class NameIn(Message):
    """A name for a mapped object (a sequence's `objects` key: a letter or _ first) and its full size (m, along its
    x, y, z, x and y either way round; omitted: unknown)."""

    name: Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$")]
    size: Annotated[list[Size], Field(min_length=3, max_length=3)] | None = None


class RandomiseIn(Message):
    """The paper's random scene from a seed (the robot goes back to its start)."""

    seed: Annotated[int, Field(ge=0, le=2**31 - 1)]
    n_boxes: Annotated[int, Field(ge=1, le=16)] = 8
    """At most 16: the generator places 0.6 m boxes 0.9 m apart in 5 × 5 m and cannot place many more."""
