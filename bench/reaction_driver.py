"""The reference sim driver for the reaction benchmark through the bridge (`bench/bridge_reaction.py`): the same
`SimDriver` (MuJoCo in real time in its own process, two depth cameras, real sockets to the bridge), on the
reaction scene (`bench/reaction.py`), with a pipe to the benchmark beside the robot link.

Over the pipe, the benchmark asks the driver to put the box in the robot's way ("place") or out of it ("park");
the driver edits its world between two of its control cycles (no physics step between the edit and reading its
time), and answers with the placement: wall time right after the edit, robot time, the box as the robot's odometry
sees it, and the base's true distance to it. Every cycle it sends back, stamped on the wall clock right after the
cycle's physics step (`time.perf_counter()`: CLOCK_MONOTONIC, which the benchmark's process shares), the robot time
it reached, and the commands it applied then (their robot time), so the benchmark can put the frames' exposures
and stamps, and the moment the robot obeyed, on its own wall clock.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.driver_client import DriverClient
from app.bridge.sim_driver import SimDriver, _connect
from app.thread_priority import set_thread_niceness
from bench.experiments.measures import body_distance
from bench.reaction import PARK, box_ahead, reaction_scene
from core.params import SimParams
from core.robot.model import RobotModel
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld

log = logging.getLogger(__name__)

DRIVER_NICENESS = -10
"""As the reference driver asks for (`sim_driver --niceness`)."""


@dataclass(frozen=True)
class DriverPlacement:
    """A box put in the robot's way by the driver: wall (s, `perf_counter`) right after the edit, robot time, the
    box's points, face and direction from the base in the world the robot believes in, and the base's true
    distance to it (m)."""

    wall: float
    t: float
    points: list[list[float]]
    face: list[float]
    towards: list[float]
    distance_m: float


@dataclass(frozen=True)
class CycleStamps:
    """What one or more of the driver's cycles did: (robot time reached, wall right after the step) per cycle,
    and (robot time of the command, wall when applied) per command applied."""

    physics: list[tuple[float, float]]
    applied: list[tuple[float, float]]


class ReactionDriver(SimDriver):
    """`SimDriver` that also obeys the benchmark's pipe and reports its stamps on it."""

    def __init__(self, client: DriverClient, robot: SimRobot, pipe: Connection) -> None:
        super().__init__(client, robot)
        self.pipe = pipe
        self._physics: list[tuple[float, float]] = []
        self._applied: list[tuple[float, float]] = []

    def _apply_commands(self) -> None:
        """The benchmark's requests first (between two cycles), then the parent's command handling, noting when a
        new command is applied."""
        self._serve_requests()
        with self._lock:
            new, t = self._inbox.new, self._inbox.t
        super()._apply_commands()
        if new:
            self._applied.append((t, time.perf_counter()))

    def _publish(self) -> None:
        """Stamp the step just made, send the state and frames, then the stamps to the benchmark."""
        self._physics.append((self.robot.time, time.perf_counter()))
        super()._publish()
        self.pipe.send(CycleStamps(self._physics, self._applied))
        self._physics, self._applied = [], []

    def _serve_requests(self) -> None:
        while self.pipe.poll():
            request = self.pipe.recv()
            if request == "place":
                self.pipe.send(self._place())
            elif request == "park":
                self.robot.world.move_box("probe", PARK)
            elif request == "stop":
                self.stop()

    def _place(self) -> DriverPlacement:
        world = self.robot.world
        with world.lock:
            ahead = box_ahead(world, world.state().q, self.robot.state().q)
            world.move_box("probe", ahead.centre, ahead.yaw)
            wall, t = time.perf_counter(), world.time
            distance = body_distance(world, "base", (world.box("probe"),))
        return DriverPlacement(wall, t, ahead.points.tolist(), ahead.face.tolist(), ahead.towards.tolist(), distance)


def run_driver(url: str, token: str, pipe: Connection, log_level: str = "WARNING") -> int:
    """The driver process: connect to the bridge at `url`, then drive until the benchmark says "stop" (or the link
    is lost); its exit status as `sim_driver`'s."""
    logging.basicConfig(level=log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    set_thread_niceness(DRIVER_NICENESS)
    world = SimWorld(RobotModel(), SimParams(), reaction_scene())
    robot = SimRobot(world)
    client = DriverClient(url, token, name="reaction_driver", clock=lambda: world.time)
    if not _connect(client, 30.0):
        return 2
    try:
        return ReactionDriver(client, robot, pipe).run()
    finally:
        robot.close()
        pipe.close()
