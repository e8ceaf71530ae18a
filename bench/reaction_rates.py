"""What rates the two cores allow, measured: the reaction to a box in the robot's way (bench/reaction.py) with the
base camera and the control loop at 10 Hz each and faster (base camera 20 or 30 Hz, control 20 Hz), each with and
without a control step on every new map, one setting after the other in one run, beside how the live loops kept time at
each: control steps started more than one period late, how late (p99), the control step's time, the control steps a
second, and the frames the map integrated per second of each camera (when it falls behind, the mapping loop
integrates only the newest frame of each camera).

    python -m bench.reaction_rates [--quick] [--settings b10_c10_map20,b30_c10_map30] [--burners 2]

With `--burners N`, N processes that only burn CPU run beside every setting (`bench/bridge_driving.py`'s), and
the figures end in `_burn<N>`.

Figures are named `<figure>_<setting>`, the setting `b<base camera Hz>_c<control Hz>` (the hand camera stays at
10 Hz), with `_map<Hz>` where a control step also runs as soon as the map has taken a new frame, at most that many a
second (`HTMPCParams.control_on_new_map`, `control_max_rate_hz`; the settings without it switch it off).
"""

from __future__ import annotations

import argparse
import logging
import os
from dataclasses import replace

from app.runtime import RuntimeConfig
from bench.bridge_driving import burning
from bench.closed_loop import reaction_figures
from bench.reaction import measure_reactions
from bench.report import bench_args, write_result
from core.params import CameraParams, HTMPCParams, SimParams

log = logging.getLogger(__name__)

SETTINGS = ((10.0, 10.0, 0.0), (30.0, 10.0, 0.0), (30.0, 20.0, 0.0), (10.0, 10.0, 20.0), (20.0, 10.0, 20.0),
            (30.0, 10.0, 20.0), (30.0, 10.0, 30.0), (30.0, 20.0, 30.0))
"""(base camera Hz, control Hz, the most control steps a second a new map may trigger: 0 for none,
`HTMPCParams.control_on_new_map` and `control_max_rate_hz`)."""
EVENTS = {True: 10, False: 40}
KEPT = ("reaction_ms_p50", "reaction_ms_p95", "reaction_ms_max", "processing_ms_p95", "reaction_events",
        "reaction_frame_wait_ms_p50", "reaction_mapping_ms_p95", "reaction_control_wait_ms_p50",
        "reaction_control_wait_ms_p95", "reaction_solve_ms_p95", "reaction_command_ms_p50",
        "reaction_references_ms_p50", "reaction_references_ms_p95", "reaction_mapping_ms_p50",
        "reaction_mapping_queue_ms_p50", "reaction_mapping_queue_ms_p95", "processing_ms_p50")


def config(base_camera_hz: float, control_hz: float, triggered_hz: float = 0.0) -> RuntimeConfig:
    sim = SimParams()
    htmpc = replace(HTMPCParams(), control_rate_hz=control_hz, control_on_new_map=triggered_hz > 0,
                    control_max_rate_hz=triggered_hz or HTMPCParams().control_max_rate_hz)
    return RuntimeConfig(map_kind="object", htmpc=htmpc,
                         sim=replace(sim, base_camera=replace(CameraParams(), rate_hz=base_camera_hz)))


def setting_figures(base_camera_hz: float, control_hz: float, triggered_hz: float, events: int) -> dict[str, float]:
    """The reaction figures and the loops' health at one setting."""
    run = measure_reactions(events, max_wall_s=60.0 + 6.0 * events,
                            config=config(base_camera_hz, control_hz, triggered_hz))
    figures = {k: v for k, v in reaction_figures(run).items() if k in KEPT}
    return figures | run.health


def setting_name(base_hz: float, control_hz: float, triggered_hz: float) -> str:
    """`b<base camera Hz>_c<control Hz>`, with `_map<Hz>` where a new map triggers control steps."""
    return f"b{base_hz:.0f}_c{control_hz:.0f}" + (f"_map{triggered_hz:.0f}" if triggered_hz else "")


def add_options(parser: argparse.ArgumentParser) -> None:
    names = ", ".join(setting_name(*s) for s in SETTINGS)
    parser.add_argument("--settings", default="", help=f"comma-separated settings to run (default all: {names})")
    parser.add_argument("--burners", type=int, default=0, help="CPU burner processes beside the runs")


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0] if __doc__ else "", argv, add_options)
    chosen = [s for s in SETTINGS if not args.settings or setting_name(*s) in args.settings.split(",")]
    if not chosen:
        raise SystemExit(f"no setting named {args.settings!r}")
    figures: dict[str, float] = {"load_avg_before": os.getloadavg()[0], "burners": float(args.burners)}
    suffix = f"_burn{args.burners}" if args.burners else ""
    with burning(args.burners):
        for base_hz, control_hz, triggered_hz in chosen:
            name = setting_name(base_hz, control_hz, triggered_hz) + suffix
            log.info("setting %s", name)
            figures |= {f"{k}_{name}": v
                        for k, v in setting_figures(base_hz, control_hz, triggered_hz, EVENTS[args.quick]).items()}
    figures["load_avg_after"] = os.getloadavg()[0]
    units = {k: "ms" if "_ms_" in k else "%" if "_pct_" in k else "Hz" if "_hz_" in k else "" for k in figures}
    write_result("reaction_rates", figures, units, quick=args.quick)


if __name__ == "__main__":
    main()
