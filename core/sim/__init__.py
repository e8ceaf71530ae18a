"""The MuJoCo world: robot, boxes, depth cameras, odometry, scene edits, ground truth.

The off-screen GL backend is chosen before any submodule imports `mujoco`. The public names
(`SimWorld`, `SimRobot`, `SceneEditError`, `ground_truth_edf`) are imported on first use (PEP 562), so a
module that needs one pure-numpy part (e.g. the depth artefacts) does not load MuJoCo with it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from core.sim.gl_backend import choose_gl_backend

choose_gl_backend()

if TYPE_CHECKING:
    from core.sim.ground_truth import ground_truth_edf
    from core.sim.sim_robot import SimRobot
    from core.sim.world import SceneEditError, SimWorld

_HOME_OF = {"SimWorld": "core.sim.world", "SceneEditError": "core.sim.world", "SimRobot": "core.sim.sim_robot",
            "ground_truth_edf": "core.sim.ground_truth"}

__all__ = ["SceneEditError", "SimRobot", "SimWorld", "ground_truth_edf"]


def __getattr__(name: str) -> Any:
    """A public name, imported from its module on first use."""
    module = _HOME_OF.get(name)
    if module is None:
        raise AttributeError(f"module 'core.sim' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
