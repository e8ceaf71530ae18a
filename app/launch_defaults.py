"""What the app starts with when no `--params` file says otherwise: the library's defaults (`core/params.py`) with
localization on.

The studio, `app run` and the bridge drive for minutes, and without localization the pose is the wheel odometry's
random walk: measured over E4's three aisle laps, the soak and the anchored picks, localization on finished what
odometry alone did not (README, "Perception as a real robot sees it"; docs/decisions.md, "Localization on when the
app starts").
The library's `LocalizationParams.enabled` stays off, so the experiments and benchmarks keep the configuration their
reports were measured with; `bench/experiments/localization_on.yaml` turns it on there. A `--params` file is read
over these defaults, so `localization: {enabled: false}` turns it off for a run.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from core.params import LocalizationParams
from core.params_file import Tunables, load_params

LAUNCH_TUNABLES = Tunables(localization=replace(LocalizationParams(), enabled=True))
"""The app's starting tunables: `core/params.py`'s defaults with `LocalizationParams.enabled`."""


def launch_tunables(params: str | Path | None = None) -> Tunables:
    """The tunables a run starts with: `params` (a YAML file, sections over these defaults) or the defaults."""
    return load_params(params, LAUNCH_TUNABLES) if params else LAUNCH_TUNABLES
