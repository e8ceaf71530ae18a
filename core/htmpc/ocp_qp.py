"""The structured QP of one HTMPC level, solved by HPIPM through casadi's `conic` interface.

Variables stage by stage: z = [x_0, u_0, x_1, u_1, …, x_N] with x_k = [q_k, v_k] (18) and
u_k = [a_k (9 accelerations), s_k (M collision slacks)]. Rows in HPIPM's order: for each stage k the
dynamics gap x_{k+1} = A x_k + B u_k, then the stage's own rows (collision rows with their slack,
lexicographic rows (7c) of earlier levels, the base's planar speed rows); the terminal rows (7c and speed at
node N) come last. The speed rows bound (vx, vy) · (cos θ, sin θ) for `SPEED_DIRECTIONS` directions θ: a
polygon inside the circle ‖(vx, vy)‖ ≤ the base's speed limit (the variable bounds alone are a square, whose
corners are √2 × the limit). Stage 0's rows
are the collision rows at the next control instant, on a_0 and s_0 only (x_0 is fixed by bounds); the
terminal node has no slack variables (HPIPM's casadi interface has no controls at stage N), so the
node collision rows cover nodes 1…N−1.

Two traps (docs/decisions.md, "HPIPM through casadi"): matrices must be passed with their sparse
pattern, or the structure is not detected, and casadi's default 1e-8 residual tolerances make HPIPM run
into its iteration limit, so they are loosened to 1e-6. The solver is called through a re-bound
`BufferedFunction` on preallocated numpy arrays: building `DM` arguments from numpy cost about as much as
HPIPM's own work (docs/decisions.md, "The QP through a re-bound buffer").
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from core.htmpc.buffered_function import BufferedFunction
from core.types import NQ

log = logging.getLogger(__name__)

NX = 2 * NQ
"""The state of the double integrator: x = [q, v]."""
SPEED_DIRECTIONS = 8
"""Directions θ = iπ/8 of the base's planar speed rows: a 16-gon whose corners touch the speed circle, its faces
at cos(π/16) = 98 % of the limit (`level_problem.set_speed_rows`)."""
HPIPM_OPTIONS = {"mode": "speed_abs", "res_g_max": 1e-6, "res_b_max": 1e-6, "res_d_max": 1e-6, "res_m_max": 1e-6,
                 "iter_max": 60, "warm_start": 1}
"""`warm_start` 1: the interior point starts from the primal guess (the linearisation point, or the previous
level's solution): fewer iterations, same costs (docs/decisions.md, "HPIPM warm start")."""
RESCUE_MODE = "balance"
"""HPIPM's mode for a second attempt when a solve in `speed_abs` stalls (status 1, iteration limit, or 2,
minimum step): such stalls come from a primal guess on the boundary of a narrow feasible set (the previous
level's optimum against its (7c) rows, a warm start at a velocity limit), and 'balance' solved every one we
met, where a cold start rescued only some and more iterations none (docs/decisions.md, "HPIPM warm
start"). It is not the default: it costs more per iteration."""


@dataclass
class LevelArrays:
    """A level's QP data: H and A as non-zeros, g and the row bounds dense."""

    h: np.ndarray
    g: np.ndarray
    a: np.ndarray
    lba: np.ndarray
    uba: np.ndarray


@dataclass(frozen=True)
class QPSolution:
    z: np.ndarray
    success: bool
    status: str
    iterations: int
    solve_ms: float
    rescued: bool = False
    """The first solve stalled and this is the second attempt's (`RESCUE_MODE`)."""
    hpipm_ms: float = float("nan")
    """HPIPM's own time inside casadi's call (casadi's `t_wall_solver`), attempts summed: `solve_ms` minus this
    is the price of the call from Python."""


class QPLayout:
    """Index bookkeeping of the stage-wise variables and rows."""

    def __init__(self, N: int, n_spheres: int, n_lex: int, slack_group: np.ndarray | None = None,
                 n_speed: int = SPEED_DIRECTIONS) -> None:
        self.N, self.M, self.n_lex, self.n_speed = N, n_spheres, n_lex, n_speed
        self.slack_group = np.arange(n_spheres) if slack_group is None else np.asarray(slack_group, int)
        """Which slack variable each sphere's row uses (several spheres may share one)."""
        self.n_slack = int(self.slack_group.max()) + 1
        self.nu = NQ + self.n_slack
        self.off_x = np.array([k * (NX + self.nu) for k in range(N + 1)])
        self.off_u = self.off_x[:N] + NX
        self.nv = N * (NX + self.nu) + NX
        self.ng = [n_spheres] + [n_spheres + n_lex + n_speed] * (N - 1) + [n_lex + n_speed]
        row = 0
        self.row_gap, self.row_con = [], []
        for k in range(N):
            self.row_gap.append(row)
            row += NX
            self.row_con.append(row)
            row += self.ng[k]
        self.row_con.append(row)
        self.na = row + self.ng[N]
        self.idx_q = self.off_x[:, None] + np.arange(NQ)
        """Variable indices of q_k, (N+1, 9); `idx_v` of v_k, `idx_a` (N, 9) of a_k, `idx_s` (N, slacks) of s_k:
        whole-horizon gathers and scatters in one numpy call, no loop over nodes."""
        self.idx_v = self.idx_q + NQ
        self.idx_a = self.off_u[:, None] + np.arange(NQ)
        self.idx_s = self.off_u[:, None] + NQ + np.arange(self.n_slack)

    def q(self, k: int) -> slice:
        return slice(self.off_x[k], self.off_x[k] + NQ)

    def v(self, k: int) -> slice:
        return slice(self.off_x[k] + NQ, self.off_x[k] + NX)

    def a(self, k: int) -> slice:
        return slice(self.off_u[k], self.off_u[k] + NQ)

    def s(self, k: int) -> slice:
        return slice(self.off_u[k] + NQ, self.off_u[k] + self.nu)

    def states(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q (N+1,9), v (N+1,9), a (N,9)) of a solution vector."""
        return z[self.idx_q], z[self.idx_v], z[self.idx_a]

    def pack(self, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
        """The variable vector of a trajectory (slacks zero): the inverse of `states`."""
        z = np.zeros(self.nv)
        z[self.idx_q] = q
        z[self.idx_v] = v
        z[self.idx_a] = a
        return z

    def slacks(self, z: np.ndarray) -> np.ndarray:
        """Slacks of nodes 1..N−1, (N−1, slacks)."""
        return z[self.idx_s[1:]]


def _pattern(layout: QPLayout) -> tuple[np.ndarray, np.ndarray]:
    """Structural non-zeros of H and A as boolean masks."""
    L = layout
    H = np.zeros((L.nv, L.nv), bool)
    A = np.zeros((L.na, L.nv), bool)
    for k in range(L.N + 1):
        H[L.q(k), L.q(k)] = True
        H[L.v(k), L.v(k)] = True
        if k < L.N:
            idx_a = np.arange(L.a(k).start, L.a(k).stop)
            H[idx_a, idx_a] = True
            idx_s = np.arange(L.s(k).start, L.s(k).stop)
            H[idx_s, idx_s] = True
    eye = np.eye(NQ, dtype=bool)
    for k in range(L.N):
        r = L.row_gap[k]
        A[r:r + NQ, L.q(k)] = eye
        A[r:r + NQ, L.v(k)] = eye
        A[r + NQ:r + NX, L.v(k)] = eye
        A[r:r + NQ, L.a(k)] = eye
        A[r + NQ:r + NX, L.a(k)] = eye
        A[r:r + NX, L.off_x[k + 1]:L.off_x[k + 1] + NX] = np.eye(NX, dtype=bool)
    r = L.row_con[0]
    A[r:r + L.M, L.a(0)] = True
    A[r + np.arange(L.M), L.s(0).start + L.slack_group] = True
    for k in range(1, L.N):
        r = L.row_con[k]
        A[r:r + L.M, L.q(k)] = True
        A[r:r + L.M, L.v(k)] = True
        A[r + np.arange(L.M), L.s(k).start + L.slack_group] = True
        A[r + L.M:r + L.M + L.n_lex, L.q(k)] = True
    r = L.row_con[L.N]
    A[r:r + L.n_lex, L.q(L.N)] = True
    for k in range(1, L.N + 1):
        A[speed_rows(L, k)[:, None], L.v(k).start + np.arange(2)[None, :]] = True
    return H, A


def speed_rows(layout: QPLayout, k: int) -> np.ndarray:
    """Row indices of the base's planar speed rows at node k (1..N): after the collision and (7c) rows."""
    L = layout
    start = L.row_con[k] + (L.M if k < L.N else 0) + L.n_lex
    return start + np.arange(L.n_speed)


def _csc_coords(mask: np.ndarray) -> tuple[ca.Sparsity, np.ndarray]:
    """casadi sparsity of a mask, and a dense map (row, col) → non-zero index (−1 outside the pattern)."""
    cols, rows = np.nonzero(mask.T)  # transposed C order = column by column, rows ascending (CSC)
    sp = ca.Sparsity.triplet(mask.shape[0], mask.shape[1], rows.tolist(), cols.tolist())
    pos = np.full(mask.shape, -1, dtype=np.int64)
    pos[rows, cols] = np.arange(len(rows))
    return sp, pos


class StructuredQP:
    """One HPIPM solver for a fixed layout. Matrices travel as non-zero vectors in casadi's order;
    `*_index` give the non-zero positions of the blocks the level assembly writes."""

    def __init__(self, layout: QPLayout, dt: float) -> None:
        self.layout = layout
        self.dt = dt
        H_mask, A_mask = _pattern(layout)
        self.H_sp, self.H_pos = _csc_coords(H_mask)
        self.A_sp, self.A_pos = _csc_coords(A_mask)
        L = layout
        opts = {"N": L.N, "nx": [NX] * (L.N + 1), "nu": [L.nu] * L.N + [0], "ng": L.ng,
                "hpipm": dict(HPIPM_OPTIONS), "error_on_fail": False}
        self.solver = ca.conic("htmpc_qp", "hpipm", {"h": self.H_sp, "a": self.A_sp}, opts)
        self._opts = opts
        self._call_buffer = BufferedFunction(self.solver, rebind=True)
        self._rescue: BufferedFunction | None = None
        self.level_templates: dict[tuple, LevelArrays] = {}
        """The constant part of a level's data per (parameters, damping), built once by `level_problem.base_arrays`."""
        self._solver_s: dict[int, float] = {}
        """casadi's `t_wall_solver` per buffer at its last call (a buffer's statistics accumulate over calls)."""
        self.A_dynamics_nz = self._dynamics_nz()
        self.H_qq = np.stack([self.H_pos[L.q(k), L.q(k)] for k in range(L.N + 1)])
        self.H_vv = np.stack([self.H_pos[L.v(k), L.v(k)] for k in range(L.N + 1)])
        self.H_aa = np.stack([np.diag(self.H_pos[L.a(k), L.a(k)]) for k in range(L.N)])
        self.H_ss = np.stack([np.diag(self.H_pos[L.s(k), L.s(k)]) for k in range(L.N)])
        inner = range(1, L.N)
        self.A_col_q = np.stack([self.A_pos[L.row_con[k]:L.row_con[k] + L.M, L.q(k)] for k in inner])
        self.A_col_v = np.stack([self.A_pos[L.row_con[k]:L.row_con[k] + L.M, L.v(k)] for k in inner])
        self.A_col_s = np.stack([self.A_pos[L.row_con[k] + np.arange(L.M), L.s(k).start + L.slack_group]
                                 for k in inner])
        self.A_lex_q = np.stack([self.A_pos[self.lex_rows(k), L.q(k)] for k in range(1, L.N + 1)])
        self.row_col = np.stack([L.row_con[k] + np.arange(L.M) for k in inner])
        step = L.row_con[0] + np.arange(L.M)
        self.A_step_a = self.A_pos[step[:, None], np.arange(L.a(0).start, L.a(0).stop)[None, :]]
        self.A_step_s = self.A_pos[step, L.s(0).start + L.slack_group]
        self.row_step = step
        """Stage 0's rows: the collision rows at the next control instant, in a_0 (and their slack s_0)."""
        self.row_lex = np.stack([self.lex_rows(k) for k in range(1, L.N + 1)])
        self.row_speed = np.stack([speed_rows(L, k) for k in range(1, L.N + 1)])
        """(N, n_speed) rows of the base's planar speed at nodes 1..N; `A_speed_v` their non-zeros in (vx, vy)."""
        self.A_speed_v = np.stack([self.A_pos[speed_rows(L, k)[:, None], L.v(k).start + np.arange(2)[None, :]]
                                   for k in range(1, L.N + 1)])

    def lex_rows(self, k: int) -> np.ndarray:
        """Row indices of the (7c) rows at node k (1..N)."""
        L = self.layout
        start = L.row_con[k] + (L.M if k < L.N else 0)
        return start + np.arange(L.n_lex)

    def _dynamics_nz(self) -> np.ndarray:
        """The constant dynamics rows x_{k+1} = [[I, dt I], [0, I]] x_k + [[dt²/2 I], [dt I]] a_k as non-zeros."""
        L, dt = self.layout, self.dt
        nz = np.zeros(self.A_sp.nnz())
        idx = np.arange(NQ)
        for k in range(L.N):
            r = L.row_gap[k]
            q0, v0, a0, x1 = L.q(k).start, L.v(k).start, L.a(k).start, L.off_x[k + 1]
            nz[self.A_pos[r + idx, q0 + idx]] = 1.0
            nz[self.A_pos[r + idx, v0 + idx]] = dt
            nz[self.A_pos[r + NQ + idx, v0 + idx]] = 1.0
            nz[self.A_pos[r + idx, a0 + idx]] = 0.5 * dt * dt
            nz[self.A_pos[r + NQ + idx, a0 + idx]] = dt
            nz[self.A_pos[r + np.arange(NX), x1 + np.arange(NX)]] = -1.0
        return nz

    def solve(self, h_nz: np.ndarray, g: np.ndarray, a_nz: np.ndarray, lba: np.ndarray, uba: np.ndarray,
              lbx: np.ndarray, ubx: np.ndarray, guess: np.ndarray | None = None) -> QPSolution:
        """Solve with H and A given as non-zeros; `guess` (primal) warm-starts HPIPM's interior point."""
        t0 = time.perf_counter()
        if not (np.all(np.isfinite(h_nz)) and np.all(np.isfinite(a_nz)) and np.all(np.isfinite(g))):
            return QPSolution(np.full(self.layout.nv, np.nan), False, "non-finite QP data", 0, 0.0)
        args = (h_nz, g, a_nz, lba, uba, lbx, ubx, np.zeros(self.layout.nv) if guess is None else guess)
        z, ok, status, iters, hpipm_ms = self._call(self._call_buffer, args)
        if not ok and status in ("1", "2"):  # stalled: iteration limit or minimum step (`RESCUE_MODE`)
            z, ok, again, more, again_ms = self._call(self._rescue_solver(), args)
            status, iters = f"{status}, {RESCUE_MODE} {again}", iters + more
            return QPSolution(z, ok, status, iters, (time.perf_counter() - t0) * 1e3, rescued=True,
                              hpipm_ms=hpipm_ms + again_ms)
        return QPSolution(z, ok, status, iters, (time.perf_counter() - t0) * 1e3, hpipm_ms=hpipm_ms)

    def _rescue_solver(self) -> BufferedFunction:
        """The same QP in HPIPM's `RESCUE_MODE`, built on first need (tens of ms, rare)."""
        if self._rescue is None:
            opts = dict(self._opts, hpipm=dict(self._opts["hpipm"], mode=RESCUE_MODE))
            solver = ca.conic("htmpc_qp_rescue", "hpipm", {"h": self.H_sp, "a": self.A_sp}, opts)
            self._rescue = BufferedFunction(solver, rebind=True)
        return self._rescue

    def _call(self, solver: BufferedFunction,
              args: tuple[np.ndarray, ...]) -> tuple[np.ndarray, bool, str, int, float]:
        """One HPIPM call on (h, g, a, lba, uba, lbx, ubx, x0): (z, success, HPIPM's status, iterations, HPIPM's
        own ms). The multipliers' warm start (lam_x0, lam_a0) stays zero: `warm_start` 1 uses the primal only."""
        for buffer, value in zip(solver.inputs, args, strict=False):
            buffer[:] = value
        for buffer in solver.inputs[len(args):]:
            buffer[:] = 0.0
        try:
            solver.evaluate()
        except RuntimeError as err:  # casadi raises on malformed input
            return np.full(self.layout.nv, np.nan), False, f"solver error: {err}", 0, float("nan")
        stats = solver.stats()
        z = solver.outputs[0].copy()
        ok = bool(stats.get("success", False)) and bool(np.all(np.isfinite(z)))
        total_s = float(stats.get("t_wall_solver", float("nan")))
        hpipm_ms = (total_s - self._solver_s.get(id(solver), 0.0)) * 1e3
        self._solver_s[id(solver)] = total_s
        return z, ok, str(stats.get("return_status", "")), int(stats.get("iter_count", -1)), hpipm_ms
