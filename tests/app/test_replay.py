"""A recorded run replays in the studio: the same views, run controls drive playback."""

import numpy as np
import pytest

from app.recording import Recorder
from app.replay import ReplaySource, wait_until_played
from app.runtime import Runtime, RuntimeConfig
from app.ui.studio import Studio
from core.sim.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.conftest import free_port


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
