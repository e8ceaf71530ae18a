"""Every edge refuses a scene with a box inside the robot, with the same message as a box added while running
(the CLI's scene file, the bridge's simulated driver, `Runtime.reset` as the studio's scene upload calls it),
and `Runtime.set_sequence` runs the target checks the other edges run."""

import subprocess
import sys

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from core.scene import Box, Scene, save_scene
from core.sim.world import SceneEditError
from tasks.schema import BasePose, BaseSubtask, TaskSequence
from tasks.sequence_file import EXAMPLES_DIR
from tasks.validation import TargetError
from tests.app.conftest import ROOT

NAV = str(EXAMPLES_DIR / "navigation_through_boxes.yaml")
INSIDE = Scene((Box("box_a", (2.0, 1.0, 0.3)), Box("box_in", (0.2, 0.0, 0.3))), robot_start=(0.0, 0.0, 0.0),
               name="inside")
MESSAGE = "scene 'inside' refused: box 'box_in' would overlap the robot by"


@pytest.fixture
def bad_scene(tmp_path):
    path = tmp_path / "inside.yaml"
    save_scene(INSIDE, path)
    return path


@pytest.mark.parametrize("command", [["run", "--headless"], []])
def test_cli_refuses_a_scene_file_with_a_box_inside_the_robot(bad_scene, command, tmp_path):
    proc = subprocess.run([sys.executable, "-m", "app", *command, "--sequence", NAV, "--scene", str(bad_scene),
                           *(["--out", str(tmp_path / "out")] if command else ["--port", "0"])],
                          cwd=ROOT, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 2, proc.stderr
    assert MESSAGE in proc.stderr


def test_bridge_sim_driver_refuses_a_scene_file_with_a_box_inside_the_robot(bad_scene, tmp_path):
    token = tmp_path / "token"
    token.write_text("x" * 32)
    token.chmod(0o600)
    proc = subprocess.run([sys.executable, "-m", "app.bridge.sim_driver", "--scene", str(bad_scene),
                           "--token-file", str(token), "--url", "ws://127.0.0.1:9/robot"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert MESSAGE in proc.stderr


def test_runtime_reset_refuses_the_scene_and_keeps_the_old_one():
    """`Runtime.reset(scene)` is what the studio's scene upload calls: the refusal reaches the operator as a
    notification (the panel's handler), and the scene, the robot and the run stay as they were."""
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene((Box("a", (2.0, 0.0, 0.3)),), name="ok"))
    world = rt.require_world()
    q = world.state().q.copy()
    with pytest.raises(SceneEditError, match=MESSAGE):
        rt.reset(INSIDE)
    assert [b.id for b in rt.scene().boxes] == ["a"]
    np.testing.assert_array_equal(world.state().q, q)
    rt.reset()  # the old scene reloads
    assert [b.id for b in rt.scene().boxes] == ["a"]


def test_set_sequence_runs_the_target_checks():
    rt = Runtime(RuntimeConfig(map_kind="ground_truth"), scene=Scene((Box("box_a", (2.2, 1.3, 0.3)),)))
    before = rt.sequence
    inside = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.2, y=1.3))])
    with pytest.raises(TargetError, match="inside box_a"):
        rt.set_sequence(inside)
    assert rt.sequence == before  # nothing loaded
    ok = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.2, y=2.5))])
    assert rt.set_sequence(ok) == [] and rt.sequence == ok
    near = TaskSequence(subtasks=[BaseSubtask(target=BasePose(x=2.2, y=2.0))])  # 0.4 m from the box
    with pytest.raises(TargetError):
        rt.set_sequence(near)
    assert rt.set_sequence(near, scene_may_change=True)  # a warning then, as the studio's tick box gives
