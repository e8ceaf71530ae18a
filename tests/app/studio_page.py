"""Helpers for browser tests of the studio: a live studio on a free port, GUI rows found by their label."""

from __future__ import annotations

import logging
import re
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from app.runtime import Runtime
from app.ui.studio import Studio
from tests.app.conftest import free_port


@contextmanager
def live_studio(runtime: Runtime) -> Iterator[Studio]:
    """The studio of a live runtime; both stopped afterwards."""
    studio = Studio(runtime, port=free_port())
    runtime.start_live()
    try:
        yield studio
    finally:
        runtime.shutdown()
        studio.close()


def row(page, label: str):
    """The GUI row whose label is `label` (exact text)."""
    label_el = page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$")).first
    label_el.wait_for(timeout=30_000)
    return label_el.locator("xpath=ancestor::p/../..")


def row_inputs(page, label: str):
    """The input elements of a GUI row, found by its label text."""
    return row(page, label).locator("input")


def set_vector(page, label: str, values) -> None:
    inputs = row_inputs(page, label)
    for i, v in enumerate(values):
        field = inputs.nth(i)
        field.fill(str(v))
        field.press("Enter")
    page.wait_for_timeout(300)


def shown_vector(page, label: str) -> np.ndarray:
    """The values the page shows in the vector row `label` (NaN where a field is empty)."""
    return np.array([float(row_inputs(page, label).nth(k).input_value() or "nan") for k in range(3)])


def pick_box(page, box_id: str, position) -> None:
    """Pick `box_id` in the Scene edits tab and wait until its pose fields show `position`: a field typed
    before the page applies that update is overwritten by it."""
    choose(page, "Box", box_id)
    wait_for(lambda: np.allclose(shown_vector(page, "Position (m)"), position, atol=0.006), 30,
             f"the fields to show {box_id}")


def choose(page, label: str, option: str) -> None:
    """Pick `option` in the dropdown of row `label`."""
    row_inputs(page, label).first.click()
    page.get_by_role("option", name=option, exact=True).click()


def wait_for(predicate, timeout_s: float, what: str, describe: Callable[[], str] | None = None) -> None:
    """Poll `predicate` until it holds; on a timeout fail with `what` and, if given, `describe()`: what the
    runtime was doing (a CI failure is read from its log alone)."""
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    pytest.fail(f"timed out waiting for {what}" + (f"; {describe()}" if describe is not None else ""))


def runtime_state(runtime: Runtime) -> str:
    """One line on a live runtime for a failure message: run state, status, pose, speed, problems."""
    state = runtime.state
    problems = [f"{c.kind.value} ×{c.count}: {c.last_message}" for c in runtime.problems.counts()]
    return (f"run state {runtime.run_state.value}, status {runtime.status_line()!r}, t {state.t:.2f} s, "
            f"base {np.round(state.q[:3], 3).tolist()}, v {np.round(state.v[:3], 3).tolist()}, "
            f"problems {problems}")


def open_studio(page, studio: Studio) -> None:
    page.set_default_timeout(60_000)
    page.goto(studio.url)
    page.get_by_text("EMERGENCY STOP").first.wait_for(timeout=60_000)


class FailedActions(logging.Handler):
    """Collects the 'X failed: reason' warnings of GUI callbacks (each is also shown as a notification)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())

    @classmethod
    @contextmanager
    def watching(cls, logger: str = "app.ui.notify") -> Iterator[FailedActions]:
        handler = cls()
        log = logging.getLogger(logger)
        log.addHandler(handler)
        try:
            yield handler
        finally:
            log.removeHandler(handler)
