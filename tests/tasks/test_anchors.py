"""Anchored targets: the schema refuses bad anchors with field and line, poses resolve on their object, and the
sequencer follows a moving object, waits for a missing one and times out with the reason."""

import math

import numpy as np
import pytest

from core.params import SequencerParams
from core.robot.model import READY_Q
from core.types import RobotState
from core.yaml_validation import FileFormatError
from tasks.anchors import MapObjects, ObjectView, anchor_box, anchor_position, face_point, resolve_pose, unsettled
from tasks.schema import Anchor, BasePose, EEPose, EESubtask, TaskSequence
from tasks.sequence_file import parse_sequence, sequence_to_yaml
from tasks.sequencer import Outcome, Sequencer

GOOD = """\
objects:
  box_3: {}
subtasks:
- name: approach box_3
  kind: base
  target: {anchor: {object: box_3, face: front, offset: [-0.9, 0, 0], rpy_deg: [0, 0, 0]}}
- name: above box_3
  kind: ee
  target:
    anchor: {object: box_3, face: top, offset: [-0.25, 0, 0.7], rpy_deg: [0, 90, 0]}
  timeout_s: 5
"""


def state_at(x: float, y: float, yaw: float = 0.0) -> RobotState:
    q = READY_Q.copy()
    q[:3] = x, y, yaw
    return RobotState(0.0, q, np.zeros(9))


def box(position, yaw=0.0, name="box_3", oid="object_1") -> ObjectView:
    return ObjectView(oid, name, np.array(position, float), yaw, np.array([0.6, 0.6, 0.6]))


def test_anchored_sequence_reads_and_writes_back():
    seq = parse_sequence(GOOD)
    assert seq.subtasks[1].target.anchor == Anchor(object="box_3", face="top", offset=(-0.25, 0, 0.7),
                                                   rpy_deg=(0, 90, 0))
    text = sequence_to_yaml(seq)
    assert "position:" not in text and " x:" not in text  # an anchored pose is written as its anchor
    assert parse_sequence(text) == seq
    assert TaskSequence.model_validate_json(seq.model_dump_json()) == seq


@pytest.mark.parametrize(("bad", "field", "line", "words"), [
    ("object: box_3, face: top, offset: [-0.25, 0, 0.7]", "subtasks.1.target.anchor.object", 10, "unknown object"),
    ("object: box_3, face: side", "subtasks.1.target.anchor.face", 10, "'top'"),
    ("object: box_3, offset: [.nan, 0, 0]", "subtasks.1.target.anchor.offset.0", 10, "finite"),
    ("object: '3 box', face: top", "subtasks.1.target.anchor.object", 10, "pattern"),
])
def test_a_bad_anchor_is_refused_with_its_field_and_line(bad, field, line, words):
    text = GOOD.replace("object: box_3, face: top, offset: [-0.25, 0, 0.7], rpy_deg: [0, 90, 0]", bad)
    if "unknown" in words:
        text = text.replace("box_3: {}", "box_4: {}").replace("box_3, face: front", "box_4, face: front")
    with pytest.raises(FileFormatError) as err:
        parse_sequence(text)
    problems = {(f, ln) for f, ln, _ in err.value.problems}
    assert (field, line) in problems, err.value
    assert words in str(err.value)


def test_coordinates_beside_an_anchor_are_refused():
    with pytest.raises(ValueError, match="drop position"):
        EEPose.model_validate({"position": [1, 2, 3], "anchor": {"object": "box_3"}})
    with pytest.raises(ValueError, match="drop x"):
        BasePose.model_validate({"x": 1, "anchor": {"object": "box_3"}})
    with pytest.raises(ValueError, match="frame: base"):
        EEPose.model_validate({"frame": "base", "anchor": {"object": "box_3"}})
    with pytest.raises(ValueError, match="only about z"):
        BasePose.model_validate({"anchor": {"object": "box_3", "rpy_deg": [10, 0, 0]}})


def test_faces_and_the_object_frame():
    ext = np.array([0.6, 0.4, 0.8])
    np.testing.assert_allclose(face_point("top", ext), [0, 0, 0.4])
    np.testing.assert_allclose(face_point("front", ext), [-0.3, 0, 0])
    np.testing.assert_allclose(face_point("left", ext), [0, 0.2, 0])
    obj = ObjectView("o", "box_3", np.array([2.0, 1.0, 0.4]), math.pi / 2, ext)
    # front (−x of the box) of a box turned 90°: toward world −y; the offset turns with it
    np.testing.assert_allclose(anchor_position(Anchor(object="box_3", face="front", offset=(-0.5, 0, 0)), obj),
                               [2.0, 1.0 - 0.8, 0.4], atol=1e-12)
    pose = resolve_pose(EEPose(anchor=Anchor(object="box_3", rpy_deg=(0, 90, 0))), MapObjects(0.0, (obj,)))
    assert isinstance(pose, EEPose) and pose.rpy_deg == pytest.approx((0, 90, 90))
    assert resolve_pose(EEPose(anchor=Anchor(object="box_9")), MapObjects(0.0, (obj,))) == "box_9 not yet seen"


def test_the_sequencer_follows_the_object_and_waits_when_it_is_gone(robot):
    seq = parse_sequence(GOOD)
    s = Sequencer(robot, seq)
    seen = MapObjects(0.0, (box([2.5, 0.0, 0.3]),))
    refs = s.update(state_at(0.0, 0.0), np.zeros((0, 3)), 0.0, seen)
    assert refs is not None and s.progress[0].anchored_goal == pytest.approx((1.3, 0.0, 0.0))
    assert s.path is not None and np.allclose(s.path[-1], [1.3, 0.0])
    moved = MapObjects(0.5, (box([2.5, 0.42, 0.3]),))
    s.update(state_at(0.1, 0.0), np.zeros((0, 3)), 0.5, moved)
    assert s.take_notices() == ["box_3 moved 0.42 m: target follows"]
    assert np.allclose(s.path[-1], [1.3, 0.42])  # the A* path was re-made to the new goal
    s.update(state_at(1.3, 0.42), np.zeros((0, 3)), 1.0, moved)
    assert s.index == 1  # reached: the EE subtask is next
    gone = MapObjects(1.1, (), {"box_3": "box_3 not in the map"})
    refs = s.update(state_at(1.3, 0.42), np.zeros((0, 3)), 1.1, gone)
    assert refs is not None and refs.order == ("base", "posture")  # hold the base, the arm at its ready pose
    np.testing.assert_allclose(refs.base.xy, [[1.3, 0.42]] * len(refs.base.xy))
    assert refs.ee is None and refs.posture is not None and np.allclose(refs.posture[0], READY_Q[3:])
    assert s.progress[1].message == "box_3 not in the map: waiting"
    assert s.update(state_at(1.3, 0.42), np.zeros((0, 3)), 7.0, gone) is None
    assert s.progress[1].outcome == Outcome.FAILED
    assert s.progress[1].message == "timed out after 5 s: box_3 not in the map"


def test_validation_checks_an_anchored_target_where_its_object_is(robot):
    from tasks.validation import Obstacle, RobotEnvelope, Rule, Severity, check_sequence

    env = RobotEnvelope.of(robot, delta_safe_m=0.25)
    seq = parse_sequence(GOOD.replace("offset: [-0.9, 0, 0]", "offset: [-0.2, 0, 0]"))  # base too near the box
    here = Obstacle("box_3", (2.5, 0.0, 0.3), (0.6, 0.6, 0.6))
    found = check_sequence(seq, [here], env, anchors={"box_3": here})
    assert [(f.field, f.rule) for f in found] == [("subtasks.0.target", Rule.BASE_CLEARANCE)]
    assert "(2.00, 0.00)" in found[0].message  # checked where the anchor puts it, not at (0, 0)
    unseen = check_sequence(seq, [], env, anchors={})
    assert {f.rule for f in unseen} == {Rule.ANCHOR} and all(f.severity == Severity.WARNING for f in unseen)
    assert "box_3 is not in the map yet" in unseen[0].message


def seen(minus_x: bool, plus_x: bool, minus_y: bool, plus_y: bool) -> np.ndarray:
    return np.array([[minus_x, plus_x], [minus_y, plus_y]])


def test_an_anchor_is_placed_from_the_seen_face_and_the_known_size():
    """A 0.6 m box seen from its front only is mapped 0.5 m deep, its centre 5 cm near: with its size known, the
    seen front face stays and the box reaches 0.6 m behind it; turned 90°, the same along world y."""
    top = Anchor(object="box_3", face="top", offset=(-0.25, 0, 0.7))
    mapped = dict(position=np.array([2.45, 0.0, 0.3]), extent=np.array([0.5, 0.6, 0.6]))
    short = ObjectView("o", "box_3", yaw=0.0, sides_seen=seen(True, False, False, False), **mapped)
    np.testing.assert_allclose(anchor_position(top, short), [2.2, 0.0, 1.3])  # as mapped: 5 cm near
    known = ObjectView("o", "box_3", yaw=0.0, sides_seen=seen(True, False, False, False),
                       size=np.array([0.6, 0.6, 0.6]), **mapped)
    centre, extent = anchor_box(known)
    np.testing.assert_allclose(centre, [2.5, 0.0, 0.3])
    np.testing.assert_allclose(extent, [0.6, 0.6, 0.6])
    np.testing.assert_allclose(anchor_position(top, known), [2.25, 0.0, 1.3])
    back = ObjectView("o", "box_3", yaw=0.0, sides_seen=seen(False, True, False, False),
                      size=np.array([0.6, 0.6, 0.6]), **mapped)  # the back seen: the box reaches toward −x
    np.testing.assert_allclose(anchor_box(back)[0], [2.4, 0.0, 0.3])
    turned = ObjectView("o", "box_3", np.array([0.0, 2.45, 0.3]), math.pi / 2, np.array([0.5, 0.6, 0.6]),
                        sides_seen=seen(True, False, False, False), size=np.array([0.6, 0.6, 0.6]))
    np.testing.assert_allclose(anchor_box(turned)[0], [0.0, 2.5, 0.3], atol=1e-12)


@pytest.mark.parametrize("sides", [seen(True, True, False, False), seen(False, False, False, False), None])
def test_both_faces_or_none_or_a_true_box_keep_the_mapped_box(sides):
    obj = ObjectView("o", "box_3", np.array([2.45, 0.0, 0.3]), 0.0, np.array([0.5, 0.6, 0.6]), sides_seen=sides,
                     size=np.array([0.6, 0.6, 0.6]))
    np.testing.assert_allclose(anchor_box(obj)[0], [2.45, 0.0, 0.3])
    unknown = ObjectView("o", "box_3", np.array([2.45, 0.0, 0.3]), 0.0, np.array([0.5, 0.6, 0.6]),
                         sides_seen=seen(True, False, False, False), size=np.array([np.nan, np.nan, np.nan]))
    np.testing.assert_allclose(anchor_box(unknown)[0], [2.45, 0.0, 0.3])  # no size measured: as mapped
    longer = ObjectView("o", "box_3", np.array([2.51, 0.0, 0.3]), 0.0, np.array([0.62, 0.6, 0.6]),
                        sides_seen=seen(True, False, False, False), size=np.array([0.6, 0.6, 0.6]))
    np.testing.assert_allclose(anchor_box(longer)[0], [2.51, 0.0, 0.3])  # seen over its whole depth: as mapped


def test_a_box_mapped_longer_than_its_size_is_not_settled(robot):
    """The map fused a moved box's old and new places (1.02 m for a 0.6 m box): the goal is followed but the
    subtask does not complete on it; once the box is mapped its size again, it does; past its timeout it fails
    with the reason."""
    size = np.array([0.6, 0.6, 0.6])
    fused = ObjectView("o", "box_3", np.array([2.5, 0.2, 0.3]), 0.0, np.array([0.6, 1.02, 0.6]), size=size)
    assert unsettled(fused, 0.15) == "box_3 mapped 1.02 m along its y, 0.60 m known: not settled"
    assert unsettled(fused, 0.5) == ""
    assert unsettled(ObjectView("o", "box_3", np.array([2.5, 0.2, 0.3]), 0.0, np.array([0.6, 1.02, 0.6])), 0.15) == ""
    short = ObjectView("o", "box_3", np.array([4.16, 1.54, 0.3]), 0.0, np.array([0.48, 0.6, 0.6]), size=size,
                       sides_seen=seen(True, True, True, True))  # shorter is no sign (its far side, or noise)
    assert unsettled(short, 0.15) == ""
    s = Sequencer(robot, parse_sequence(GOOD))
    at_goal = state_at(1.3, 0.2)  # the approach: 0.9 m before the front face
    s.update(at_goal, np.zeros((0, 3)), 0.0, MapObjects(0.0, (fused,)))
    s.update(at_goal, np.zeros((0, 3)), 0.1, MapObjects(0.1, (fused,)))
    assert s.index == 0 and s.progress[0].position_error_m < 0.01
    assert s.progress[0].message == "box_3 mapped 1.02 m along its y, 0.60 m known: not settled: waiting"
    never = SequencerParams(anchor_base_settle_s=math.inf)  # a base stance waiting as a hand target does
    late = Sequencer(robot, parse_sequence(GOOD), never)
    late.update(at_goal, np.zeros((0, 3)), 0.0, MapObjects(0.0, (fused,)))
    late.update(at_goal, np.zeros((0, 3)), 999.0, MapObjects(999.0, (fused,)))  # past its timeout: failed, with why
    assert late.progress[0].outcome == Outcome.FAILED
    assert late.progress[0].message.startswith("timed out after 120 s (box_3 mapped 1.02 m along its y, 0.60 m known:"
                                               " not settled; 0.00 m")
    settled = ObjectView("o", "box_3", np.array([2.5, 0.2, 0.3]), 0.0, np.array([0.6, 0.62, 0.6]), size=size)
    s.update(at_goal, np.zeros((0, 3)), 0.2, MapObjects(0.2, (settled,)))
    assert s.index == 1 and s.progress[0].outcome == Outcome.DONE


def test_a_named_object_declares_its_size():
    seq = parse_sequence(GOOD.replace("box_3: {}", "box_3: {size: [0.6, 0.4, 0.6]}"))
    assert seq.objects["box_3"].size == (0.6, 0.4, 0.6)
    assert parse_sequence(sequence_to_yaml(seq)) == seq
    with pytest.raises(FileFormatError) as err:
        parse_sequence(GOOD.replace("box_3: {}", "box_3: {size: [0.6, 0, 0.6]}"))
    assert ("objects.box_3.size.1", 2) in {(f, ln) for f, ln, _ in err.value.problems}


def test_a_base_stance_on_an_unsettled_box_completes_after_a_while_a_hand_target_waits(robot):
    """At the approach on a fused box (1.02 m for 0.6 m) whose old place no camera sees from there, the base
    subtask waits `anchor_base_settle_s`, then completes on the map's box (the operator is told); the hand target
    on the same box keeps waiting for the map to settle, up to its timeout."""
    size = np.array([0.6, 0.6, 0.6])
    fused = ObjectView("o", "box_3", np.array([2.5, 0.2, 0.3]), 0.0, np.array([0.6, 1.02, 0.6]), size=size)
    s = Sequencer(robot, parse_sequence(GOOD))
    wait = s.params.anchor_base_settle_s
    at_goal = state_at(1.3, 0.2)  # 0.9 m before the front face of the fused box
    for t in (0.0, 0.1, wait - 0.5):
        s.update(at_goal, np.zeros((0, 3)), t, MapObjects(t, (fused,)))
    assert s.index == 0 and s.progress[0].outcome == Outcome.ACTIVE
    assert s.progress[0].message.endswith("not settled: waiting")  # kept through the path's re-planning
    s.update(at_goal, np.zeros((0, 3)), wait + 0.2, MapObjects(wait + 0.2, (fused,)))
    assert s.index == 1 and s.progress[0].outcome == Outcome.DONE
    assert s.take_notices() == [f"box_3 mapped 1.02 m along its y, 0.60 m known: not settled after {wait:g} s at the"
                                " goal: the stance completes on it"]
    hand = s.active  # the pick above the same box: its wait is not cut short, however long
    assert isinstance(hand, EESubtask)
    why = "box_3 mapped 1.02 m along its y, 0.60 m known: not settled"
    assert [s._base_settled_enough(hand, why, t) for t in (0.0, wait, 10 * wait)] == [why] * 3


def test_a_waiting_base_turns_in_place_to_where_its_object_was_last_mapped(robot):
    """box_3 removed from the map while the base stood at the approach, facing along x: the base holds its place
    and turns to face where box_3 was last mapped, so that its cameras may find it again; with nowhere known it
    holds its heading."""
    s = Sequencer(robot, parse_sequence(GOOD))
    s.update(state_at(1.3, 0.0), np.zeros((0, 3)), 0.0, MapObjects(0.0, (box([2.5, 0.0, 0.3]),)))
    gone = MapObjects(0.5, (), {"box_3": "box_3 not in the map"}, {"box_3": np.array([1.3, 1.5, 0.3])})
    refs = s.update(state_at(1.3, 0.0), np.zeros((0, 3)), 0.5, gone)
    assert refs is not None and s.progress[s.index].message == "box_3 not in the map: waiting"
    np.testing.assert_allclose(refs.base.xy, [[1.3, 0.0]] * len(refs.base.xy))
    assert refs.base.yaw[-1] == pytest.approx(math.pi / 2)
    nowhere = MapObjects(0.6, (), {"box_3": "box_3 not in the map"})
    refs = s.update(state_at(1.3, 0.0, 0.3), np.zeros((0, 3)), 0.6, nowhere)
    assert refs is not None and np.allclose(refs.base.yaw, 0.3)
