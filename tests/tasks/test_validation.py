"""Target checks at authoring time: each rule refuses with a reason and a nearest value that passes, scene
rules turn into warnings when the operator says the scene will change, and the shipped examples pass."""

import numpy as np
import pytest

from core.scene import load_scene
from tasks import BasePose, BaseSubtask, EEPose, EESubtask, TaskSequence, load_sequence
from tasks.sequence_file import EXAMPLES_DIR, sequence_to_yaml
from tasks.validation import (
    Obstacle,
    RobotEnvelope,
    Rule,
    Severity,
    TargetError,
    box_distance,
    changed_subtasks,
    check_sequence,
    require_valid,
)

BOX = Obstacle("box_b", (2.0, 1.0, 0.3), (0.6, 0.6, 0.6), 0.3)


@pytest.fixture(scope="module")
def env(robot):
    return RobotEnvelope.of(robot, delta_safe_m=0.25)


def one(sub) -> TaskSequence:
    return TaskSequence(subtasks=[sub])


def test_envelope_numbers(env):
    assert env.base_clearance_m == pytest.approx(0.80)  # the planner's inflation
    assert env.base_top_m == pytest.approx(0.92 + 0.25)  # the rack's top + delta_safe
    assert env.shoulder_m == pytest.approx([0.27, 0.0, 0.78], abs=0.01)
    assert 1.15 < env.reach_m < 1.3 and env.wrist_reach_m < env.reach_m
    assert {name for name, _, _ in env.hand} == {"wrist_3", "tool"}


def test_box_distance_is_signed_and_follows_yaw():
    assert box_distance(BOX, np.array([2.0, 1.0, 0.3])) == pytest.approx(-0.3)
    assert box_distance(BOX, np.array([2.0, 1.0, 1.1])) == pytest.approx(0.5)
    corner = np.array(BOX.position[:2]) + 0.3 * np.array([np.cos(0.3) - np.sin(0.3), np.sin(0.3) + np.cos(0.3)])
    assert box_distance(BOX, corner) == pytest.approx(0.0, abs=1e-9)


def test_base_goal_inside_the_clearance_is_refused_with_the_nearest_clear_goal(env):
    findings = check_sequence(one(BaseSubtask(target=BasePose(x=2.0, y=0.3))), [BOX], env)
    (f,) = findings
    assert f.rule == Rule.BASE_CLEARANCE and f.severity == Severity.ERROR and f.field == "subtasks.0.target"
    assert "box_b" in f.message and "0.80 m" in f.message
    moved = BasePose(x=f.nearest[0], y=f.nearest[1])
    assert not check_sequence(one(BaseSubtask(target=moved)), [BOX], env)
    d = float(np.hypot(f.nearest[0] - 2.0, f.nearest[1] - 0.3))
    assert d < 0.45  # the goal was about 0.4 m short of 0.8 m from the box's face: moved about that far


def test_base_goal_at_a_box_centre_and_waypoints_are_checked(env):
    sub = BaseSubtask(target=BasePose(x=2.0, y=1.0), waypoints=[BasePose(x=0.0, y=0.0), BasePose(x=2.5, y=1.2)])
    fields = {f.field: f for f in check_sequence(one(sub), [BOX], env)}
    assert set(fields) == {"subtasks.0.target", "subtasks.0.waypoints.1"}
    assert "inside box_b" in fields["subtasks.0.target"].message
    assert "base waypoint" in fields["subtasks.0.waypoints.1"].message


def test_boxes_above_the_base_do_not_block_it(env):
    shelf = Obstacle("high", (2.0, 1.0, 2.3), (0.6, 0.6, 0.4))
    assert not check_sequence(one(BaseSubtask(target=BasePose(x=2.0, y=1.0))), [shelf], env)


def test_scene_may_change_turns_box_rules_into_warnings_but_not_reach(env):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.0, y=1.0)),
                                 EESubtask(target=EEPose(position=(2.0, 0.0, 5.0)))])
    findings = check_sequence(seq, [BOX], env, scene_may_change=True)
    by_rule = {f.rule: f for f in findings}
    assert by_rule[Rule.BASE_CLEARANCE].severity == Severity.WARNING
    assert "scene may change" in by_rule[Rule.BASE_CLEARANCE].message
    assert by_rule[Rule.REACH].severity == Severity.ERROR
    with pytest.raises(TargetError) as err:
        require_valid(seq, [BOX], env, scene_may_change=True)
    assert [f.rule for f in err.value.findings] == [Rule.REACH]


def test_ee_target_out_of_reach_above_the_floor(env):
    (f,) = check_sequence(one(EESubtask(target=EEPose(position=(2.0, 0.0, 5.0)))), [], env)
    assert f.rule == Rule.REACH and "reaches" in f.message
    assert f.nearest[:2] == (2.0, 0.0) and 1.8 < f.nearest[2] < 2.05
    assert not check_sequence(one(EESubtask(target=EEPose(position=f.nearest))), [], env)


def test_ee_target_in_the_hand_clearance_of_a_box_top(env):
    # 0.25 m above the top, pointing down: the tool sphere (0.15 m) is 0.15 m from the top, it keeps 0.4 m
    target = EEPose(position=(2.0, 1.0, 0.85), rpy_deg=(0.0, 90.0, 0.0))
    (f,) = check_sequence(one(EESubtask(target=target)), [BOX], env)
    assert f.rule == Rule.HAND_CLEARANCE and "tool sphere" in f.message and "0.40 m" in f.message
    assert f.nearest[2] == pytest.approx(0.6 + 0.4 + 0.1, abs=0.02)  # top + clearance + tool offset
    fixed = EEPose(position=f.nearest, rpy_deg=target.rpy_deg)
    assert not check_sequence(one(EESubtask(target=fixed)), [BOX], env)


def test_position_only_ee_target_keeps_the_unavoidable_hand_clearance(env):
    inside = check_sequence(one(EESubtask(target=EEPose(position=(2.0, 1.0, 0.85)))), [BOX], env)
    assert [f.rule for f in inside] == [Rule.HAND_CLEARANCE]
    assert not check_sequence(one(EESubtask(target=EEPose(position=(2.0, 1.0, 1.0)))), [BOX], env)


def test_ee_target_into_the_floor(env):
    (f,) = check_sequence(one(EESubtask(target=EEPose(position=(1.0, 0.0, 0.05), rpy_deg=(0, 90, 0)))), [], env)
    assert f.rule == Rule.FLOOR and "floor" in f.message
    assert f.nearest[2] > 0.05


def test_ee_target_with_no_collision_free_base_pose_in_reach(env):
    # a hand target in the middle of a 5 m wide field of boxes: every base pose within reach is blocked
    field = [Obstacle(f"b{i}_{j}", (x, y, 0.3), (0.9, 0.9, 0.6)) for i, x in enumerate(np.arange(-2.0, 2.1, 1.0))
             for j, y in enumerate(np.arange(-2.0, 2.1, 1.0))]
    target = EEPose(position=(0.0, 0.0, 1.2))
    findings = check_sequence(one(EESubtask(target=target)), field, env)
    assert [f.rule for f in findings] == [Rule.BASE_POSE]
    near = findings[0].nearest
    assert near is not None and not check_sequence(one(EESubtask(target=EEPose(position=near))), field, env)
    assert 1.0 < np.hypot(*near[:2]) < 2.5  # pulled toward the edge of the field, no further than needed


def test_base_frame_targets_reach_and_self_collision(env):
    beside = EEPose(position=(0.3, -0.6, 0.9), rpy_deg=(0.0, 0.0, -90.0), frame="base")
    assert not check_sequence(one(BaseSubtask(target=BasePose(x=4, y=0), ee=beside)), [BOX], env)
    far = EESubtask(target=EEPose(position=(2.0, 0.0, 0.9), frame="base"))
    (f,) = check_sequence(one(far), [BOX], env)
    assert f.rule == Rule.REACH and "base frame" in f.message
    into_base = EESubtask(target=EEPose(position=(0.3, -0.3, 0.35), frame="base"))  # 3 cm above the body
    (g,) = check_sequence(one(into_base), [], env)
    assert g.rule == Rule.SELF_COLLISION
    assert not check_sequence(one(EESubtask(target=EEPose(position=g.nearest, frame="base"))), [], env)


def test_yaml_problems_name_the_line(env):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=0.0, y=0.0)),
                                 BaseSubtask(name="into the box", target=BasePose(x=2.0, y=1.0))])
    text = sequence_to_yaml(seq)
    with pytest.raises(TargetError) as err:
        require_valid(seq, [BOX], env, source="seq.yaml", text=text)
    (field, line, message), = err.value.problems
    assert field == "subtasks.1.target" and text.splitlines()[line - 1].strip().startswith("target:")
    assert "seq.yaml" in str(err.value) and "nearest acceptable" in message


def test_only_changed_targets_are_judged(env):
    before = TaskSequence(subtasks=[BaseSubtask(name="a", target=BasePose(x=2.0, y=1.0))])
    renamed = TaskSequence(subtasks=[BaseSubtask(name="b", target=BasePose(x=2.0, y=1.0)),
                                     BaseSubtask(target=BasePose(x=5.0, y=5.0))])
    assert changed_subtasks(before, renamed) == [1]
    assert not check_sequence(renamed, [BOX], env, indices=[1])


@pytest.mark.parametrize("path", sorted(EXAMPLES_DIR.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_examples_pass_in_their_scenes(path, env):
    seq = load_sequence(path)
    scene = load_scene((path.parent / seq.scene).resolve())
    named = {b.id: b for b in scene.boxes if b.id in seq.objects}  # anchors on scene box ids (simulation)
    assert check_sequence(seq, scene.boxes, env, start_xy=scene.robot_start[:2], anchors=named) == []


def pen_boxes(centre=(4.0, 0.0)) -> list[Obstacle]:
    """A closed ring of 0.6 m boxes, 3.6 m across, around `centre`: inside, 1.2 m from every box face."""
    cx, cy = centre
    out = []
    for k, d in enumerate(np.arange(-1.8, 1.81, 0.6)):
        out += [Obstacle(f"pen_s{k}", (cx + d, cy - 1.8, 0.3), (0.6, 0.6, 0.6)),
                Obstacle(f"pen_n{k}", (cx + d, cy + 1.8, 0.3), (0.6, 0.6, 0.6)),
                Obstacle(f"pen_w{k}", (cx - 1.8, cy + d, 0.3), (0.6, 0.6, 0.6)),
                Obstacle(f"pen_e{k}", (cx + 1.8, cy + d, 0.3), (0.6, 0.6, 0.6))]
    return out


def test_a_goal_in_a_closed_pen_is_refused_when_the_scene_is_known(env):
    """The goal keeps its clearance from every box, but no path leads in: refused, with the nearest position a
    path reaches; without a known start (a real robot's partial map) it passes."""
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=4.0, y=0.0)),
                                 BaseSubtask(target=BasePose(x=0.0, y=2.0))])
    boxes = pen_boxes()
    assert check_sequence(seq, boxes, env) == []
    found = check_sequence(seq, boxes, env, start_xy=(0.0, 0.0))
    assert [(f.index, f.rule, f.severity) for f in found] == [(0, Rule.PATH, Severity.ERROR)]
    assert "no path reaches it from (0.00, 0.00)" in found[0].message and "pen_" in found[0].message
    near = np.array(found[0].nearest)
    assert near[0] < 4.0 - 1.8 - 0.3 - 0.8 + 0.11  # outside the pen, beside it
    assert not check_sequence(seq, boxes, env, start_xy=(4.0, 0.0), indices=[0])  # starting inside: reachable
    warned = check_sequence(seq, boxes, env, start_xy=(0.0, 0.0), scene_may_change=True)
    assert [f.severity for f in warned] == [Severity.WARNING]


def test_a_waypoint_in_a_pen_is_refused_and_the_goal_judged_from_before_it(env):
    seq = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=0.0, y=3.0), waypoints=[BasePose(x=4.0, y=0.0)])])
    found = check_sequence(seq, pen_boxes(), env, start_xy=(0.0, 0.0))
    assert [f.field for f in found] == ["subtasks.0.waypoints.0"]
