import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from core.scene import (
    PAPER_BOX_M,
    Box,
    _passable,
    aisle_scene,
    load_scene,
    parse_scene,
    random_scene,
    save_scene,
    scene_to_yaml,
)
from core.yaml_validation import FileFormatError


def test_random_scene_follows_the_paper_and_is_seeded():
    for seed in range(15):
        s = random_scene(seed)
        assert len(s.boxes) >= 8
        assert all(b.size == (PAPER_BOX_M,) * 3 for b in s.boxes)
        xy = np.array([b.position[:2] for b in s.boxes])
        assert np.all(np.abs(xy) <= 2.5)
        assert {round(b.position[2], 3) for b in s.boxes} <= {0.3, 0.9}
        assert _passable(list(s.boxes), s.robot_start[:2], s.goal, 0.6, (-4.5, 4.5, -3.5, 3.5))
    assert random_scene(4) == random_scene(4)
    assert random_scene(4) != random_scene(5)
    assert any(b.position[2] > 0.5 for seed in range(5) for b in random_scene(seed).boxes)


def test_random_scene_makes_any_count_from_one_box():
    """Every box count the bridge accepts (1–16) is generated; a stacked box always stands on a floor box."""
    for n in range(1, 17):
        for seed in range(4):
            boxes = random_scene(seed, n).boxes
            assert len(boxes) == n
            floor = {b.position[:2] for b in boxes if b.position[2] < 0.5}
            assert all(b.position[:2] in floor for b in boxes if b.position[2] > 0.5)


def test_aisle_is_a_closed_ring():
    s = aisle_scene()
    start = s.robot_start[:2]
    opposite = (-start[0], -start[1])
    assert _passable(list(s.boxes), start, opposite, 0.6, (-6, 6, -5, 5))
    assert not _passable(list(s.boxes), start, (0.0, 0.0), 0.3, (-6, 6, -5, 5))  # the island is closed


def test_yaml_round_trip(tmp_path):
    dark = random_scene(3).with_box(Box("black", (1.0, 2.0, 0.3), dark=True))  # returns no depth
    assert parse_scene(scene_to_yaml(dark)).box("black").dark
    for scene in (random_scene(2), aisle_scene(), dark):
        path = tmp_path / "s.yaml"
        save_scene(scene, path)
        assert load_scene(path) == scene
        assert parse_scene(scene_to_yaml(scene)) == scene


def test_shipped_scenes_load():
    paths = sorted((Path(__file__).parents[2] / "core/scenes").glob("*.yaml"))
    assert paths, "no scene files found"
    for path in paths:
        assert load_scene(path).boxes, path.name


@pytest.mark.parametrize(
    ("text", "field", "line"),
    [
        ("boxes:\n- id: a\n  position: [1, 2, .nan]\n", "boxes.0.position.2", 3),
        ("boxes:\n- id: a\n  position: [1, 2, 0.3]\n  size: [0.6, -1, 0.6]\n", "boxes.0.size", 4),
        ("boxes:\n- id: a\n  position: [1, 2, 0.3]\n  colour: red\n", "boxes.0.colour", 4),
        ("name: x\nboxes:\n- {id: a, position: [1, 2, 0.3]}\n- {id: a, position: [3, 2, 0.3]}\n", "boxes", 2),
        ("boxes: [\n", "", 2),
    ],
)
def test_bad_scene_files_name_field_and_line(text, field, line):
    with pytest.raises(FileFormatError) as err:
        parse_scene(text)
    problems = err.value.problems
    assert any(f == field and ln == line for f, ln, _ in problems), problems


def test_box_pose_matrix():
    from core.scene import Box

    T = Box("a", (1.0, 2.0, 0.3), yaw=math.pi / 2).pose()
    np.testing.assert_allclose(T[:3, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], [1.0, 2.0, 0.3])


def test_the_scene_types_import_neither_mujoco_nor_the_gl_probe():
    """`Box`, `Scene` and scene files are plain data: importing them must not pick a GL backend or load MuJoCo
    (core/sim does both on its first import), so the UI, the bridge's views and snapshots stay light."""
    code = ("import sys, core.scene, app.runtime.snapshot, app.bridge.views; "
            "loaded = [m for m in ('mujoco', 'core.sim', 'core.sim.gl_backend') if m in sys.modules]; "
            "print(loaded); sys.exit(1 if loaded else 0)")
    done = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parents[2], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, f"importing the scene types loaded {done.stdout.strip()} {done.stderr[-500:]}"
