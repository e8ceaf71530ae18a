"""Localization live: the registrations' time beside mapping and control, at speed 1 on the embedded simulation,
and what they cost the loops that keep time (issue 28).

    python -m bench.localization_live [--quick]

E4's aisle (`bench/experiments/e4_long_term.py`: its scene, its lap sequence) driven live, in real time (speed 1),
with the whole sensor model, the object map in its own process and HTMPC, three times for the same wall time:
`off` (no localization), `on` (localization, the registrations on their own thread:
`app/runtime/localization_worker.py`) and `inline` (localization, the registrations in the mapping loop as lockstep
runs them: what the worker avoids).
Figures, each suffixed with its condition:

- `registration_ms_p50`/`_p95`: the GICP alignment's own time (`Correction.registration_ms`, as
  `bench/localization.py` reports it in lockstep); `registration_wall_ms_p50`/`_p95`: the whole registration on
  the worker's clock (thinning, the reference, the gates; stretched by the other threads holding the GIL);
  `registrations_per_s`, `accepted`;
- `mapping_ms_p50`/`_p95`: an integration on the mapping loop, handed to the map's process and back (with
  `inline`, the registration after it too);
- `control_ms_p50`/`_p95`: a control step, wake to solved; `control_period_ms_p50`/`_p95`/`_max`: wall time between
  the starts of consecutive control steps (nominally 100 ms); `control_late_pct`: control steps that started more
  than one period late (robot time) and `control_lateness_ms_p95`;
- `command_gap_ms_p50`/`_p99`/`_max`: wall time between consecutive commands of the io loop (nominally 10 ms);
- `interpreter_wait_ms_p99`/`_max`: how late a probe thread of this process woke from 1 ms sleeps: the longest
  anything held the GIL (small_gicp holds it while it aligns and builds the reference's tree), plus scheduling;
- `reference_ms_p95`/`_max`: rebuilding the registration's target (the reference's k-d tree and covariances) when
  the reference or the base's 1 m cell changed, one call holding the GIL;
- `ate_rmse_m`, `final_error_m`: the pose the loop uses against the simulator's truth, sampled every 0.1 s.

The run's load average is in `machine` and `load_avg_before` / `load_avg_after`: live timings on a shared 2-core
machine are comparable only at similar load.
"""

from __future__ import annotations

import logging
import math
import os
import threading
import time
from dataclasses import replace

import numpy as np

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.runtime import Runtime
from app.runtime.stage_stamps import StageStamps
from bench.experiments.e4_long_term import SEED, lap_sequence, layouts, scene
from bench.experiments.trials import quiet_logs, runtime_config
from bench.report import bench_args, percentile, write_result
from core.localization.gates import Verdict
from core.params import LocalizationParams

log = logging.getLogger(__name__)

NAME = "localization_live"
CONDITIONS = ("off", "on", "inline")
QUICK_S, FULL_S = 10.0, 90.0
WARM_UP_S = 3.0
"""Wall seconds after Start that are not measured (the first control steps, the map process taking over)."""


class InterpreterProbe:
    """A thread that sleeps 1 ms at a time and records how much later than that it woke (ms): while another thread
    holds the GIL in C code, it cannot wake."""

    def __init__(self) -> None:
        self.late_ms: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="probe", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            t0 = time.perf_counter()
            time.sleep(0.001)
            self.late_ms.append((time.perf_counter() - t0) * 1e3 - 1.0)

    def stop(self) -> list[float]:
        self._stop.set()
        self._thread.join(timeout=2.0)
        return self.late_ms


def run(condition: str, seconds: float, seed: int = 0) -> dict[str, float]:
    """One live run of `seconds` wall time in `condition` (off, on, inline); its figures."""
    enabled = condition != "off"
    config = runtime_config(map_kind="object", seed=seed, localization=replace(LocalizationParams(), enabled=enabled))
    rt = Runtime(config, scene=scene(layouts(SEED, 1)[0]), sequence=lap_sequence(1))
    loop = rt.closed_loop
    rt.start_live()
    live = rt.live
    assert live is not None
    if condition == "inline":
        loop.localization_worker = None  # the mapping loop registers, as in lockstep
    rt.start()
    time.sleep(WARM_UP_S)
    loop.stamps = StageStamps(keep_s=seconds + 10.0)
    lateness_start = len(live.control_lateness_s)
    late_start, steps_start = live.control.stats.late, live.control_steps
    localizer = loop.localizer
    corrections_start = len(localizer.corrections) if localizer is not None else 0
    worker = live.localization
    wall_start = len(worker.wall_ms) if worker is not None else 0
    errors: list[float] = []
    probe = InterpreterProbe()
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        reading = loop.reading()
        if reading.base_true is not None:
            errors.append(float(np.linalg.norm(reading.state.q[:2] - reading.base_true[:2])))
        time.sleep(0.1)
    stamps, loop.stamps = loop.stamps, None
    waits = probe.stop()
    lateness = list(live.control_lateness_s)[lateness_start:]
    late, steps = live.control.stats.late - late_start, live.control_steps - steps_start
    corrections = list(localizer.corrections)[corrections_start:] if localizer is not None else []
    wall_ms = list(worker.wall_ms)[wall_start:] if worker is not None and condition == "on" else []
    fault = rt.fault
    rt.shutdown()
    if fault is not None:
        log.warning("%s: the run faulted: %s", condition, fault)
    controls = list(stamps.controls)
    commands = list(stamps.commands)
    integrations = list(stamps.integrations)
    wakes = np.array([c.wall_wake for c in controls])
    gaps = np.diff([c.wall for c in commands]) * 1e3
    reg = [c.registration_ms for c in corrections if math.isfinite(c.registration_ms)]
    err = np.array(errors) if errors else np.array([math.nan])
    f = {
        "mapping_ms_p50": percentile([(i.wall_end - i.wall_start) * 1e3 for i in integrations], 50),
        "mapping_ms_p95": percentile([(i.wall_end - i.wall_start) * 1e3 for i in integrations], 95),
        "control_ms_p50": percentile([(c.wall_solve_end - c.wall_wake) * 1e3 for c in controls], 50),
        "control_ms_p95": percentile([(c.wall_solve_end - c.wall_wake) * 1e3 for c in controls], 95),
        "control_period_ms_p50": percentile(np.diff(wakes) * 1e3, 50),
        "control_period_ms_p95": percentile(np.diff(wakes) * 1e3, 95),
        "control_period_ms_max": float(np.max(np.diff(wakes)) * 1e3) if len(wakes) > 1 else math.nan,
        "control_late_pct": 100.0 * late / max(steps, 1),
        "control_lateness_ms_p95": percentile(np.array(lateness) * 1e3, 95),
        "command_gap_ms_p50": percentile(gaps, 50),
        "command_gap_ms_p99": percentile(gaps, 99),
        "command_gap_ms_max": float(np.max(gaps)) if len(gaps) else math.nan,
        "interpreter_wait_ms_p99": percentile(waits, 99),
        "interpreter_wait_ms_max": float(np.max(waits)) if waits else math.nan,
        "ate_rmse_m": float(np.sqrt(np.nanmean(err**2))),
        "final_error_m": float(err[-1]),
        "faulted": float(fault is not None),
    }
    if enabled:
        ref = [c.reference_ms for c in corrections if c.reference_ms > 0]
        f |= {"registration_ms_p50": percentile(reg, 50), "registration_ms_p95": percentile(reg, 95),
              "reference_ms_p95": percentile(ref, 95), "reference_ms_max": float(max(ref)) if ref else math.nan,
              "registrations_per_s": len(corrections) / seconds,
              "accepted": float(sum(c.verdict == Verdict.ACCEPTED for c in corrections))}
        if condition == "on":
            f |= {"registration_wall_ms_p50": percentile(wall_ms, 50),
                  "registration_wall_ms_p95": percentile(wall_ms, 95)}
    return {f"{k}_{condition}": v for k, v in f.items()}


def main(argv: list[str] | None = None) -> dict[str, float]:
    args = bench_args("Localization live: registration time beside mapping and control, loops' timing on vs off",
                      argv)
    quiet_logs()
    seconds = QUICK_S if args.quick else FULL_S
    figures: dict[str, float] = {"load_avg_before": os.getloadavg()[0], "seconds_per_condition": seconds}
    for condition in CONDITIONS:
        figures |= run(condition, seconds)
    figures["load_avg_after"] = os.getloadavg()[0]
    figures["control_period_ms_p95_on_vs_off"] = (figures["control_period_ms_p95_on"]
                                                  - figures["control_period_ms_p95_off"])
    figures["command_gap_ms_p99_on_vs_off"] = figures["command_gap_ms_p99_on"] - figures["command_gap_ms_p99_off"]
    units = {k: ("ms" if "_ms" in k else "%" if "pct" in k else "m" if k.endswith(("_m", "_m_on", "_m_off",
                                                                                   "_m_inline"))
                 else "1/s" if "per_s" in k else "s" if k.startswith("seconds") else "") for k in figures}
    targets = {"registration_ms_p95_on": "<= 50", "control_late_pct_on": "<= control_late_pct_off + 1",
               "mapping_ms_p95_on": "~ mapping_ms_p95_off"}
    write_result(NAME, figures, units, targets, quick=args.quick)
    return figures


if __name__ == "__main__":
    main()
