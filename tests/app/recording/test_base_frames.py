"""The estimated and the true base in Foxglove: with localization on, every `/tf` of a recording has world →
base_estimated (the localizer's pose, the one world → base follows) and world → base_true (the simulator's);
`/robot/state` carries both as numbers to plot, and the replay reads them back. In simulation the true base is
there without localization too, taken when the state was observed (with exact sensing it is the state's pose)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from app.recording import Recorder, read_recording
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import Snapshot
from core.params import LocalizationParams
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.recording.test_recording import LAYOUT, LOCALIZATION_TOPIC, _resolve, layout_paths

SCENE = Scene((Box("a", (2.0, 0.8, 0.3)), Box("b", (1.5, -1.0, 0.3))))
DRIVE = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.5, y=-0.2))])


@pytest.fixture(scope="module")
def localized(tmp_path_factory) -> Path:
    """A 2 s lockstep run on the object map with localization, recorded."""
    path = tmp_path_factory.mktemp("loc") / "localized.mcap"
    rt = Runtime(RuntimeConfig(map_kind="object", localization=LocalizationParams(enabled=True)), scene=SCENE,
                 sequence=DRIVE)
    recorder = Recorder(path, sim_time=True)
    rt.subscribe(recorder)
    rt.run_lockstep(2.0, publish_every=1)
    recorder.close()
    return path


def _messages(path: Path, topic: str) -> list:
    decoders = DecoderFactory()
    out = []
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(topics=[topic]):
            if channel.message_encoding == "json":
                out.append(json.loads(message.data))
            else:
                decoder = decoders.decoder_for("protobuf", schema)
                assert decoder is not None
                out.append(decoder(message.data))
    return out


def test_every_transform_message_has_the_estimated_and_the_true_base(localized) -> None:
    tfs = _messages(localized, "/tf")
    assert len(tfs) > 15
    moved = 0.0
    for tf in tfs:
        by_child = {t.child_frame_id: t for t in tf.transforms}
        base, estimated, true = by_child["base"], by_child["base_estimated"], by_child["base_true"]
        assert estimated.parent_frame_id == true.parent_frame_id == base.parent_frame_id == "world"
        assert (estimated.translation, estimated.rotation) == (base.translation, base.rotation)
        gap = np.hypot(true.translation.x - base.translation.x, true.translation.y - base.translation.y)
        assert gap < 0.2, "the estimate stays near the truth over 2 s"
        moved = max(moved, true.translation.x)
    assert moved > 0.1, "the true base drove"


def test_the_robot_state_carries_both_poses_and_the_replay_reads_them(localized) -> None:
    states = _messages(localized, "/robot/state")
    assert all(s["base_estimate"] == s["q"][:3] and len(s["base_true"]) == 3 for s in states)
    last = read_recording(localized)[-1]
    assert last.base_estimate is not None and last.base_true is not None
    np.testing.assert_allclose(last.base_estimate, last.state.q[:3], atol=1e-5)
    np.testing.assert_allclose(last.base_true, states[-1]["base_true"])


def test_the_pose_health_is_recorded_and_the_replay_reads_it(localized) -> None:
    health = _messages(localized, "/localization/health")
    assert len(health) > 15 and all(np.array(h["covariance"]).shape == (3, 3) for h in health)
    verdicts = ("accepted", "rejected", "degenerate", "no_reference")
    assert sum(health[-1][k] for k in verdicts) > 0, "the frames localization wanted got their verdicts"
    last = read_recording(localized)[-1]
    assert last.localization is not None
    np.testing.assert_allclose(last.localization.covariance, health[-1]["covariance"], atol=1e-9)
    assert last.localization.sigma_xy_m == pytest.approx(health[-1]["sigma_xy_m"])
    assert last.localization.untrusted == health[-1]["untrusted"]


def test_the_foxglove_layout_plots_the_pose_health(localized) -> None:
    """docs/foxglove_layout.json plots `/localization/health` (σ_xy, the margin's growth, the correction rate and
    the age of the last correction); every path resolves to numbers in a recording with localization."""
    layout = json.loads(LAYOUT.read_text())
    assert sorted(_leaves(layout["layout"])) == sorted(layout["configById"])
    paths = [p for p in layout_paths(layout) if p.startswith(LOCALIZATION_TOPIC + ".")]
    fields = {p[len(LOCALIZATION_TOPIC) + 1:] for p in paths}
    assert {"sigma_xy_m", "margin_growth_m", "accepted_per_s", "since_accepted_s"} <= fields, fields
    last = _messages(localized, LOCALIZATION_TOPIC)[-1]
    for path in paths:
        values = _resolve(last, path[len(LOCALIZATION_TOPIC):])
        assert values and all(isinstance(v, int | float) for v in values), path


def _leaves(node) -> list[str]:
    return [node] if isinstance(node, str) else [*_leaves(node["first"]), *_leaves(node["second"])]


def test_without_localization_the_true_base_is_the_state_when_sensing_is_exact() -> None:
    """The ground-truth map senses exactly: the truth taken at the observation is the state's own base pose
    (the truth is read when the state is, not when the snapshot goes out)."""
    snaps: list[Snapshot] = []
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=SCENE, sequence=DRIVE)
    rt.subscribe(snaps.append)
    rt.run_lockstep(1.0, publish_every=1)
    assert len(snaps) > 5 and snaps[-1].state.q[0] > 0.05
    for snap in snaps:
        assert snap.base_estimate is None and snap.base_true is not None
        np.testing.assert_allclose(snap.base_true, snap.state.q[:3], rtol=0, atol=1e-9)
