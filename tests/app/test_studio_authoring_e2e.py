"""Authoring in a real headless Chromium: the defects an operator met (issue 16), each shown by a page."""

import warnings

import pytest

from app.runtime import Runtime, RuntimeConfig
from core.scene import Box, Scene
from tasks import BasePose, BaseSubtask, TaskSequence
from tests.app.studio_page import FailedActions, choose, live_studio, open_studio, set_vector, wait_for

pytestmark = pytest.mark.wallclock

SCENE = Scene((Box("mover", (1.2, 2.0, 0.3)), Box("side", (2.5, -1.6, 0.3))), robot_start=(0.0, 0.0, 0.0))
THREE = TaskSequence(name="three", subtasks=[BaseSubtask(name=n, target=BasePose(x=x, y=0.0))
                                             for n, x in (("A", 1.0), ("B", 2.0), ("C", 3.0))])

CLICK_BURST = """async ([names, rounds, gapMs]) => {
  const byName = (n) => [...document.querySelectorAll('button')].find((b) => b.textContent.trim() === n);
  for (let i = 0; i < rounds; i++) {
    for (const n of names) byName(n).click();
    await new Promise((r) => setTimeout(r, gapMs));
  }
}"""
"""Clicks buttons by their text in quick rounds: the server receives the messages together and viser runs
their callbacks on its thread pool at the same time (as when an operator clicks fast on a slow page)."""


def studio_runtime(sequence: TaskSequence) -> Runtime:
    return Runtime(RuntimeConfig(map_kind="ground_truth"), scene=SCENE, sequence=sequence)


def goal_markers(studio) -> list[str]:
    names = list(studio.server.scene._handle_from_node_name)
    return [n for n in names if n.startswith("/authoring/goals/") and not n.endswith("_label")]


@pytest.mark.slow
def test_rapid_add_and_delete_while_snapshots_stream(page):
    """Bursts of adds, moves, deletes, undos and redos while snapshots stream never fail: the panel drew its
    goal markers from two threads at once (`add subtask failed | Cannot assign to 'visible' on a removed
    FrameHandle`, or viser's 'Attempted to remove already removed node')."""
    runtime = studio_runtime(TaskSequence(name="authored"))
    with live_studio(runtime) as studio, FailedActions.watching() as failed, \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        open_studio(page, studio)
        set_vector(page, "Target (m)", (3.0, 0.0, 0.9))
        page.evaluate(CLICK_BURST, [["Base goal", "Up", "Redo"], 30, 25])
        page.evaluate(CLICK_BURST, [["Base goal", "Delete", "Undo"], 30, 25])
        wait_for(lambda: studio.authoring.history.current == runtime.sequence, 20, "the panel and the runtime to agree")
        page.wait_for_timeout(1500)
        benign = ("select a subtask first", "nothing to")
        assert [m for m in failed.messages if not any(b in m for b in benign)] == []
        assert [str(w.message) for w in caught if "removed" in str(w.message)] == []
        assert len(goal_markers(studio)) == len(runtime.sequence.subtasks)


@pytest.mark.slow
def test_undo_keeps_the_selection_on_the_same_subtask(page):
    """Select A, move it down, undo, delete: A is deleted. The selection used to stay at the same row number,
    which after the undo held B, and Delete removed B."""
    runtime = studio_runtime(THREE)
    with live_studio(runtime) as studio:
        open_studio(page, studio)
        choose(page, "Subtask", "1. base: A")
        page.get_by_role("button", name="Down", exact=True).click()
        wait_for(lambda: [s.name for s in runtime.sequence.subtasks] == ["B", "A", "C"], 20, "A moved down")
        page.get_by_role("button", name="Undo", exact=True).click()
        wait_for(lambda: [s.name for s in runtime.sequence.subtasks] == ["A", "B", "C"], 20, "the undo")
        page.get_by_text("subtask 1 'A' changed").first.wait_for()  # the undo says what it did
        page.get_by_role("button", name="Delete", exact=True).click()
        wait_for(lambda: len(runtime.sequence.subtasks) == 2, 20, "the delete")
        assert [s.name for s in runtime.sequence.subtasks] == ["B", "C"]
