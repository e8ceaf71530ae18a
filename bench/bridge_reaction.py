"""Reaction time through the hardware bridge: bench/reaction.py's boxes put in front of the robot driving at 1 m/s,
with the runtime driving the reference sim driver in its own process through a real bridge (uvicorn on 127.0.0.1).

    python -m bench.bridge_reaction [--quick]

The same shuttle, box and reading as the embedded figure (`python -m bench.closed_loop --reaction-only`), with
the physics, the cameras and the box in the driver's process (`bench/reaction_driver.py`): the driver places the
box between two of its cycles and notes the wall time right after the edit (the start), and stamps its cycles and
the commands it applies on the wall clock the two processes share; the bridge's end notes each frame's arrival.
The parts are the embedded chain's plus the bridge's two hops (`bench/bridge_reaction_chain.py`): `link` (the
frame from the driver's stamp to the bridge) and `delivery` (the command from the bridge to the driver applying
it). `bridge_reaction_ms_*` runs from the placement to the robot obeying; `bridge_reaction_issued_ms_*` stops at
the command handed to the bridge, where the embedded figure stops. The runtime is told the driver's camera latency
(20 ms, as docs/bridge.md asks of a real driver); cruising is read from the state the driver reports.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import queue
import secrets
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field, replace
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path

import numpy as np

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.server import BridgeServer
from app.runtime import Runtime, RuntimeConfig
from app.runtime.snapshot import RunState
from app.runtime.stage_stamps import StageStamps
from bench.bridge_reaction_chain import BRIDGE_PARTS, BridgeReaction, LinkStamps, bridge_analyse
from bench.reaction import ReactionRun, await_reaction, cruising_at, loop_health, reaction_runtime, velocity_before
from bench.reaction_chain import Placement, Reaction
from bench.reaction_driver import CycleStamps, DriverPlacement, run_driver
from bench.report import bench_args, percentile, write_result
from core.params import MappingParams, SensorParams

log = logging.getLogger(__name__)

EVENTS = {True: 10, False: 100}
"""Reactions measured in a quick and a full run."""
MAX_WALL_S = {True: 150.0, False: 1800.0}
OBEY_WAIT_S = 0.5
"""Longest wait for the driver's stamps of the reacting command once the runtime's chain is read (wall s)."""


@dataclass
class BridgeReactionRun(ReactionRun[BridgeReaction]):
    """`ReactionRun` through the bridge: with the bridge's own stamps, the stale-state pauses restarted and the
    machine's load average (1, 5, 15 min) before and after."""

    link: LinkStamps = field(default_factory=lambda: LinkStamps.keeping(3000))
    stale_pauses: int = 0
    load: tuple[tuple[float, float, float], tuple[float, float, float]] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))


class DriverFeed:
    """The benchmark's end of the driver's pipe: a thread files the driver's stamps; `place` and `park` ask."""

    def __init__(self, pipe: Connection, stamps: StageStamps, link: LinkStamps, clock_offset: float) -> None:
        self.pipe, self.stamps, self.link, self.offset = pipe, stamps, link, clock_offset
        self._replies: queue.Queue[DriverPlacement] = queue.Queue()
        threading.Thread(target=self._read, name="driver-feed", daemon=True).start()

    def _read(self) -> None:
        while True:
            try:
                message = self.pipe.recv()
            except (EOFError, OSError):
                return
            if isinstance(message, CycleStamps):
                self.stamps.physics.extend((t + self.offset, wall) for t, wall in message.physics)
                self.link.applied.extend((t + self.offset, wall) for t, wall in message.applied)
            else:
                self._replies.put(message)

    def place(self, stamps: StageStamps, delta_safe_m: float, timeout_s: float = 2.0) -> Placement:
        """The box put in the robot's way by the driver, as a `Placement` on this process's clocks."""
        self.pipe.send("place")
        placed = self._replies.get(timeout=timeout_s)
        towards = np.array(placed.towards)
        return Placement(placed.wall, placed.t + self.offset, np.array(placed.points), np.array(placed.face),
                         towards, velocity_before(stamps, placed.wall, towards), placed.distance_m - delta_safe_m)

    def park(self) -> None:
        self.pipe.send("park")


def bridge_config() -> RuntimeConfig:
    """The embedded benchmark's configuration, told the driver's camera latency (its sensor model's offset)."""
    latency = SensorParams().camera_time_offset_s
    return RuntimeConfig(map_kind="object", mapping=replace(MappingParams(), camera_latency_s=latency))


def _note_arrivals(bridge: BridgeServer, link: LinkStamps) -> None:
    """Note each frame's arrival at the bridge (camera, robot time, wall) before the link queues it."""
    accept = bridge.link.accept_frame

    def noting(frame) -> None:
        link.arrivals.append((frame.camera, frame.t + bridge.link.clock_offset, time.perf_counter()))
        accept(frame)

    bridge.link.accept_frame = noting


@contextmanager
def bridged_runtime(stamps: StageStamps, link: LinkStamps) -> Iterator[tuple[Runtime, DriverFeed]]:
    """A real bridge, the reaction driver in its own process connected to it, and the reaction runtime driving it
    with `stamps` recording; all stopped on exit."""
    with tempfile.TemporaryDirectory() as tmp:
        bridge = BridgeServer(port=0, token=secrets.token_urlsafe(24), token_file=Path(tmp) / "token")
        bridge.start()
        _note_arrivals(bridge, link)
        ctx = multiprocessing.get_context("spawn")
        mine, theirs = ctx.Pipe()
        driver = ctx.Process(target=run_driver, args=(bridge.robot_url, bridge.token, theirs), daemon=True)
        driver.start()
        rt: Runtime | None = None
        try:
            _await_driver(bridge, driver, 120.0)
            rt = reaction_runtime(bridge_config(), backend=bridge.robot)
            bridge.attach(rt)
            rt.closed_loop.stamps = stamps
            yield rt, DriverFeed(mine, stamps, link, bridge.link.clock_offset)
        finally:
            if rt is not None:
                rt.shutdown()
            _stop(driver, mine)
            bridge.stop()


def _await_driver(bridge: BridgeServer, driver: BaseProcess, timeout_s: float) -> None:
    """Until the driver's first state arrives; RuntimeError if it exits or stays silent for `timeout_s`."""
    deadline = time.monotonic() + timeout_s
    while not bridge.robot.wait_for_state(0.5):
        if not driver.is_alive() or time.monotonic() > deadline:
            raise RuntimeError(f"the reaction driver sent no state (exit code {driver.exitcode})")


def _stop(driver: BaseProcess, pipe: Connection) -> None:
    with suppress(OSError):
        pipe.send("stop")
    driver.join(20.0)
    if driver.is_alive():
        driver.terminate()
        driver.join(5.0)


def await_bridge_reaction(rt: Runtime, run: BridgeReactionRun, placement: Placement) -> BridgeReaction | str:
    """The runtime's chain (`await_reaction`), then the driver's stamps of the reacting command."""
    chain: Reaction | str = await_reaction(rt, run.stamps, placement)
    if not isinstance(chain, Reaction):
        return chain
    mapping, cameras = rt.config.mapping, rt.config.sim
    voxel, range_m = mapping.edf_voxel_m, min(mapping.range_m, cameras.base_camera.range_m)
    deadline = time.perf_counter() + OBEY_WAIT_S
    while True:
        result = bridge_analyse(run.stamps, run.link, placement, chain, voxel, range_m)
        if isinstance(result, BridgeReaction) or time.perf_counter() > deadline:
            return result
        time.sleep(0.02)


def _ready(rt: Runtime, run: BridgeReactionRun) -> bool:
    """Running (a stale-state pause restarted, as an operator would), cruising, with EDFs coming."""
    if rt.run_state == RunState.PAUSED:
        run.stale_pauses += 1
        rt.start()
        return False
    recent = list(run.stamps.integrations)[-3:]
    return cruising_at(rt.state) and any(i.edf is not None for i in recent)


def measure_bridge_reactions(events: int, max_wall_s: float, keep_s: float = 30.0) -> BridgeReactionRun:
    """Live through the bridge: place boxes until `events` reactions are measured (or `max_wall_s` has passed)."""
    run = BridgeReactionRun(StageStamps(keep_s), link=LinkStamps.keeping(int(keep_s * 100)))
    load_before = os.getloadavg()
    with bridged_runtime(run.stamps, run.link) as (rt, feed):
        gamma, delta_safe = rt.controller.params.gamma, rt.controller.params.delta_safe_m
        rt.start_live()
        rt.start()
        start = time.perf_counter()
        while len(run.events) < events and time.perf_counter() < start + max_wall_s and rt.fault is None:
            if not _ready(rt, run):
                time.sleep(0.02)
                continue
            run.trial(feed.place(run.stamps, delta_safe), gamma, lambda p: await_bridge_reaction(rt, run, p), feed.park)
        run.health = loop_health(rt, run.stamps, time.perf_counter() - start)
    run.load = (load_before, os.getloadavg())
    return run


def bridge_reaction_figures(run: BridgeReactionRun) -> dict[str, float]:
    """The whole (to the robot obeying, and to the command issued), the part after the frame's stamp, each part
    (p50, p95), the same reaction in robot time, the counts and the loops' health."""
    reactions = run.reactions
    total, processing = [r.total_ms for r in reactions], [r.processing_ms for r in reactions]
    issued, sim = [r.issued_ms for r in reactions], [r.chain.sim_ms for r in reactions]
    figures = {"bridge_reaction_ms_p50": percentile(total, 50), "bridge_reaction_ms_p95": percentile(total, 95),
               "bridge_reaction_ms_max": max(total, default=float("nan")),
               "bridge_processing_ms_p50": percentile(processing, 50),
               "bridge_processing_ms_p95": percentile(processing, 95),
               "bridge_reaction_issued_ms_p50": percentile(issued, 50),
               "bridge_reaction_issued_ms_p95": percentile(issued, 95),
               "bridge_reaction_sim_ms_p50": percentile(sim, 50), "bridge_reaction_sim_ms_p95": percentile(sim, 95)}
    for part in BRIDGE_PARTS:
        values = [r.parts_ms[part] for r in reactions]
        figures |= {f"bridge_reaction_{part}_ms_p50": percentile(values, 50),
                    f"bridge_reaction_{part}_ms_p95": percentile(values, 95)}
    figures |= {"bridge_reaction_events": float(len(reactions)), "bridge_reaction_placements": float(run.placements),
                "bridge_reaction_constrained": float(run.constrained),
                "bridge_reaction_rejected": float(len(run.rejected)), "bridge_stale_pauses": float(run.stale_pauses),
                "load_average_1min_before": run.load[0][0], "load_average_1min_after": run.load[1][0]}
    return figures | {f"bridge_{name}": value for name, value in run.health.items()}


UNITS = {name: "ms" for name in ("bridge_reaction_ms_p50", "bridge_reaction_ms_p95", "bridge_reaction_ms_max",
                                 "bridge_processing_ms_p50", "bridge_processing_ms_p95",
                                 "bridge_reaction_issued_ms_p50", "bridge_reaction_issued_ms_p95",
                                 "bridge_reaction_sim_ms_p50", "bridge_reaction_sim_ms_p95")}
UNITS |= {f"bridge_reaction_{part}_ms_p{q}": "ms" for part in BRIDGE_PARTS for q in (50, 95)}
TARGETS = {"bridge_reaction_ms_p95": "<= 100", "bridge_processing_ms_p95": "<= 40"}
"""Issue 33's targets of the embedded figure, held against the bridge's too."""


def reaction_record(reaction: BridgeReaction) -> dict[str, float | str]:
    """One reaction for the JSON: the wholes, the parts, and how the chain went."""
    chain = reaction.chain
    return {"total_ms": reaction.total_ms, "issued_ms": reaction.issued_ms, "sim_ms": chain.sim_ms,
            "camera": chain.camera, "h_m": chain.h_m, "v_before_mps": chain.v_before_mps,
            "v_after_mps": chain.v_after_mps, "later_plans": chain.later_plans,
            "unseen_frames": chain.unseen_frames, **reaction.parts_ms}


def main(argv: list[str] | None = None) -> int:
    args = bench_args((__doc__ or "").splitlines()[0], argv)
    logging.basicConfig(level=logging.WARNING)
    run = measure_bridge_reactions(EVENTS[args.quick], MAX_WALL_S[args.quick])
    write_result("bridge_reaction", bridge_reaction_figures(run), UNITS, TARGETS, quick=args.quick,
                 extra={"rejected": run.rejected[:30], "reactions": [reaction_record(r) for r in run.reactions],
                        "load_before": run.load[0], "load_after": run.load[1]})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
