"""A recorded run replays in the studio: the same views, run controls drive playback."""

import time

import numpy as np
import pytest

from app.recording import Recorder
from app.recording.replay import ReplaySource, wait_until_played
from app.runtime import Runtime, RuntimeConfig
from app.ui.studio import Studio
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.conftest import free_port

pytestmark = pytest.mark.wallclock


def test_replay_drives_the_studio(tmp_path):
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("a", (2.0, 1.0, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=1.0, y=-0.5))]))
    path = tmp_path / "run.mcap"
    rec = Recorder(path)
    rt.subscribe(rec)
    rt.run_lockstep(4.0, publish_every=1)
    rec.close()

    source = ReplaySource(path)
    studio = Studio(source, port=free_port())
    try:
        source.start_live()
        source.set_speed(8.0)
        start_q = source.state.q.copy()
        draws = studio.draws
        source.start()
        assert wait_until_played(source, 30.0)
        assert studio.draws > draws + 10
        T = studio.robot_view.frames["mobile_base"].position
        np.testing.assert_allclose(T[:2], source.snapshots[-1].state.q[:2], atol=1e-6)
        assert np.linalg.norm(source.state.q[:2] - start_q[:2]) > 0.5
        source.reset()
        assert source.index == 0
        with pytest.raises(RuntimeError, match="replay"):
            source.move_box("a", (0.0, 0.0, 0.3))
    finally:
        source.shutdown()
        studio.close()


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A 6 s lockstep run past a box, every snapshot recorded (map points every 5th)."""
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("a", (2.0, 1.0, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.5, y=-0.5))]))
    path = tmp_path_factory.mktemp("replay") / "run.mcap"
    rec = Recorder(path, points_every=5)
    rt.subscribe(rec)
    rt.run_lockstep(6.0, publish_every=1, until_done=False)
    rec.close()
    return path


def test_seek_shows_the_run_at_that_time(recording):
    source = ReplaySource(recording)
    t_mid = source.start_time + 3.0
    snap = source.seek(t_mid)
    assert snap.state.t <= t_mid < snap.state.t + 0.11 and source.time == snap.state.t
    shown = source.snapshot()
    assert shown.map_points is not None and len(shown.map_points)  # the latest points kept before this snapshot
    assert shown.object_map is not None and shown.object_map.objects  # the map with E[v] at that time
    length = source.end_time - source.start_time
    assert shown.plan is not None and f"replay {snap.state.t - source.start_time:.1f} / {length:.1f} s" in shown.status
    assert [s.state.t for s in source.history(5)] == list(source.times[source.index - 5:source.index])
    assert source.seek(-5.0).state.t == source.start_time and source.seek(1e6).state.t == source.end_time


def test_timeline_scrubs_plays_and_sets_speed(recording):
    source = ReplaySource(recording)
    studio = Studio(source, port=free_port())
    try:
        source.start_live()
        timeline = studio.timeline
        assert timeline is not None and timeline.time.max == pytest.approx(round(source.end_time, 1))
        timeline.seek(source.start_time + 4.0)
        base = studio.robot_view.frames["mobile_base"].position
        np.testing.assert_allclose(base[:2], source.state.q[:2], atol=1e-6)  # the robot where it was at 4 s
        assert studio.monitor.rows[-1][0] == pytest.approx(source.time)  # the plots end at that time
        assert len(studio.monitor.rows) == source.index + 1
        assert timeline.time.value == pytest.approx(round(source.time, 1))
        timeline.seek(source.start_time + 1.0)  # back in time: the plots start over
        assert studio.monitor.rows[-1][0] == pytest.approx(source.time) and len(studio.monitor.rows) == source.index + 1
        timeline.speed.value = "8"
        assert source.config.speed == 8.0
        i0 = source.index
        timeline._on_button("Play")
        deadline = time.time() + 20
        while time.time() < deadline and source.index < i0 + 10:
            time.sleep(0.02)
        assert source.index >= i0 + 10
        timeline._on_button("Pause")
        i1 = source.index
        time.sleep(0.5)
        assert source.index == i1
    finally:
        source.shutdown()
        studio.close()
