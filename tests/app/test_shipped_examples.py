"""Every shipped example (`tasks/examples/`) runs headless in lockstep on the object map, through the whole
sensor model with the odometry's drift, and finishes with 0 collisions, as a new user would run it (`python -m app
run --sequence F`: the app's launch tunables, localization on; `app/launch_defaults.py`). `docs/decisions.md` says
what was fixed for the aisle laps to finish."""

from pathlib import Path

import pytest

from app.launch_defaults import launch_tunables
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from tasks.sequence_file import EXAMPLES_DIR, load_sequence


def _scene_of(path: Path) -> Path | None:
    scene = load_sequence(path).scene
    return (path.parent / scene).resolve() if scene else None


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted(EXAMPLES_DIR.glob("*.yaml")), ids=lambda p: p.stem)
def test_a_shipped_example_finishes_on_the_object_map_without_a_collision(path: Path):
    config = RuntimeConfig(scene=_scene_of(path), sequence=path, map_kind="object", **launch_tunables().sections())
    rt = Runtime(config)
    budget = sum(s.timeout_s + s.dwell_s for s in rt.sequence.subtasks)
    rt.run_lockstep(budget)
    assert rt.run_state == RunState.FINISHED, rt.status_line()
    assert rt.world is not None and len(rt.world.collisions) == 0
