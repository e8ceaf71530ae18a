"""Replaying a recorded run in a real headless Chromium: scrub the timeline, play, pause, change speed."""

import numpy as np
import pytest

from app.recording import Recorder
from app.recording.replay import ReplaySource
from app.runtime import Runtime, RuntimeConfig
from app.ui.studio import Studio
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.conftest import ARTIFACTS, free_port
from tests.app.studio_page import choose, row_inputs, wait_for

pytestmark = pytest.mark.wallclock


@pytest.mark.slow
def test_scrub_play_and_speed_in_the_browser(tmp_path, page):
    rt = Runtime(RuntimeConfig(map_kind="object"), scene=Scene((Box("a", (2.0, 1.0, 0.3)),)),
                 sequence=TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.5, y=-0.5))]))
    path = tmp_path / "run.mcap"
    rec = Recorder(path, points_every=5)
    rt.subscribe(rec)
    rt.run_lockstep(8.0, publish_every=1, until_done=False)
    rec.close()
    source = ReplaySource(path)
    studio = Studio(source, port=free_port())
    source.start_live()
    try:
        page.set_default_timeout(60_000)
        page.goto(studio.url)
        page.get_by_text("Replay time (s)").first.wait_for()
        target = round(source.start_time + 5.0, 1)
        field = row_inputs(page, "Replay time (s)").last  # the slider's number box
        field.fill(str(target))
        field.press("Enter")
        wait_for(lambda: abs(source.time - target) < 0.11, 30, "the replay to jump")
        q = source.state.q
        wait_for(lambda: np.allclose(studio.robot_view.frames["mobile_base"].position[:2], q[:2], atol=1e-6), 30,
                 "the robot drawn at that time")
        wait_for(lambda: studio.monitor.rows[-1][0] == pytest.approx(source.time), 30,
                 "the monitor at that time")  # its rows are published after the robot is drawn
        # the snapshot at or before the target (control steps follow the frames, not the clock's tenths)
        shown = f"replay {source.time - source.start_time:.1f} / {source.end_time - source.start_time:.1f} s"
        page.get_by_text(shown).first.wait_for()
        page.screenshot(path=str(ARTIFACTS / "studio_replay_scrubbed.png"))
        choose(page, "Replay speed (×)", "4")
        wait_for(lambda: source.config.speed == 4.0, 30, "the speed")
        i0 = source.index
        page.get_by_role("button", name="Play", exact=True).click()
        wait_for(lambda: source.index >= i0 + 10, 30, "playback")
        page.get_by_role("button", name="Pause", exact=True).click()
        wait_for(lambda: not source.playing, 30, "the pause")
        page.get_by_role("button", name="Rewind", exact=True).click()
        wait_for(lambda: source.index == 0, 30, "the rewind")
    finally:
        source.shutdown()
        studio.close()
