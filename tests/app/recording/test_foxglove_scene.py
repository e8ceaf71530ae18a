"""The Foxglove encoding of a snapshot, without a simulation: the localization hook adds base frames to
`/tf`, targets land in their own frame (an EE target given in the base frame is drawn there), and removed
or unknown objects are grey."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from mcap.records import Schema

from app.recording.foxglove_scene import SCHEMAS, plan_paths, transforms
from app.recording.protobuf import ProtobufDecoder
from app.runtime.snapshot import Snapshot
from app.runtime.target_marks import target_marks
from core.robot.model import READY_Q, RobotModel
from core.types import RobotState
from tasks import BasePose, BaseSubtask, TaskSequence
from tasks.schema import EEPose, EESubtask
from tasks.sequence_file import parse_sequence
from tasks.sequencer import SubtaskProgress


def _decode(name: str, data: bytes):
    schema = SCHEMAS[name]
    return ProtobufDecoder().decode(Schema(id=1, name=schema.name, encoding=schema.encoding, data=schema.data), data)


def test_base_poses_the_snapshot_carries_become_frames_of_their_own() -> None:
    robot = RobotModel()
    q = READY_Q.copy()
    q[:3] = (1.0, 2.0, 0.5)
    snap = Snapshot(seq=0, wall_time=0.0, state=RobotState(3.25, q, np.zeros(9)))
    plain = {t.child_frame_id for t in _decode("foxglove.FrameTransforms", transforms(robot, snap)).transforms}
    assert "base_estimated" not in plain and {"base", "wrist_3_link", "camera_base"} <= plain
    assert "base_true" not in plain
    localized = replace(snap, base_estimate=np.array([1.1, 1.9, 0.45]), base_true=np.array([1.2, 2.0, 0.5]))
    tf = _decode("foxglove.FrameTransforms", transforms(robot, localized)).transforms
    estimated = next(t for t in tf if t.child_frame_id == "base_estimated")
    assert estimated.parent_frame_id == "world" and (estimated.translation.x, estimated.translation.y) == (1.1, 1.9)
    true = next(t for t in tf if t.child_frame_id == "base_true")
    assert true.parent_frame_id == "world" and (true.translation.x, true.translation.y) == (1.2, 2.0)
    assert tf[0].timestamp.seconds == 3 and tf[0].timestamp.nanos == 250_000_000


def test_targets_are_drawn_in_their_frame() -> None:
    sequence = TaskSequence(subtasks=[
        BaseSubtask(name="drive", waypoints=[BasePose(x=1.0, y=0.0)], target=BasePose(x=2.0, y=1.0, yaw_deg=90)),
        EESubtask(name="reach", target=EEPose(position=(0.7, 0.0, 0.9), frame="base"))])
    marks = target_marks(sequence)
    assert [(m.index, m.goal, m.frame) for m in marks] == [(0, False, "world"), (0, True, "world"), (1, True, "base")]
    update = _decode("foxglove.SceneUpdate", plan_paths(0.0, None, None, marks, active_index=1))
    frames = {e.id.split("/")[1] + ("g" if e.texts else "w"): e.frame_id for e in update.entities}
    assert frames == {"0w": "world", "0g": "world", "1g": "base"}
    drive = next(e for e in update.entities if e.texts and e.texts[0].text == "drive")
    assert drive.arrows[0].pose.orientation.z == np.sin(np.pi / 4)
    assert update.deletions[0].type == 1  # all of the topic's entities first: each message is the whole picture


def test_an_anchored_target_is_drawn_where_it_sits_on_its_object_never_at_its_raw_offset() -> None:
    sequence = parse_sequence("objects: {box_3: {}}\nsubtasks:\n- kind: ee\n  name: reach\n"
                              "  target: {anchor: {object: box_3, offset: [0.0, 0.0, 0.4]}}\n"
                              "- kind: base\n  target: {x: 1.0, y: 2.0}\n")
    assert [m.index for m in target_marks(sequence)] == [1]  # not placed yet: not drawn
    placed = SubtaskProgress(0, "reach", "ee", anchored_goal=(2.5, 0.0, 1.0))
    marks = target_marks(sequence, [placed])
    assert [(m.index, m.position) for m in marks] == [(0, (2.5, 0.0, 1.0)), (1, (1.0, 2.0, 0.0))]


def test_link_meshes_are_y_up_gltf_so_foxglove_draws_them_in_the_link_frame() -> None:
    """Foxglove turns a glTF model +90° about x (glTF is y-up, its scene z-up): the embedded mesh is the link's
    STL with (x, y, z) → (x, z, −y), so that turn puts every vertex back where the URDF has it."""
    import json
    import struct

    import trimesh

    from app.recording.foxglove_scene import link_glb
    from core.robot.ur10_assets import ur10_mesh

    glb = link_glb("upper_arm_link")
    header = struct.unpack_from("<I", glb, 12)[0]
    accessor = next(a for a in json.loads(glb[20:20 + header])["accessors"] if a["type"] == "VEC3")
    lo, hi = trimesh.load(ur10_mesh("upper_arm_link", "collision")).bounds
    turned = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]) @ np.array([accessor["min"], accessor["max"]]).T
    np.testing.assert_allclose(np.sort(turned, axis=1), np.column_stack([lo, hi]), atol=1e-5)  # Rx(+90°) undoes it


def test_mapped_objects_carry_the_studio_label_with_the_operators_name() -> None:
    """'#4 shelf E[v]=…' in the 3D panel and '#4 shelf' in `/map/posterior`: the name bound to map object 4 (as
    `Snapshot.anchors` says) follows its id; an unnamed object is '#7'."""
    from app.recording.foxglove_scene import scene_messages
    from app.recording.topics import snapshot_messages
    from core.types import MappedObject, ObjectMapSnapshot, Posterior
    from tasks.anchors import MapObjects, ObjectView

    def mapped(oid: int, x: float) -> MappedObject:
        pose = np.eye(4)
        pose[:3, 3] = (x, 0.0, 0.3)
        return MappedObject(oid, pose, np.full(3, 0.6), np.zeros((0, 3)), Posterior(0.0, 0.1, 9.0, 1.0))

    shelf = ObjectView("object_4", "shelf", np.array([1.0, 0.0, 0.3]), 0.0, np.full(3, 0.6))
    other = ObjectView("object_7", None, np.array([3.0, 0.0, 0.3]), 0.0, np.full(3, 0.6))
    snap = Snapshot(seq=0, wall_time=0.0, state=RobotState(1.0, READY_Q.copy(), np.zeros(9)),
                    object_map=ObjectMapSnapshot(1.0, (mapped(4, 1.0), mapped(7, 3.0))),
                    anchors=MapObjects(1.0, (shelf, other)))
    scene = dict(scene_messages(RobotModel(), snap, with_points=False, with_model=False))
    entities = _decode("foxglove.SceneUpdate", scene["/map/objects"]).entities
    assert [e.texts[0].text for e in entities] == ["#4 shelf E[v]=0.90", "#7 E[v]=0.90"]
    assert [{kv.key: kv.value for kv in e.metadata}["name"] for e in entities] == ["shelf", ""]
    posterior = dict(snapshot_messages(snap))["/map/posterior"]
    assert [o["label"] for o in posterior["objects"]] == ["#4 shelf", "#7"]
