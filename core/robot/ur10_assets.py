"""Locate the UR10 URDF and meshes shipped inside the example-robot-data wheel.

The wheel installs its files under `<site-packages>/cmeel.prefix/share/example-robot-data`, and its
Python module is not importable, so we search the installed prefixes for the data folder.
"""

from __future__ import annotations

import site
import sys
import sysconfig
from functools import cache
from pathlib import Path

from core.errors import StudioError

_RELATIVE = Path("cmeel.prefix/share/example-robot-data/robots/ur_description")
ARM_LINKS = ("base_link", "shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link", "wrist_2_link",
             "wrist_3_link")
"""UR10 links that carry a mesh, in kinematic order."""
_MESH_STEM = {"base_link": "base", "shoulder_link": "shoulder", "upper_arm_link": "upperarm",
              "forearm_link": "forearm", "wrist_1_link": "wrist1", "wrist_2_link": "wrist2",
              "wrist_3_link": "wrist3"}


class RobotAssetsNotFoundError(StudioError, FileNotFoundError):
    """The example-robot-data files are not installed where we look for them."""


def _candidate_roots() -> list[Path]:
    roots = [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"], *site.getsitepackages()]
    roots += [p for p in sys.path if p.endswith("site-packages")]
    return list(dict.fromkeys(Path(r) for r in roots))


@cache
def ur_description_dir() -> Path:
    """Folder `ur_description` with `urdf/` and `meshes/`; raises `RobotAssetsNotFoundError` if absent."""
    tried = []
    for root in _candidate_roots():
        candidate = root / _RELATIVE
        tried.append(str(candidate))
        if (candidate / "urdf" / "ur10_robot.urdf").is_file():
            return candidate
    raise RobotAssetsNotFoundError(
        "UR10 URDF not found; install the 'example-robot-data' wheel (pip install example-robot-data). "
        f"Looked in: {', '.join(tried)}"
    )


def ur10_urdf() -> Path:
    """Path of `ur10_robot.urdf`."""
    return ur_description_dir() / "urdf" / "ur10_robot.urdf"


def ur10_mesh(link: str, kind: str = "collision") -> Path:
    """Mesh of a UR10 link: `collision` (STL, for MuJoCo) or `visual` (COLLADA, for the browser)."""
    if link not in _MESH_STEM:
        raise KeyError(f"UR10 link {link!r} has no mesh; links with meshes: {', '.join(ARM_LINKS)}")
    suffix = {"collision": "stl", "visual": "dae"}[kind]
    path = ur_description_dir() / "meshes" / "ur10" / kind / f"{_MESH_STEM[link]}.{suffix}"
    if not path.is_file():
        raise RobotAssetsNotFoundError(f"mesh {path} is missing from the example-robot-data install")
    return path
