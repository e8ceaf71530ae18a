"""The symbols the studio writes into its text, each one Debian's DejaVu fonts have (chromium on a machine
without emoji fonts draws a missing one as an empty box). A browser test checks every one of them."""

from __future__ import annotations

from app.runtime.snapshot import RunState

RUN_STATE = {RunState.RUNNING: "▶", RunState.PAUSED: "‖", RunState.ESTOP: "⊘", RunState.FINISHED: "✔",
             RunState.FAILED: "✖", RunState.IDLE: "■", RunState.FAULT: "⚠"}
"""Run state → glyph for the status line (not ⏸ or ⛔: no font here has them)."""
OTHER_STATE = "■"
OUTCOME = {"done": "✔", "failed": "✖", "active": "▶", "pending": "·", "skipped": "»"}
WARNING = "⚠"

ALL = frozenset("".join([*RUN_STATE.values(), OTHER_STATE, *OUTCOME.values(), WARNING]))
