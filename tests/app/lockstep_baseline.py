"""A lockstep run of the default scene and sequence on the object map, summarised as plain data: the
baseline that shows a refactoring changed no behaviour (`test_lockstep_baseline.py` compares against
`data/lockstep_baseline.json`).

A box the robot is looking at is taken away early in the run, so the summary holds a removal too.
Regenerate the file (only when a change of behaviour is intended, and say so in the commit) with
`python -m tests.app.lockstep_baseline --write`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from app.runtime import Runtime, RuntimeConfig

BASELINE = Path(__file__).parent / "data" / "lockstep_baseline.json"
DURATION_S = 4.0
MOVE_AT_S = 1.0
MOVED_BOX = ("box_a", (2.2, 9.0, 0.3))
DECIMALS = 6


def _round(values, decimals: int = DECIMALS) -> list[float]:
    return [round(float(v), decimals) for v in np.ravel(values)]


def run_summary() -> dict:
    """Run the default scene lockstep on the object map and summarise what it produced."""
    rt = Runtime(RuntimeConfig(map_kind="object"))
    rt.run_lockstep(MOVE_AT_S, until_done=False)
    rt.move_box(*MOVED_BOX)
    log = rt.run_lockstep(DURATION_S - MOVE_AT_S, until_done=False)
    snap = rt.map.snapshot()
    objects = sorted(({"position": _round(o.pose[:3, 3], 4), "extent": _round(o.extent, 4),
                       "status": str(o.status)} for o in snap.objects), key=lambda o: o["position"])
    return {
        "duration_s": DURATION_S,
        "t_end": round(rt.time, DECIMALS),
        "run_state": str(rt.run_state),
        "objects": objects,
        "removed": len(snap.removed_ids),
        "q_final": _round(rt.state.q),
        "task_errors": [_round(e) for e in log.task_errors],
        "plan_status": [str(s) for s in log.plan_status],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description="Run the lockstep baseline; print it or write it.")
    parser.add_argument("--write", action="store_true", help=f"write {BASELINE.name} (else print)")
    summary = run_summary()
    text = "{\n" + ",\n".join(f" {json.dumps(key)}: {json.dumps(value)}" for key, value in summary.items()) + "\n}"
    if parser.parse_args().write:
        BASELINE.write_text(text + "\n", encoding="utf-8")
    else:
        print(text)


if __name__ == "__main__":
    main()
