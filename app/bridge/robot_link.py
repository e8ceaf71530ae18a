"""`RobotLink`: the bridge's side of the connection to one robot driver, shared by threads.

The WebSocket handler (uvicorn's event loop) puts accepted states, frames and acks in; the runtime's
threads (through `BridgeRobot`) take observations out and send commands, which the handler's outbox
delivers. Only validated data gets here: the handler rejects malformed messages and counts them with
`reject`. Times for freshness and round trips are this process's `time.monotonic()`.

Robot time (`t` of states, frames and commands) is the driver's clock, except that when a driver
reconnects with its clock restarted (a restarted sim driver begins at 0) the link adds an offset, so
the runtime's robot time never goes backwards; commands go out in the driver's own clock.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter, OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from app.bridge.protocol import STALE_AFTER_S, Ack, Command, CommandReason, RejectionCode, StateMessage
from core.errors import StudioError
from core.types import NQ, DepthFrame, Odometry, PoseSource, RobotState

log = logging.getLogger(__name__)

PENDING_ACKS = 1024
"""Sent commands remembered for their acks (older ones are forgotten, never measured)."""


class MessageRejectedError(StudioError, ValueError):
    """A message that validated but cannot be accepted (e.g. time going backwards); `code` names the kind."""

    def __init__(self, code: RejectionCode, message: str) -> None:
        super().__init__(message)
        self.code: RejectionCode = code


class LinkBusyError(StudioError, RuntimeError):
    """A second driver tried to connect while one is connected."""


@dataclass(frozen=True)
class SafetyEvent:
    """Something the safety logic did, at `at` (monotonic s), with the state's age then (s)."""

    at: float
    kind: str
    detail: str
    state_age_s: float


@dataclass(frozen=True)
class SentCommand:
    """A command the bridge issued (to the driver if one was connected), at `at` (monotonic s)."""

    seq: int
    t: float
    qdot: np.ndarray
    reason: CommandReason
    at: float
    delivered: bool


class RobotLink:
    """Latest state, queued frames, command sequence, round trips and counters of the robot link."""

    def __init__(self, stale_after_s: float = STALE_AFTER_S, frame_buffer: int = 32, rtt_window: int = 4096) -> None:
        self.stale_after_s = stale_after_s
        self._lock = threading.Lock()
        self._sender: Callable[[str, int], None] | None = None
        self.driver: str | None = None
        self._state: RobotState | None = None
        self._odometry: Odometry | None = None
        self.pose_source: PoseSource | None = None
        """The `pose_source` of the latest accepted state (None before any)."""
        self._state_at = -math.inf
        self._connection_t = -math.inf
        self.clock_offset = 0.0
        """Studio robot time minus driver time (non-zero after a driver reconnected with its clock restarted)."""
        self._frames: deque[DepthFrame] = deque()
        self._frame_buffer = frame_buffer
        self._frame_times: deque[float] = deque(maxlen=256)
        self._seq = 0
        self._pending: OrderedDict[int, float] = OrderedDict()
        self._rtt_ms: deque[float] = deque(maxlen=rtt_window)
        self.counts: Counter[str] = Counter()
        self.rejected: Counter[str] = Counter()
        self.events: deque[SafetyEvent] = deque(maxlen=512)
        self.last_command: SentCommand | None = None

    # --- connection --------------------------------------------------------------------------------

    def connect(self, sender: Callable[[str, int], None], driver: str = "driver") -> None:
        """A driver connected; `sender(text, seq)` delivers command `seq` to it, callable from any thread."""
        with self._lock:
            if self._sender is not None:
                raise LinkBusyError(f"driver {self.driver!r} is connected already; one driver at a time")
            self._sender, self.driver = sender, driver
            self._connection_t = -math.inf
        self.record("connected", driver)

    def disconnect(self) -> None:
        """The driver went away: its state is stale from now on."""
        with self._lock:
            self._sender = None
        self.record("disconnected", self.driver or "")

    @property
    def connected(self) -> bool:
        return self._sender is not None

    def name_driver(self, name: str) -> None:
        """The driver introduced itself (`hello`)."""
        self.driver = name

    # --- incoming ----------------------------------------------------------------------------------

    def _shift_clock(self, t: float) -> None:
        """On a connection's first state: if the driver's clock restarted behind the studio's, shift it
        so the runtime's time continues from where it was (its control loop needs time to increase)."""
        if self._connection_t == -math.inf and self._state is not None and t + self.clock_offset < self._state.t:
            self.clock_offset = self._state.t - t
            log.info("driver clock restarted at %.3f s: the studio's robot time continues from %.3f s", t,
                     self._state.t)

    def accept_state(self, msg: StateMessage) -> None:
        """Store a validated state; refuses time going backwards within one connection."""
        with self._lock:
            if msg.t < self._connection_t:
                raise MessageRejectedError("invalid_state", f"t went backwards: {msg.t} after {self._connection_t}")
            self._shift_clock(msg.t)
            self._connection_t = msg.t
            t = msg.t + self.clock_offset
            self._state = RobotState(t, np.array(msg.q, dtype=float), np.array(msg.v, dtype=float))
            odo = msg.odometry
            self._odometry = None if odo is None else Odometry(t, np.array(odo.pose), np.array(odo.twist))
            self.pose_source = PoseSource(msg.pose_source)
            self._state_at = time.monotonic()
            self.counts["states"] += 1

    def accept_frame(self, frame: DepthFrame) -> None:
        """Queue a validated depth frame for the next observation (the oldest is dropped when full)."""
        with self._lock:
            if len(self._frames) >= self._frame_buffer:
                self._frames.popleft()
                self.counts["frames_dropped"] += 1
            self._frames.append(replace(frame, t=frame.t + self.clock_offset))
            self._frame_times.append(time.monotonic())
            self.counts["frames"] += 1

    def accept_ack(self, ack: Ack) -> None:
        """Measure the round trip of an acknowledged command."""
        now = time.monotonic()
        with self._lock:
            sent = self._pending.pop(ack.seq, None)
            if sent is None:
                raise MessageRejectedError("stale_ack", f"ack of command {ack.seq}, which is not awaiting an ack")
            self._rtt_ms.append((now - sent) * 1e3)
            self.counts["acks"] += 1

    def reject(self, code: str, message: str) -> int:
        """Count a rejected message of kind `code`; returns how many of that kind so far."""
        with self._lock:
            self.rejected[code] += 1
            n = self.rejected[code]
        if n <= 10 or n % 100 == 0:
            log.warning("robot link: rejected %s #%d: %s", code, n, message)
        return n

    # --- outgoing ----------------------------------------------------------------------------------

    def send_command(self, qdot: np.ndarray, t: float, reason: CommandReason = "runtime") -> SentCommand:
        """Issue a command; delivered to the driver if one is connected. Returns what was issued."""
        with self._lock:
            self._seq += 1
            seq, sender = self._seq, self._sender
            msg = Command(seq=seq, t=t - self.clock_offset, qdot=[float(x) for x in qdot], reason=reason)
            now = time.monotonic()
            if sender is not None:
                self._pending[seq] = now
                while len(self._pending) > PENDING_ACKS:
                    self._pending.popitem(last=False)
                self.counts["commands_sent"] += 1
            sent = SentCommand(seq, t, np.asarray(qdot, dtype=float).copy(), reason, now, sender is not None)
            self.last_command = sent
            if sender is not None:
                sender(msg.model_dump_json(), seq)
        return sent

    def send_zero(self, reason: CommandReason) -> SentCommand:
        """Command zero velocity now (safety), stamped with the latest state's time."""
        sent = self.send_command(np.zeros(NQ), self.latest_t(), reason)
        self.record("zero_command", reason)
        return sent

    def superseded(self, seq: int) -> None:
        """The outbox replaced command `seq` by a newer one before sending it."""
        with self._lock:
            self._pending.pop(seq, None)
            self.counts["commands_superseded"] += 1

    # --- reading -----------------------------------------------------------------------------------

    def state_age_s(self) -> float:
        """Seconds since the latest state arrived; inf without a connected driver or before any state."""
        if self._sender is None:
            return math.inf
        return time.monotonic() - self._state_at

    def is_stale(self) -> bool:
        return self.state_age_s() > self.stale_after_s

    @property
    def state_received_at(self) -> float:
        """Monotonic time the latest state arrived (−inf before any)."""
        return self._state_at

    @property
    def state(self) -> RobotState | None:
        """The latest accepted state (None before any)."""
        return self._state

    def latest_t(self) -> float:
        state = self._state
        return state.t if state is not None else 0.0

    def take(self) -> tuple[RobotState | None, tuple[DepthFrame, ...], Odometry | None, PoseSource]:
        """Latest state (None before any), the frames queued since the previous call, latest odometry, and what
        the state's base pose is (odometry before any state)."""
        with self._lock:
            frames = tuple(self._frames)
            self._frames.clear()
            return self._state, frames, self._odometry, self.pose_source or PoseSource.ODOMETRY

    def rtt_ms(self) -> list[float]:
        """Recent command round trips (ms)."""
        with self._lock:
            return list(self._rtt_ms)

    def frame_rate(self, window_s: float = 5.0) -> float:
        """Depth frames per second that arrived over the last `window_s`."""
        now = time.monotonic()
        with self._lock:
            recent = [t for t in self._frame_times if now - t <= window_s]
        return len(recent) / window_s

    def count(self, name: str) -> None:
        """Add one to counter `name`."""
        with self._lock:
            self.counts[name] += 1

    def record(self, kind: str, detail: str = "") -> SafetyEvent:
        """Log a safety-relevant event (connect, disconnect, stale, fresh, zero command)."""
        event = SafetyEvent(time.monotonic(), kind, detail, self.state_age_s())
        self.events.append(event)
        log.info("robot link: %s %s (state age %.3f s)", kind, detail, event.state_age_s)
        return event
