"""The runtime: the paper's closed loop (robot backend, map, sequencer, HTMPC) run in lockstep or live, and
what it publishes. Its public face is this module; the parts behind it:

- `runtime.py`: `Runtime`, the one entry the studio, the bridge and the CLI use;
- `config.py`: `RuntimeConfig` and the default scene and sequence;
- `closed_loop.py`: one tick, observe → map → control → command → measure, with the lock order;
- `live_loops.py`: the same stages on supervised wall-clock threads;
- `snapshot.py`, `snapshot_builder.py`: the frozen `Snapshot` subscribers read, and its assembly;
- `problems.py`, `run_log.py`: the problems panel's counts and the rows of a run;
- `components.py`, `ground_truth_map.py`, `map_process.py`: the exchangeable parts (maps, controller) and
  the process an object or voxel map runs in live; `native_memory.py`: the heap after a Reset.

Names are imported on first use: the map's worker process (spawned) imports `app.runtime.map_process`, and
with it this package, without loading the simulator, the controller or the UI's dependencies.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.map_kind import MAP_KINDS, MapKind
    from app.runtime.closed_loop import ClosedLoop, FaultError
    from app.runtime.config import CONSTRAINT_KINDS, DEFAULT_SCENE, DEFAULT_SEQUENCE, ROOT, RuntimeConfig
    from app.runtime.map_process import MapProcessError
    from app.runtime.problems import ProblemCount, ProblemKind, ProblemLog
    from app.runtime.run_log import RunEvent, RunLog
    from app.runtime.runtime import Runtime
    from app.runtime.snapshot import EDFSlice, RunState, Snapshot

_HOMES = {
    "app.map_kind": ("MAP_KINDS", "MapKind"),
    "app.runtime.closed_loop": ("ClosedLoop", "FaultError"),
    "app.runtime.config": ("CONSTRAINT_KINDS", "DEFAULT_SCENE", "DEFAULT_SEQUENCE", "ROOT", "RuntimeConfig"),
    "app.runtime.map_process": ("MapProcessError",),
    "app.runtime.problems": ("ProblemCount", "ProblemKind", "ProblemLog"),
    "app.runtime.run_log": ("RunEvent", "RunLog"),
    "app.runtime.runtime": ("Runtime",),
    "app.runtime.snapshot": ("EDFSlice", "RunState", "Snapshot"),
}
_HOME_OF = {name: module for module, names in _HOMES.items() for name in names}

__all__ = ["CONSTRAINT_KINDS", "DEFAULT_SCENE", "DEFAULT_SEQUENCE", "MAP_KINDS", "ROOT", "ClosedLoop", "EDFSlice",
           "FaultError", "MapKind", "MapProcessError", "ProblemCount", "ProblemKind", "ProblemLog", "RunEvent",
           "RunLog", "RunState", "Runtime", "RuntimeConfig", "Snapshot"]


def __getattr__(name: str) -> Any:
    """A public name, imported from its module on first use (PEP 562)."""
    if name not in _HOME_OF:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_HOME_OF[name]), name)
    globals()[name] = value
    return value
