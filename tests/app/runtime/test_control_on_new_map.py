"""A control step on a new map (`HTMPCParams.control_on_new_map`): the plan takes each new base frame in the command
tick the map took it, instead of up to a control period later; the steps a camera's frames trigger never come closer
than 1 / `control_max_rate_hz`, and no two steps further apart than the control period."""

from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from app.runtime import Runtime, RuntimeConfig
from core.params import HTMPCParams

DT_CMD_S = 0.01
EPS = 1e-9


@dataclass
class Steps:
    """Each control step's robot time, and for the steps that first see a base frame, that frame's arrival."""

    times: list[float] = field(default_factory=list)
    lags: list[tuple[float, float]] = field(default_factory=list)
    """(lag from the frame's arrival to the step, s; the gap to the step before, s)."""
    base_times: list[float] = field(default_factory=list)
    """The steps that first see a new base frame."""


def _control_steps(on_new_map: bool, seconds: float = 4.0) -> tuple[Steps, HTMPCParams]:
    htmpc = replace(HTMPCParams(), control_on_new_map=on_new_map)
    rt = Runtime(RuntimeConfig(map_kind="object", map_process=False, htmpc=htmpc))
    steps, seen = Steps(), [-1.0]
    latency = rt.closed_loop.camera_latency_s()

    def on_control(r: Runtime) -> None:
        t = r.time
        frame = r.closed_loop.latest_frames.get("base")
        if frame is not None and frame.t > seen[0]:
            seen[0] = frame.t
            gap = t - steps.times[-1] if steps.times else np.inf
            steps.lags.append((t - (frame.t + latency), gap))
            steps.base_times.append(t)
        steps.times.append(t)

    rt.run_lockstep(seconds, until_done=False, on_control=on_control)
    return steps, htmpc


def test_each_new_base_frame_reaches_a_plan_in_the_tick_the_map_took_it() -> None:
    steps, p = _control_steps(True)
    spacing = 1.0 / p.control_max_rate_hz
    assert len(steps.lags) >= 30, "a 10 Hz camera over 4 s"
    for lag, gap in steps.lags:
        # at once, unless the step before was too recent: then as soon as the spacing allows
        assert lag < DT_CMD_S + EPS or gap <= spacing + DT_CMD_S + EPS, (lag, gap)
    prompt = sum(lag < DT_CMD_S + EPS for lag, _ in steps.lags) / len(steps.lags)
    assert prompt >= 0.8, f"{prompt:.0%} of the base frames planned on in the tick they arrived"
    assert np.diff(steps.base_times).min() >= spacing - EPS, "a camera triggers no faster than control_max_rate_hz"
    assert np.diff(steps.times).max() <= 1.0 / p.control_rate_hz + EPS, "never slower than the control rate"


@pytest.mark.parametrize("on_new_map", [False])
def test_without_it_the_steps_keep_the_control_period_and_wait_for_it(on_new_map: bool) -> None:
    steps, p = _control_steps(on_new_map)
    assert np.allclose(np.diff(steps.times), 1.0 / p.control_rate_hz)
    triggered, _ = _control_steps(True)
    assert np.mean([lag for lag, _ in steps.lags]) > 4 * np.mean([lag for lag, _ in triggered.lags]), \
        "the new map waits for the period without the trigger"
