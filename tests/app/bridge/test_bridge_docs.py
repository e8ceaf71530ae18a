"""docs/bridge.md says what the code does: the welcome example, every command reason and error code, the
ready pose and the speed limits are checked against the code, so the two cannot drift apart."""

from __future__ import annotations

import re
import typing

import numpy as np

from app.bridge.protocol import STALE_AFTER_S, CommandReason, ErrorMessage, Welcome
from core.params import RobotParams
from core.robot.model import READY_Q
from tests.app.bridge.conftest import ROOT

DOC = (ROOT / "docs" / "bridge.md").read_text()
FLAT = " ".join(DOC.split())
"""The text with line breaks as spaces (for phrases that wrap)."""


def _table_first_column(heading: str) -> set[str]:
    """The `code` cells of the first column of the markdown table whose header starts with `heading`."""
    block = DOC.split(f"| {heading} |", 1)[1].split("\n\n", 1)[0]
    return set(re.findall(r"^\| `([a-z_]+)` \|", block, flags=re.MULTILINE))


def test_the_welcome_example_is_what_the_bridge_sends() -> None:
    assert Welcome().model_dump_json() in DOC
    assert Welcome().stale_after_s == STALE_AFTER_S and f"older than {STALE_AFTER_S * 1e3:.0f} ms" in FLAT


def test_every_command_reason_and_error_code_is_documented_exactly() -> None:
    assert _table_first_column("reason") == set(typing.get_args(CommandReason))
    assert _table_first_column("code") == set(typing.get_args(ErrorMessage.model_fields["code"].annotation))


def test_ready_pose_and_speed_limits_match_the_code() -> None:
    arm = re.search(r"\*\*Ready pose\*\*: arm joints `\[([^\]]+)\]`", FLAT).group(1)
    np.testing.assert_allclose([float(x) for x in arm.split(",")], READY_Q[3:], atol=1e-4)
    v_max = RobotParams().v_max
    assert f"base x and y {v_max[0]:.1f} m/s, yaw {v_max[2]:.2f} rad/s" in FLAT
    assert "arm joints " + ", ".join(f"{v:g}" for v in v_max[3:]) + " rad/s" in FLAT
    assert f"the norm of (x, y), {RobotParams().base_speed_mps:.1f} m/s too" in FLAT


def test_the_command_rate_paragraph_states_the_codes_period_and_priorities() -> None:
    from app.bridge.sim_driver import build_parser
    from app.runtime import RuntimeConfig
    from app.runtime.map_process import NICENESS
    from core.params import HTMPCParams

    paragraph = FLAT.split("**The command rate a driver sees.**", 1)[1].split("received.", 1)[0]
    rate = HTMPCParams().command_rate_hz
    assert f"every command period ({1e3 / rate:.0f} ms, {rate:.0f} Hz)" in paragraph
    niceness = RuntimeConfig().live_niceness
    assert f"niceness {niceness}" in paragraph and f"runs {NICENESS} above them" in paragraph
    assert f"reference driver at {build_parser().get_default('niceness')} too" in paragraph
