"""README command 1 serves a page that shows the robot and the boxes in headless Chromium."""

import time

import numpy as np
import pytest
from PIL import Image

from tests.app.conftest import ARTIFACTS


@pytest.mark.slow
def test_studio_serves_robot_and_boxes(studio_process, page):
    proc, url = studio_process
    page.goto(url)
    page.wait_for_selector("canvas", timeout=60_000)
    page.get_by_text("boxes").first.wait_for(timeout=60_000)
    time.sleep(4.0)  # meshes arrive after the page
    shot = ARTIFACTS / "studio_seed.png"
    page.screenshot(path=str(shot))
    rgb = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    tan = (r > 120) & (r - b > 40) & (r > g) & (g > b)  # cardboard boxes
    dark = (r < 90) & (g < 90) & (b < 100) & (np.abs(r - g) < 12)  # the base
    assert tan.mean() > 0.02, "no boxes visible"
    assert dark.mean() > 0.003, "no robot base visible"
    assert proc.poll() is None
