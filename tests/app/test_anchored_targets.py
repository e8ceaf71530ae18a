"""Anchored targets in the closed loop (lockstep, MuJoCo), measured against the simulator's true box: the hand
follows a moved box, waits and times out when it is gone without entering where it was, and follows a box pushed
during the reach; never a collision. The binding, following, waiting and re-checking run on the ground-truth
map's objects; the accuracy of a pick on a moved box (issue 29, 6(a)) on the object map, through the whole
sensor model."""

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from app.runtime.snapshot import RunState
from core.scene import Box, Scene
from tasks.anchors import ObjectView, anchor_position
from tasks.schema import EEPose
from tasks.sequence_file import parse_sequence

PICK = """
objects: {{box_3: {{}}}}
subtasks:
- name: above box_3
  kind: ee
  target: {{anchor: {{object: box_3, face: top, offset: [-0.25, 0, 0.7], rpy_deg: [0, 90, 0]}}}}
  tolerance: {{position_m: 0.02, orientation_deg: 5}}
  timeout_s: {timeout}
  dwell_s: 1.0
"""


def runtime(timeout_s: float, map_kind: str = "ground_truth", seed: int = 0, size: str = "") -> Runtime:
    scene = Scene((Box("box_3", (2.5, 0.0, 0.3)), Box("far", (0.0, 4.0, 0.3))), robot_start=(0.0, 0.0, 0.0))
    text = PICK.format(timeout=timeout_s)
    if size:
        text = text.replace("objects: {box_3: {}}", f"objects: {{box_3: {{size: {size}}}}}")
    return Runtime(RuntimeConfig(map_kind=map_kind, seed=seed), scene=scene, sequence=parse_sequence(text))  # type: ignore[arg-type]


def true_target(rt: Runtime) -> tuple[np.ndarray, np.ndarray]:
    """The anchored pose on the simulator's box now: position and rotation."""
    box = rt.world.box("box_3")
    target = rt.sequence.subtasks[0].target
    obj = ObjectView("truth", "box_3", np.array(box.position), box.yaw, np.array(box.size))
    rpy = target.anchor.rpy_deg
    R = EEPose(position=(0, 0, 0), rpy_deg=(rpy[0], rpy[1], rpy[2] + np.degrees(box.yaw))).rotation()
    return anchor_position(target.anchor, obj), R


def ee_error(rt: Runtime) -> tuple[float, float]:
    """The hand's TRUE pose (the simulator's joints, not the drifting estimate) against the anchored pose on the
    true box."""
    backend = rt.backend
    q = backend.true_state().q if hasattr(backend, "true_state") else rt.state.q  # type: ignore[attr-defined]
    T = rt.robot.ee_pose(q)
    p, R = true_target(rt)
    angle = np.degrees(np.arccos(np.clip((np.trace(T[:3, :3].T @ R) - 1) / 2, -1, 1)))
    return float(np.linalg.norm(T[:3, 3] - p)), float(angle)


@pytest.mark.slow
def test_a_box_moved_half_a_metre_while_the_robot_approaches_is_followed():
    rt = runtime(40.0)
    moved: list[float] = []

    def move(r: Runtime) -> None:
        if not moved and r.time >= 2.0:
            r.move_box("box_3", (2.5, 0.5, 0.3))
            moved.append(r.time)

    rt.run_lockstep(45.0, on_control=move)
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    pos, ang = ee_error(rt)
    assert pos <= 0.02 and ang <= 5.0, (pos, ang)
    assert len(rt.world.collisions) == 0


@pytest.mark.slow
@pytest.mark.parametrize(("move_m", "seed"), [(0.5, 0), (0.5, 2), (0.0, 1)])
def test_on_the_object_map_a_pick_on_a_box_of_known_size_ends_on_the_true_box(move_m, seed):
    """Issue 29, 6(a), perceived: the box moved 0.5 m at 2 s (or not at all), the object map through the whole
    sensor model (noise, flying pixels, drifting odometry), its size declared with its name. Seen from its front
    only, the box is mapped 0.49-0.55 m deep, 2-5 cm near (the far strip of its top is seen only in passing, out of
    the hand camera's view at the goal): the anchor keeps the seen front face and the known depth. On seed 2 the
    map first fuses the old and new places into one 1.02 m box: the pick does not complete until it settles."""
    rt = runtime(40.0, map_kind="object", seed=seed, size="[0.6, 0.6, 0.6]")
    moved: list[float] = []
    unsettled: list[str] = []

    def move(r: Runtime) -> None:
        if move_m and not moved and r.time >= 2.0:
            r.move_box("box_3", (2.5, move_m, 0.3))
            moved.append(r.time)
        if "not settled" in r.sequencer.progress[0].message:
            unsettled.append(r.sequencer.progress[0].message)

    rt.run_lockstep(45.0, on_control=move)
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    pos, ang = ee_error(rt)
    assert pos <= 0.02 and ang <= 5.0, (pos, ang, unsettled[-1:])
    assert len(rt.require_world().collisions) == 0
    if seed == 2:
        assert unsettled, "the fused box was expected on this seed (the map's behaviour changed?)"


@pytest.mark.slow
def test_a_removed_box_makes_the_subtask_wait_and_time_out_without_entering_its_place():
    rt = runtime(8.0)
    former = rt.world.box("box_3")
    hand: list[np.ndarray] = []
    reasons: list[str] = []

    def remove(r: Runtime) -> None:
        if r.time >= 2.0 and any(b.id == "box_3" for b in r.world.boxes()):
            r.remove_box("box_3")
        hand.append(r.robot.ee_pose(r.state.q)[:3, 3])
        reasons.append(r.sequencer.progress[0].message)

    rt.run_lockstep(15.0, on_control=remove)
    assert rt.run_state == RunState.FAILED
    assert rt.sequencer.progress[0].message == "timed out after 8 s: box_3 not in the map"
    assert "box_3 not in the map: waiting" in reasons
    lo = np.array(former.position) - np.array(former.size) / 2
    hi = np.array(former.position) + np.array(former.size) / 2
    inside = [np.all((p >= lo) & (p <= hi)) for p in hand]
    assert not any(inside)
    assert len(rt.world.collisions) == 0


@pytest.mark.slow
def test_a_box_pushed_during_the_reach_is_followed_without_collision():
    rt = runtime(40.0)
    pushed: list[float] = []
    closest: list[float] = []

    def push(r: Runtime) -> None:
        if not pushed and np.isfinite(r.sequencer.progress[0].position_error_m) \
                and r.sequencer.progress[0].position_error_m < 0.3:
            r.move_box("box_3", (2.8, 0.0, 0.3))  # pushed 0.3 m away while the hand comes down on it
            pushed.append(r.time)
        closest.append(r.min_distance_m)

    rt.run_lockstep(45.0, on_control=push)
    assert pushed, "the reach never came within 0.3 m"
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    pos, ang = ee_error(rt)
    assert pos <= 0.02 and ang <= 5.0, (pos, ang)
    assert len(rt.world.collisions) == 0 and np.nanmin(closest) > 0.0


@pytest.mark.slow
def test_an_anchored_target_moved_out_of_reach_is_a_problem_with_its_reason():
    scene = Scene((Box("box_3", (3.0, 0.0, 0.3)), Box("blocker", (5.0, 2.0, 0.3))), robot_start=(0.0, 0.0, 0.0))
    seq = parse_sequence("""
objects: {box_3: {}}
subtasks:
- kind: base
  target: {anchor: {object: box_3, face: front, offset: [-0.9, 0, 0]}}
""")
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=scene, sequence=seq)
    messages: list[str] = []
    rt.subscribe(lambda snap: messages.extend(snap.messages))

    def move(r: Runtime) -> None:
        if r.time >= 1.0 and r.world.box("box_3").position[0] < 4.0:
            r.move_box("box_3", (6.0, 2.0, 0.3))  # its front goal (4.8, 2.0) is now beside the blocker

    rt.run_lockstep(2.0, until_done=False, publish_every=1, on_control=move)
    counts = {c.kind: c for c in rt.problems.counts()}
    problem = counts[ProblemKind.ANCHORED_TARGET]
    assert "blocker" in problem.last_message and "its object moved" in problem.last_message
    assert any(m.startswith("box_3 moved 3.") and m.endswith(": target follows") for m in messages)
