"""The pose's health in a real headless Chromium (Debian's), localization on and every registration refused: the
3D view draws the estimate's 3σ ellipse (red: untrusted) and heading wedge and the true base as a translucent
ghost; the Monitor tab shows the pose-error and correction plots; the Problems panel and the status line say the
pose is untrusted and why."""

from __future__ import annotations

import io
import re
from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from app.runtime import Runtime, RuntimeConfig
from app.runtime.problems import ProblemKind
from app.ui.pose_view import GHOST_COLOR, UNTRUSTED_COLOR
from core.params import SensorParams, SimParams
from tests.app.conftest import ARTIFACTS
from tests.app.studio_page import live_studio, open_studio, wait_for
from tests.app.test_localization_health import BOX_AHEAD, REFUSED, UP_TO_THE_BOX

pytestmark = pytest.mark.wallclock

VIEW_COLUMNS = slice(320, 870)
"""The 3D view's part of the 1280-pixel page between the notices (left) and the panel (right)."""


def _pixels_near(png: bytes, color: tuple[int, int, int], tol: int = 40) -> int:
    """Pixels of the 3D view in the screenshot within `tol` of `color` in every channel."""
    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), int)[:, VIEW_COLUMNS]
    return int(np.sum(np.all(np.abs(rgb - np.array(color)) <= tol, axis=2)))


@pytest.mark.slow
def test_the_ellipse_the_ghost_and_the_localization_plots_appear(page):
    config = RuntimeConfig(map_kind="object", sim=replace(SimParams(), sensor=SensorParams.ideal()),
                           localization=replace(REFUSED, drift_m_per_sqrt_m=0.2))
    runtime = Runtime(config, scene=BOX_AHEAD, sequence=UP_TO_THE_BOX)
    with live_studio(runtime) as studio:
        open_studio(page, studio)
        before = page.screenshot()
        red_before = _pixels_near(before, UNTRUSTED_COLOR)  # nothing red before the run: no ellipse yet (σ ~ 1 mm)
        page.get_by_role("button", name="Start").click()
        page.get_by_text(re.compile(r"localization untrusted: position 3σ [\d.]+ m exceeds")).first.wait_for(
            timeout=120_000)
        wait_for(lambda: runtime.state.q[0] > 0.4, 60, "the base to drive on (σ grows with the distance driven)")
        page.wait_for_timeout(1500)
        shot = page.screenshot(path=str(ARTIFACTS / "studio_localization.png"))
        view = studio.pose_view
        assert {"ellipse", "wedge", "ghost_outline"} <= set(view.handles)
        assert view._ghost is not None and view._ghost.visible
        red, green = _pixels_near(shot, UNTRUSTED_COLOR), _pixels_near(shot, GHOST_COLOR)
        assert red > max(80, 4 * red_before), f"the 3σ ellipse and wedge should show red ({red} vs {red_before} px)"
        assert green > 8, f"the ghost's outline should show ({green} pixels)"  # under the base: the pose is exact

        page.get_by_role("tab", name="Problems").click()
        page.get_by_text(re.compile(r"untrusted localization episode")).first.wait_for()
        assert runtime.closed_loop.problems.count(ProblemKind.LOCALIZATION) == 1

        page.get_by_role("tab", name="Monitor").click()
        page.get_by_text("Pose error against the truth (simulation)").first.wait_for()
        page.get_by_text("Localization: corrections per second, rejected and degenerate registrations").first.wait_for()
        monitor = studio.monitor
        assert monitor.pose_error is not None and monitor.pose_error.visible
        assert monitor.corrections is not None and monitor.corrections.visible
        rejected = np.asarray(monitor.corrections.data[2])
        assert rejected[-1] >= 5, rejected[-5:]
