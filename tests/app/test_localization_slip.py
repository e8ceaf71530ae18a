"""Slip and kidnap (issue 28, item 3) in the lockstep closed loop (real MuJoCo, whole sensor model, object map,
HTMPC, localization against the map the run builds): the odometry jumps once (0.5 m sideways or 30°) while the
robot drives; the registrations disagree, the localizer gets lost, the base stops, mapping pauses (no frame exposed
after the slip is integrated until the pose is found again), and the global search re-anchors within centimetres
of the truth, after which the run goes on and the map holds each box once where it is. Along a uniform wall the
search cannot be unique: the run faults with "lost localization" and the robot stops."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from app.runtime.snapshot import RunState
from core.params import LocalizationParams, SensorParams, SimParams
from core.scene import Box, Scene
from core.types import Observation
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.test_localization_loop import CORRIDOR, OUT_AND_BACK

AHEAD = replace(CORRIDOR, boxes=(*CORRIDOR.boxes[:6], Box("c1", (3.7, 0.9, 0.3)), Box("c2", (4.4, -0.1, 0.3)),
                                 Box("c3", (3.9, -1.1, 0.3))), name="corridor with boxes ahead")
"""The corridor with three boxes ahead at different depths: from its middle the base camera sees all three, so the
pose is unique within ±1 m and ±30° (at the corridor's end a single box face is all it sees, and it is not)."""
SLIP_AT_S = 2.5
"""On the way out, at about x = 1.4 m and 0.6 m/s, localized against the boxes ahead."""
LONG_WALL = Scene(tuple(Box(f"w{i}", (1.8, -4.8 + 0.6 * i, 0.3)) for i in range(17)), robot_start=(-2.0, 0.0, 0.0),
                  name="long wall")
"""A wall of 17 boxes side by side (its face at x = 1.5 m, y within ±5.1 m), the robot 3.5 m before it facing it: flat
and uniform along y, its ends out of view."""
TOWARD_THE_WALL = TaskSequence(subtasks=[BaseSubtask(name="toward", target=BasePose(x=0.2, y=0.0), timeout_s=60.0)])
SLIP_AT_WALL_S = 2.6
"""Localized against the wall since 2.1 s, at x = -0.6 m and 0.6 m/s."""


def _off_boxes(points: np.ndarray, scene: Scene) -> float:
    """How far (m) a mapped object's points lie from the scene's nearest box: the median over its points of the
    distance to that box's solid."""
    best = math.inf
    for b in scene.boxes:
        half = np.asarray(b.size, float) / 2
        outside = np.maximum(np.abs(np.asarray(points, float) - np.asarray(b.position, float)) - half, 0.0)
        best = min(best, float(np.median(np.linalg.norm(outside, axis=1))))
    return best


@dataclass
class Trace:
    """At every control step: robot time, the loop's pose, the true pose and the true base speed; and the exposure
    times of the frames the map integrated."""

    t: list[float] = field(default_factory=list)
    estimate: list[np.ndarray] = field(default_factory=list)
    truth: list[np.ndarray] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    integrated: list[float] = field(default_factory=list)

    def at(self, t0: float, t1: float = math.inf) -> np.ndarray:
        return np.array([t0 <= t <= t1 for t in self.t])

    def errors(self) -> tuple[np.ndarray, np.ndarray]:
        """x-y error (m) and heading error (rad) at every control step."""
        e, tr = np.array(self.estimate), np.array(self.truth)
        heading = (e[:, 2] - tr[:, 2] + math.pi) % (2 * math.pi) - math.pi
        return np.linalg.norm(e[:, :2] - tr[:, :2], axis=1), np.abs(heading)


def _run(scene: Scene, sequence: TaskSequence, slip: dict, slip_at_s: float, duration_s: float,
         localization: LocalizationParams | None = None, until_done: bool = True) -> tuple[Runtime, Trace]:
    sensor = replace(SensorParams(), slip_at_s=slip_at_s, **slip)
    config = RuntimeConfig(map_kind="object", seed=3, sim=replace(SimParams(), sensor=sensor),
                           localization=localization or LocalizationParams(enabled=True))
    rt = Runtime(config, scene=scene, sequence=sequence)
    trace = Trace()
    world_map = rt.closed_loop.map
    integrate = world_map.integrate

    def recorded(obs: Observation) -> None:  # the real map's integration, its frames' exposure times noted
        trace.integrated.extend(f.t for f in obs.frames)
        integrate(obs)

    world_map.integrate = recorded  # type: ignore[method-assign]

    def track(r: Runtime) -> None:
        truth = r.backend.true_state()  # type: ignore[attr-defined]
        trace.t.append(r.state.t)
        trace.estimate.append(r.state.q[:3].copy())
        trace.truth.append(truth.q[:3].copy())
        trace.speed.append(float(np.linalg.norm(truth.v[:2])))

    rt.run_lockstep(duration_s, until_done=until_done, on_control=track)
    return rt, trace


@pytest.mark.slow
@pytest.mark.parametrize("slip", [{"slip_m": (0.0, 0.5)}, {"slip_rad": math.radians(30.0)}],
                         ids=["0.5 m sideways", "30 degrees"])
def test_a_slip_while_driving_stops_the_base_pauses_mapping_and_the_search_finds_the_pose_again(slip):
    """Measured (seed 3, sideways / 30°): the first refused registration at the slip's first frame (2.5 s), lost at
    3.1 / 3.3 s, the base at rest by the control step at 3.72 / 3.92 s, one search on a frame at rest (best 0.995 /
    0.960 against a runner-up of 0.35 / 0.23), re-anchored at 4.4 / 4.6 s 4.7 / 4.4 cm from the truth (the view leaves
    the base's x weakly constrained: GICP from the true pose ends 2 cm off, from 3 cm behind it 5 cm off), at most
    7.3 / 7.9 cm afterwards; 42 / 46 frames dropped, none integrated from the slip to the re-anchoring, the sequence
    finished. Without the lost state and the frames' wait (`lost_after_s` inf, `hold_frames` off) the error stays
    0.51 / 0.52 m and the map places boxes up to 0.41 / 0.81 m off; with the lost state alone 38 frames at the jumped
    pose go in."""
    rt, trace = _run(AHEAD, OUT_AND_BACK, slip, SLIP_AT_S, 40.0)
    loop, loc = rt.closed_loop, rt.closed_loop.localizer
    assert loc is not None
    xy_error, heading_error = trace.errors()
    slipped = trace.at(SLIP_AT_S + 0.1, SLIP_AT_S + 0.5)
    assert xy_error[slipped].max() > 0.4 or heading_error[slipped].max() > math.radians(25), "the premise: a slip"

    # lost once, found by one search, and the run went on to the end of its sequence
    assert len(loc.lost.episodes) == 1, loc.lost.episodes
    episode = loc.lost.episodes[0]
    assert SLIP_AT_S - 1e-6 <= episode.refused_t <= episode.lost_t < SLIP_AT_S + 1.5
    assert np.isfinite(episode.anchored_t) and len(episode.searches) == 1 and episode.searches[0][1].unique
    assert loop.fault_reason is None and loop.run_state == RunState.FINISHED and rt.sequencer.finished

    # the base stopped while lost (braked to rest: the search waits for it)
    lost = trace.at(episode.lost_t, episode.anchored_t)
    assert lost.any() and min(np.array(trace.speed)[lost]) < 0.01, np.array(trace.speed)[lost]

    # mapping paused: no frame exposed after the slip went into the map until the pose was found again
    assert loop.frames_dropped > 0
    doubtful = [t for t in trace.integrated if SLIP_AT_S <= t <= episode.anchored_t]
    assert not doubtful, f"frames at a pose that had jumped were integrated: {doubtful[:5]}"

    # found again within centimetres, and kept there
    found = trace.at(episode.anchored_t + 0.05)
    first = int(np.argmax(found))
    assert xy_error[first] < 0.06 and heading_error[first] < math.radians(1.0), (xy_error[first], heading_error[first])
    assert xy_error[found].max() < 0.12, xy_error[found].max()

    # each box mapped once, where it is: none doubled, none at the slipped offset (judged by the object's points, not
    # its centre: a box seen from one side only has its centre 0.1-0.25 m off the true one, slip or not)
    objects = rt.map.snapshot().objects
    off = {o.id: round(_off_boxes(o.points, AHEAD), 3) for o in objects}
    assert max(off.values()) < 0.1, f"objects off every box (median of their points, m): {off}"
    assert len(objects) <= len(AHEAD.boxes)
    assert rt.closed_loop.problems.count(ProblemKind.LOCALIZATION) >= 1


@pytest.mark.slow
def test_a_slip_before_a_uniform_wall_cannot_be_found_uniquely_and_the_run_faults_lost_localization():
    """Driving toward the wall at 0.6 m/s the odometry slips 0.5 m forward: the registrations disagree across the wall
    (lost 0.6 s later), but every guess along the wall fits alike: measured best 1.00 against runners-up 1.00 0.4–1.0 m
    along it, in each of the five searches (the distance to the wall found to 3 cm). Run on after the sequence ends
    (the robot believes it reached its goal): the localizer keeps searching while the robot stands."""
    rt, trace = _run(LONG_WALL, TOWARD_THE_WALL, {"slip_m": (0.5, 0.0)}, SLIP_AT_WALL_S, 10.0, until_done=False)
    loop, loc = rt.closed_loop, rt.closed_loop.localizer
    assert loc is not None and len(loc.lost.episodes) == 1
    episode = loc.lost.episodes[0]
    p = loc.params
    assert len(episode.searches) == p.search_tries and not any(r.unique for _, r in episode.searches)
    assert not np.isfinite(episode.anchored_t)
    assert loop.run_state == RunState.FAULT and loop.fault_reason is not None
    assert loop.fault_reason.startswith("lost localization"), loop.fault_reason
    assert rt.closed_loop.problems.count(ProblemKind.FAULT) == 1
    # the robot has stopped: at rest from the first search on, and at the end
    searching = trace.at(episode.searches[0][0] + 0.5)
    assert searching.any() and max(np.array(trace.speed)[searching]) < 0.01
    assert np.linalg.norm(rt.backend.true_state().v[:3]) < 1e-3  # type: ignore[attr-defined]
    assert not [t for t in trace.integrated if t >= SLIP_AT_WALL_S], "mapping should have paused"
