"""The studio end to end in a real headless Chromium: author a two-subtask sequence through the GUI,
start it, move a box through the UI while the robot runs, and check the runtime (box moved in MuJoCo,
sequence finished). Screenshots are saved as test artefacts (the README's docs/studio.png comes from
test_studio_status_e2e.py, which shows named mapped objects)."""

import re
import threading

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from app.ui.studio import Studio
from core.scene import Box, Scene
from tasks import TaskSequence
from tests.app.conftest import ARTIFACTS, free_port
from tests.app.studio_page import pick_box, set_vector, wait_for

pytestmark = pytest.mark.wallclock

SCENE = Scene((Box("mover", (1.2, 2.0, 0.3)), Box("side", (2.5, -1.6, 0.3)), Box("far", (5.5, 1.8, 0.3))),
              robot_start=(0.0, 0.0, 0.0))


@pytest.fixture
def studio():
    # slowed down: a browser with software rendering on a busy machine lags seconds behind the runtime
    runtime = Runtime(RuntimeConfig(map_kind="object", speed=0.3), scene=SCENE, sequence=TaskSequence(name="authored"))
    studio = Studio(runtime, port=free_port())
    runtime.start_live()
    yield runtime, studio
    runtime.shutdown()
    studio.close()


@pytest.mark.slow
def test_author_run_and_move_a_box_in_the_browser(studio, page):
    runtime, ui = studio
    page.goto(ui.url)
    page.get_by_text("EMERGENCY STOP").first.wait_for(timeout=60_000)

    # author: a base goal, then an EE target, through the GUI fields and buttons
    set_vector(page, "Target (m)", (4.0, 0.0, 0.9))
    set_vector(page, "Target rpy (deg)", (0, 0, 0))
    page.get_by_role("button", name="Base goal").click()
    wait_for(lambda: len(runtime.sequence.subtasks) == 1, 10, "the base goal")
    set_vector(page, "Target (m)", (4.8, 0.2, 1.1))
    set_vector(page, "Target rpy (deg)", (0, 90, 0))
    page.get_by_role("button", name="EE target").click()
    wait_for(lambda: len(runtime.sequence.subtasks) == 2, 10, "the EE target")
    base, ee = runtime.sequence.subtasks
    assert (base.kind, base.target.x, base.target.y) == ("base", 4.0, 0.0)
    assert ee.kind == "ee" and ee.target.position == (4.8, 0.2, 1.1) and ee.target.rpy_deg[1] == pytest.approx(90)
    page.screenshot(path=str(ARTIFACTS / "studio_authored.png"))

    # run it, and move a box through the Scene tab while the robot drives
    page.get_by_role("button", name="Start").click()
    wait_for(lambda: runtime.run_state == RunState.RUNNING and np.hypot(*runtime.state.v[:2]) > 0.1, 20,
             "the robot to drive")
    page.get_by_role("tab", name="Monitor").click()
    page.get_by_text(re.compile(r"▶\s*running")).first.wait_for(timeout=30_000)
    page.wait_for_timeout(1500)
    assert runtime.run_state == RunState.RUNNING
    mid = ARTIFACTS / "studio_midrun.png"
    page.screenshot(path=str(mid))
    page.get_by_role("tab", name="Scene edits").click()
    pick_box(page, "mover", runtime.world.box("mover").position)
    set_vector(page, "Position (m)", (1.2, 3.0, 0.3))
    page.get_by_role("button", name="Move to typed pose").click()
    wait_for(lambda: runtime.world.box("mover").position == (1.2, 3.0, 0.3), 20, "the box to move in MuJoCo")
    page.screenshot(path=str(ARTIFACTS / "studio_box_moved.png"))

    wait_for(lambda: runtime.run_state in (RunState.FINISHED, RunState.FAILED), 120, "the sequence to end")
    assert runtime.run_state == RunState.FINISHED, runtime.status_line()
    assert runtime.world.collisions == []
    geom = runtime.world.model.geom("box_geom_0").id
    np.testing.assert_allclose(runtime.world.data.geom_xpos[geom], (1.2, 3.0, 0.3))
    page.wait_for_timeout(1000)
    page.screenshot(path=str(ARTIFACTS / "studio_finished.png"))
    assert page.get_by_text("sequence finished").count() >= 1


@pytest.mark.slow
def test_emergency_stop_hotkey_and_errors_as_notifications(studio, page):
    runtime, ui = studio
    page.goto(ui.url)
    page.get_by_text("EMERGENCY STOP").first.wait_for(timeout=60_000)
    # a bad edit (a box into the robot) becomes a notification; nothing changes
    page.get_by_role("tab", name="Scene edits").click()
    pick_box(page, "mover", runtime.world.box("mover").position)
    set_vector(page, "Position (m)", (0.0, 0.0, 0.3))  # into the robot
    page.get_by_role("button", name="Move to typed pose").click()
    page.get_by_text("overlap the robot").first.wait_for(timeout=30_000)
    assert runtime.world.box("mover").position == (1.2, 2.0, 0.3)  # the refused edit changed nothing
    # Escape stops the robot
    page.mouse.click(300, 600)  # focus the 3D view (not a text field) so the hotkey reaches viser
    page.keyboard.press("Escape")
    wait_for(lambda: runtime.run_state == RunState.ESTOP, 10, "the emergency stop")
    page.screenshot(path=str(ARTIFACTS / "studio_estop.png"))
    assert threading.active_count() > 1
