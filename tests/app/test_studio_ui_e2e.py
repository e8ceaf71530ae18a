"""The studio's panels in a real headless Chromium: scene edits, notices, glyphs, plots, sequence name,
progress. One studio and one page for the module (a page takes tens of seconds to load on a busy machine)."""

import re
import threading
import time

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from app.ui import glyphs
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.conftest import ARTIFACTS, CHROMIUM, CHROMIUM_ARGS
from tests.app.studio_page import (
    choose,
    live_studio,
    open_studio,
    pick_box,
    row_inputs,
    runtime_state,
    set_vector,
    wait_for,
)

pytestmark = pytest.mark.wallclock

SCENE = Scene((Box("mover", (1.2, 2.0, 0.3)), Box("side", (2.5, -1.6, 0.3))), robot_start=(0.0, 0.0, 0.0))
GOAL = TaskSequence(name="to the far side", subtasks=[BaseSubtask(name="cross", target=BasePose(x=3.0, y=0.5),
                                                                  timeout_s=60.0)])
TOFU = """(glyphs) => {
  const c = document.createElement('canvas'); c.width = 64; c.height = 64;
  const ctx = c.getContext('2d');
  ctx.font = '32px ' + getComputedStyle(document.body).fontFamily;
  const draw = (g) => { ctx.clearRect(0, 0, 64, 64); ctx.fillText(g, 8, 40);
                        return Array.from(ctx.getImageData(0, 0, 64, 64).data).join(','); };
  const missing = draw(String.fromCodePoint(0x10FFFD));
  return glyphs.filter((g) => draw(g) === missing);
}"""
"""The glyphs among `glyphs` that the page draws like a code point no font has (the empty box, 'tofu')."""


def project(camera, point, rect) -> tuple[float, float]:
    """Page pixel of a world point seen by the browser's camera (viser reports it to the server)."""
    f = np.asarray(camera.look_at) - np.asarray(camera.position)
    f /= np.linalg.norm(f)
    r = np.cross(f, np.asarray(camera.up_direction))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.asarray(point) - np.asarray(camera.position)
    t = np.tan(camera.fov / 2)
    x, y = (d @ r) / ((d @ f) * t * camera.aspect), (d @ u) / ((d @ f) * t)
    return rect["x"] + (x + 1) / 2 * rect["width"], rect["y"] + (1 - y) / 2 * rect["height"]


@pytest.fixture(scope="module")
def session():
    from playwright.sync_api import sync_playwright

    runtime = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=SCENE, sequence=GOAL)
    with live_studio(runtime) as studio, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        open_studio(page, studio)
        yield runtime, studio, page
        browser.close()


def notices(page) -> list[str]:
    return page.evaluate("() => [...document.querySelectorAll('[class*=Notification-root]')].map(e => e.textContent)")


@pytest.mark.slow
def test_typed_pose_moves_the_box_once(session):
    """Typing x then y used to move the box to (new x, old y) first; now the gizmo previews and a button moves."""
    runtime, _, page = session
    page.get_by_role("tab", name="Scene edits").click()
    pick_box(page, "mover", runtime.world.box("mover").position)
    seen, stop = set(), threading.Event()

    def watch() -> None:
        while not stop.is_set():
            seen.add(tuple(round(v, 3) for v in runtime.world.box("mover").position))
            time.sleep(0.005)

    watcher = threading.Thread(target=watch)
    watcher.start()
    try:
        set_vector(page, "Position (m)", (0.8, 3.0, 0.3))
        page.wait_for_timeout(1000)
        assert runtime.world.box("mover").position == (1.2, 2.0, 0.3)  # typing alone moves nothing
        page.get_by_role("button", name="Move to typed pose").click()
        wait_for(lambda: runtime.world.box("mover").position == (0.8, 3.0, 0.3), 30, "the move")
    finally:
        stop.set()
        watcher.join()
    seen.add(tuple(round(v, 3) for v in runtime.world.box("mover").position))  # the watcher may not have run since
    assert seen == {(1.2, 2.0, 0.3), (0.8, 3.0, 0.3)}


@pytest.mark.slow
def test_pose_fields_show_the_picked_box(session):
    """The fields show the box just picked (they showed the previous one while the page, drawing the detailed
    view in software at well under one frame a second, had not yet applied the update: bench.studio_fps)."""
    runtime, _, page = session
    page.get_by_role("tab", name="Scene edits").click()
    for box_id in ("side", "mover", "side"):
        pick_box(page, box_id, runtime.world.box(box_id).position)


@pytest.mark.slow
def test_box_gizmo_drags_the_box_not_the_camera(session):
    """The gizmo sits above the box: a drag on its plane handle moves the box, the camera stays (inside the box,
    the box took the pointer and the drag turned the camera)."""
    runtime, studio, page = session
    page.get_by_role("tab", name="Scene edits").click()
    choose(page, "Box", "side")
    gizmo = np.asarray(studio.scene_panel.gizmo.position)
    box0 = runtime.world.box("side").position
    assert gizmo[2] > box0[2] + 0.3  # above the top
    page.wait_for_timeout(2000)
    client = next(iter(studio.server.get_clients().values()))
    camera0 = np.array(client.camera.position)
    rect = page.evaluate("() => { const r = document.querySelector('canvas').getBoundingClientRect();"
                         " return {x: r.x, y: r.y, width: r.width, height: r.height}; }")
    x, y = project(client.camera, gizmo + [0.12, 0.12, 0.0], rect)  # the gizmo's xy plane handle
    page.mouse.move(x, y)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(x + 8 * k, y - 3 * k)
        page.wait_for_timeout(200)
    page.mouse.up()
    wait_for(lambda: runtime.world.box("side").position != box0, 30, "the box to move")
    assert np.linalg.norm(np.array(client.camera.position) - camera0) < 1e-6


@pytest.mark.slow
def test_plot_legends_name_their_series(session):
    _, _, page = session
    page.get_by_role("tab", name="Monitor").click()
    page.get_by_text("Task error per level").first.wait_for()
    page.wait_for_timeout(1500)
    legends = page.evaluate("() => [...document.querySelectorAll('.u-legend')].map(e => e.textContent)")
    assert legends and all("level 1" in t or "solve" in t or "distance" in t or "#" in t or "—" in t for t in legends)
    assert not any("--" in t for t in legends), legends


@pytest.mark.slow
def test_rename_and_start_a_new_sequence(session):
    runtime, _, page = session
    page.get_by_role("tab", name="Sequence").click()
    field = row_inputs(page, "Sequence name").first
    field.fill("morning round")
    field.press("Enter")
    wait_for(lambda: runtime.sequence.name == "morning round", 30, "the rename")
    page.get_by_role("button", name="New sequence").click()
    wait_for(lambda: runtime.sequence.subtasks == [], 30, "an empty sequence")
    page.get_by_role("button", name="Undo", exact=True).click()
    wait_for(lambda: runtime.sequence.name == "morning round" and len(runtime.sequence.subtasks) == 1, 30,
             "the undo")


def _canvas_rect(page) -> dict:
    return page.evaluate("() => { const r = document.querySelector('canvas').getBoundingClientRect();"
                         " return {x: r.x, y: r.y, width: r.width, height: r.height}; }")


@pytest.mark.slow
def test_the_names_tab_names_a_clicked_object_and_anchors_a_target_on_it(session):
    """Click a mapped object in the 3D view, type a name and its size, press *Name…* and *Reach its top*: the name
    is bound to that object with its declared size and an anchored subtask on its top joins the sequence, listed
    with its binding."""
    runtime, studio, page = session
    page.get_by_role("tab", name="Names").click()
    client = next(iter(studio.server.get_clients().values()))
    top = np.asarray(runtime.world.box("mover").position) + [0.0, 0.0, 0.31]  # on its pick shell's top
    page.mouse.click(*project(client.camera, top, _canvas_rect(page)))
    wait_for(lambda: studio.anchor_panel.object.value == "mover", 30, "the click to select the object")
    field = row_inputs(page, "Object name").first
    field.fill("box_7")
    field.press("Enter")
    wait_for(lambda: studio.anchor_panel.name.value == "box_7", 30, "the typed name")
    set_vector(page, "Size (m)", [0.6, 0.5, 0.6])
    wait_for(lambda: np.allclose(studio.anchor_panel.size.value, (0.6, 0.5, 0.6)), 30, "the typed size")
    page.get_by_role("button", name="Name…").click()
    wait_for(lambda: runtime.closed_loop.names.bound().get("box_7") == "mover", 30, "the name to bind")
    # the UI's callback binds the name, then sets the sequence that saves it: wait for both
    wait_for(lambda: "box_7" in runtime.sequence.objects, 30, "the name saved with the sequence")
    assert runtime.sequence.objects["box_7"].size == (0.6, 0.5, 0.6)
    page.get_by_role("button", name="Reach its top").click()
    wait_for(lambda: any(s.name == "reach top of box_7" for s in runtime.sequence.subtasks), 30,
             "the anchored subtask")
    assert "box_7" in runtime.sequence.objects
    page.get_by_text(re.compile(r"reach top of box_7")).first.wait_for()
    page.screenshot(path=str(ARTIFACTS / "studio_names_tab.png"))


@pytest.mark.slow
def test_progress_bar_and_time_left_while_running(session):
    runtime, studio, page = session
    runtime.set_sequence(GOAL)
    page.get_by_role("button", name="Start").click()
    wait_for(lambda: runtime.run_state == RunState.RUNNING and np.hypot(*runtime.state.v[:2]) > 0.1, 30,
             "the robot to drive", lambda: runtime_state(runtime))
    page.get_by_text(re.compile(r"about \d+(\.\d)? s left")).first.wait_for()
    page.get_by_text(re.compile(r"times out in \d+(\.\d)? s")).first.wait_for()
    wait_for(lambda: float(page.get_by_role("progressbar").first.get_attribute("aria-valuenow") or 0) > 10, 60,
             "the progress bar to fill")
    wait_for(lambda: runtime.run_state == RunState.FINISHED, 90, "the run to finish", lambda: runtime_state(runtime))
    page.get_by_text(re.compile(r"finished after \d+(\.\d)? s")).first.wait_for()
    page.screenshot(path=str(ARTIFACTS / "studio_progress.png"))


@pytest.mark.slow
def test_emergency_stop_raises_one_notice_and_its_glyphs_render(session):
    """One notice (there were two: the button's and the runtime's), and no glyph the studio writes is an empty box
    in Debian's chromium (the stop glyph ⛔ was: no font here has it)."""
    runtime, _, page = session
    before = len([n for n in notices(page) if "stop" in n.lower()])
    page.get_by_role("button", name="EMERGENCY STOP").click()
    wait_for(lambda: runtime.run_state == RunState.ESTOP, 30, "the emergency stop")
    page.get_by_text("emergency_stop").first.wait_for()
    page.wait_for_timeout(3000)
    assert len([n for n in notices(page) if "stop" in n.lower()]) - before == 1
    status = page.locator("p", has_text="emergency_stop").first.text_content()
    shown = {ch for ch in status if ord(ch) > 127}
    assert shown and page.evaluate(TOFU, sorted(shown | glyphs.ALL)) == []
    assert page.get_by_role("button", name="EMERGENCY STOP").locator("svg").count() == 1  # an icon, not a glyph
    page.screenshot(path=str(ARTIFACTS / "studio_estop_glyphs.png"))
    runtime.reset()
