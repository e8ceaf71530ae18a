"""README command 1 serves a page that shows the robot and the boxes in headless Chromium."""

import time

import numpy as np
import pytest
from PIL import Image

from tests.app.conftest import ARTIFACTS

pytestmark = pytest.mark.wallclock


def _colour_fractions(shot) -> tuple[float, float]:
    """Fractions of the screenshot that look like cardboard boxes and like the robot's dark base."""
    rgb = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    tan = (r > 120) & (r - b > 40) & (r > g) & (g > b)
    dark = (r < 90) & (g < 90) & (b < 100) & (np.abs(r - g) < 12)
    return float(tan.mean()), float(dark.mean())


@pytest.mark.slow
def test_studio_serves_robot_and_boxes(studio_process, page):
    proc, url = studio_process
    page.goto(url)
    page.wait_for_selector("canvas", timeout=60_000)
    page.get_by_text("EMERGENCY STOP").first.wait_for(timeout=60_000)
    shot = ARTIFACTS / "studio_seed.png"
    tan = dark = 0.0
    for _ in range(20):  # the scene fades in while meshes arrive; a busy machine takes longer
        time.sleep(2.0)
        page.screenshot(path=str(shot))
        tan, dark = _colour_fractions(shot)
        if tan > 0.008 and dark > 0.004:
            break
    assert tan > 0.008, "no boxes visible"  # six boxes take about 1.4 % of the default view
    assert dark > 0.004, "no robot base visible"
    assert proc.poll() is None
