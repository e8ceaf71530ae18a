"""Reference driver: the MuJoCo robot in its own process, talking to the bridge over real sockets.

    python -m app.bridge.sim_driver [--url ws://127.0.0.1:8090/robot] [--token-file FILE] [--scene FILE]
                                    [--pose-source odometry|localized]

It behaves as a robot's driver should: the simulation (`SimWorld` + `SimRobot`) advances in real time;
state goes out at `--state-hz` (100), depth frames as the cameras render them (10 Hz each); every
command is acknowledged on receipt and applied at the next control cycle. Its base pose is its wheel odometry,
drifting as the sensor model's does (`--pose-source odometry`, the default: the studio localizes it when
localization is on), or, standing in for a robot with its own SLAM, the simulator's true pose, sent as
`"pose_source": "localized"` (`--pose-source localized`: the studio uses it as it is). Safety:
- no command for `--command-timeout` (0.25 s) → zero velocity until commands come back;
- the link closes or fails (the bridge went away) → zero velocity, exit with status 3.
Exit status 0 after `--duration` or SIGINT/SIGTERM; 2 when it cannot connect within `--connect-timeout`.
The token comes from `HTMPC_BRIDGE_TOKEN`, else `--token-file` (default: the user's token file), never
from the command line, where every user could read it in `ps`.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from websockets.exceptions import ConnectionClosed, InvalidStatus

import core.sim  # noqa: F401  (chooses the GL backend before mujoco is imported)
from app.bridge.auth import TOKEN_ENV, read_token
from app.bridge.driver_client import DriverClient
from app.bridge.protocol import Command, DepthEncoding, PoseSourceIn
from app.thread_priority import set_thread_niceness
from core.errors import StudioError
from core.params import SimParams
from core.robot.model import RobotModel
from core.scene import load_scene
from core.sim.sim_robot import SimRobot
from core.sim.world import SimWorld

log = logging.getLogger("app.bridge.sim_driver")

DEFAULT_SCENE = Path(__file__).parents[2] / "core" / "scenes" / "default.yaml"
EXIT_LINK_LOST = 3
EXIT_NO_CONNECTION = 2
MAX_LAG_S = 0.1


class LinkLostError(StudioError, ConnectionError):
    """The link to the bridge closed or failed."""


@dataclass
class _Inbox:
    """The latest command received (written by the receiver thread, read by the control loop)."""

    qdot: np.ndarray | None = None
    t: float = 0.0
    received_at: float = -np.inf
    new: bool = False
    lost: str | None = None


class SimDriver:
    """Runs a `SimRobot` in real time and bridges it to the link of a connected `DriverClient`."""

    def __init__(self, client: DriverClient, robot: SimRobot, state_hz: float = 100.0,
                 command_timeout_s: float = 0.25, encoding: DepthEncoding = "float32_m",
                 pose_source: PoseSourceIn = "odometry") -> None:
        self.client, self.robot = client, robot
        self.pose_source: PoseSourceIn = pose_source
        """What the state's base pose is, as sent (`pose_source` of every state)."""
        self.period_s = 1.0 / state_hz
        self.command_timeout_s = command_timeout_s
        self.encoding: DepthEncoding = encoding
        self._inbox = _Inbox()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.timed_out = True
        """Whether the robot was stopped for want of commands (true until the first command)."""

    def stop(self) -> None:
        """Ask the loop to end (signal handlers, tests)."""
        self._stop.set()

    def _receive_loop(self) -> None:
        try:
            while not self._stop.is_set():
                msg = self.client.receive(timeout_s=0.5)
                if isinstance(msg, Command):
                    with self._lock:
                        self._inbox = _Inbox(np.array(msg.qdot), msg.t, time.monotonic(), True)
        except (ConnectionClosed, OSError) as err:
            with self._lock:
                self._inbox.lost = f"link closed: {err}"

    def _apply_commands(self) -> None:
        """Apply a new command, or stop the robot once commands stopped coming."""
        with self._lock:
            command = self._inbox.qdot if self._inbox.new else None
            age = time.monotonic() - self._inbox.received_at
            self._inbox.new = False
        if command is not None:
            self.robot.command(command, self.robot.time)
            self.timed_out = False
        elif age > self.command_timeout_s and not self.timed_out:
            self.timed_out = True
            self.robot.stop()
            log.warning("no command for %.0f ms: stopped the robot", age * 1e3 if np.isfinite(age) else -1)

    def _publish(self) -> None:
        obs = self.robot.observe()
        self.client.send_state(obs.state.t, obs.state.q, obs.state.v, obs.odometry, self.pose_source)
        for frame in obs.frames:
            self.client.send_frame(frame, self.encoding)

    def _pace(self, next_tick: float) -> float:
        """Sleep until the next tick; a slow cycle (a camera rendering) is caught up by the following
        ones, so simulated time keeps up with wall time; beyond `MAX_LAG_S` behind, time is dropped."""
        next_tick += self.period_s
        delay = next_tick - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        elif delay < -MAX_LAG_S:
            log.warning("%.0f ms behind real time: dropping it", -delay * 1e3)
            next_tick = time.monotonic()
        return next_tick

    def run(self, duration_s: float | None = None) -> int:
        """Step, publish and obey until stopped, `duration_s` passes or the link is lost; the exit status."""
        receiver = threading.Thread(target=self._receive_loop, name="driver-receive", daemon=True)
        receiver.start()
        end = time.monotonic() + duration_s if duration_s else np.inf
        next_tick = time.monotonic()
        try:
            while not self._stop.is_set() and time.monotonic() < end:
                if self._inbox.lost:
                    raise LinkLostError(self._inbox.lost)
                self._apply_commands()
                self.robot.step(self.period_s)
                self._publish()
                next_tick = self._pace(next_tick)
        except (LinkLostError, ConnectionClosed, OSError) as err:
            self.robot.stop()
            log.warning("the bridge went away (%s): robot stopped, driver exits", err)
            print("sim driver: link lost, robot stopped", flush=True)
            return EXIT_LINK_LOST
        finally:
            self._stop.set()
            self.robot.stop()
        self.client.close()
        return 0


def _connect(client: DriverClient, timeout_s: float) -> bool:
    """Try until connected or `timeout_s`; a refused token ends at once."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            client.connect()
            return True
        except InvalidStatus as err:
            log.error("the bridge refused the link: %s", err)
            return False
        except OSError as err:
            if time.monotonic() > deadline:
                log.error("cannot reach %s: %s", client.url, err)
                return False
            time.sleep(0.2)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m app.bridge.sim_driver",
                                     description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--url", default="ws://127.0.0.1:8090/robot", help="the bridge's robot link")
    parser.add_argument("--token-file", type=Path, default=None,
                        help="file holding the bridge token, mode 0600 (default: HTMPC_BRIDGE_TOKEN, else "
                             "~/.config/htmpc-studio/bridge_token)")
    parser.add_argument("--token", help=argparse.SUPPRESS)
    parser.add_argument("--scene", type=Path, default=DEFAULT_SCENE, help="scene YAML the robot lives in")
    parser.add_argument("--state-hz", type=float, default=100.0, help="state rate (50–100 Hz)")
    parser.add_argument("--command-timeout", type=float, default=0.25, help="stop the robot after this long without "
                        "a command (s)")
    parser.add_argument("--cameras", default="hand,base", help="depth cameras to stream, comma-separated ('' none)")
    parser.add_argument("--encoding", choices=("float32_m", "uint16_mm"), default="float32_m")
    parser.add_argument("--pose-source", choices=("odometry", "localized"), default="odometry",
                        help="the base pose sent: the wheel odometry, drifting (the studio localizes it when "
                             "localization is on), or, as a robot with its own SLAM would, a localized pose (here the "
                             "simulator's true pose, used as it is)")
    parser.add_argument("--duration", type=float, default=None, help="exit after this many seconds")
    parser.add_argument("--connect-timeout", type=float, default=30.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--log-level", default="INFO")
    parser.add_argument("--niceness", type=int, default=-10,
                        help="scheduling niceness asked for: a robot's driver keeps time, so it runs before ordinary "
                             "programs where allowed (root or CAP_SYS_NICE; else normal priority)")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.token is not None:
        parser.error(f"--token is refused: every user can read a command line (ps). Set {TOKEN_ENV} or use "
                     "--token-file")
    try:
        token = read_token(args.token_file)
    except (OSError, ValueError) as err:
        parser.error(str(err))
    logging.basicConfig(level=args.log_level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    set_thread_niceness(args.niceness)  # before any thread starts: they inherit it
    try:
        world = SimWorld(RobotModel(), SimParams(), load_scene(args.scene))
    except (OSError, ValueError) as err:  # a bad file, or a box inside the robot (SceneEditError)
        parser.error(str(err))
    sensor = world.params.sensor
    if args.pose_source == "localized":  # its own SLAM, standing in: the true pose (the depth stays as noisy)
        sensor = replace(sensor, odometry_drift_m=0.0, odometry_drift_rad=0.0)
    robot = SimRobot(world, seed=args.seed, cameras=tuple(c for c in args.cameras.split(",") if c), sensor=sensor)
    client = DriverClient(args.url, token, name="sim_driver", clock=lambda: world.time)
    if not _connect(client, args.connect_timeout):
        return EXIT_NO_CONNECTION
    print(f"sim driver: connected to {args.url}", flush=True)
    driver = SimDriver(client, robot, args.state_hz, args.command_timeout, args.encoding, args.pose_source)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: driver.stop())
    try:
        return driver.run(args.duration)
    finally:
        robot.close()


if __name__ == "__main__":
    sys.exit(main())
