"""The problems panel: QP failures, fallback plans, slow solves, faults, stale state, watchdog events and unknown
space ahead, with counts and times (`app.runtime.problems`); a one-line summary stays in view under the status."""

from __future__ import annotations

import viser

from app.runtime.problems import ProblemCount, ProblemKind
from app.runtime.snapshot import Snapshot
from app.ui import glyphs


class ProblemsPanel:
    """`summary` at the top of the sidebar; `build_table` puts the table in the active container (a tab)."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.summary = server.gui.add_markdown("", order=3)
        self.table = None
        self._shown: tuple[ProblemCount, ...] | None = None

    def build_table(self) -> None:
        self.table = self.server.gui.add_markdown(self._table(()))

    def update(self, snap: Snapshot) -> None:
        if snap.problems == self._shown:
            return
        self._shown = snap.problems
        total = sum(c.count for c in snap.problems)
        self.summary.content = "" if not total else (
            f"{glyphs.WARNING} **{total} problem{'s' * (total != 1)}**: "
            + ", ".join(c.kind.counted(c.count) for c in snap.problems) + " (Problems tab)")
        if self.table is not None:
            self.table.content = self._table(snap.problems)

    @staticmethod
    def _table(counts: tuple[ProblemCount, ...]) -> str:
        by_kind = {c.kind: c for c in counts}
        rows = ["| problem | count | first | last | last message |", "|---|---:|---:|---:|---|"]
        for kind in ProblemKind:
            c = by_kind.get(kind)
            if c is None:
                rows.append(f"| {kind.label} | 0 | | | |")
            else:
                message = c.last_message.replace("|", "/")[:160]
                rows.append(f"| **{kind.label}** | **{c.count}** | {c.first_t:.1f} s | {c.last_t:.1f} s | {message} |")
        return "\n".join(rows)
