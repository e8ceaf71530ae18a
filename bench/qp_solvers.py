"""The controller's level QPs solved side by side: HPIPM through casadi (the controller's path) against every
fast QP solver installable from the package index, through `qpsolvers` (PIQP, DAQP, ProxQP, OSQP, Clarabel).

    python -m bench.qp_solvers [--quick]

The QPs are generated at bench time, not stored: a short deterministic lockstep run of the two-level
controller (`bench.htmpc_solve.closed_loop`, CBF rows on, ground-truth EDF) records every QP it solves, both
levels, with the collision rows active or not. Each is then solved by every solver at the controller's
tolerance (1e-6 absolute residuals) and compared with a tight reference solve (Clarabel at 1e-10):
median and p99 wall time of the call (argument conversion included, as the controller would pay it), the
solver's own time where it reports one, iterations, the largest constraint violation, and the objective gap.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from unittest import mock

import numpy as np
import scipy.sparse as sp

from bench.report import bench_args, percentile, write_result
from core.htmpc.ocp_qp import StructuredQP
from core.params import HTMPCParams
from core.robot.model import RobotModel

TOL = 1e-6
"""The controller's HPIPM residual tolerance (ocp_qp.HPIPM_OPTIONS), given to every solver."""
REFERENCE_TOL = 1e-10
SOLVER_OPTIONS: dict[str, dict[str, float]] = {
    "piqp": {"eps_abs": TOL, "eps_rel": 0.0, "compute_timings": True},
    "daqp": {"primal_tol": TOL},
    "proxqp": {"eps_abs": TOL, "eps_rel": 0.0, "compute_timings": True},
    "osqp": {"eps_abs": TOL, "eps_rel": 0.0, "max_iter": 10000, "polishing": True},
    "clarabel": {"tol_feas": TOL, "tol_gap_abs": TOL, "tol_gap_rel": 0.0},
}


@dataclass
class RecordedQP:
    """One level QP as the controller built it (H and A as casadi non-zeros of `qp`'s layout)."""

    qp: StructuredQP
    args: tuple[np.ndarray, ...]
    """(h_nz, g, a_nz, lba, uba, lbx, ubx, guess): `StructuredQP.solve`'s arguments."""

    @property
    def level(self) -> int:
        return 1 if self.qp.layout.n_lex == 0 else 2


@dataclass
class SolverLog:
    """One solver's results over the QP set (failures are counted, not timed)."""

    ms: list[float] = field(default_factory=list)
    solver_ms: list[float] = field(default_factory=list)
    iterations: list[float] = field(default_factory=list)
    violation: list[float] = field(default_factory=list)
    gap: list[float] = field(default_factory=list)
    failures: int = 0


def record_qps(seconds: float) -> list[RecordedQP]:
    """Every level QP of a two-level closed-loop run of `seconds` (deterministic lockstep)."""
    from bench.htmpc_solve import closed_loop

    recorded: list[RecordedQP] = []
    original = StructuredQP.solve

    def spy(self: StructuredQP, *args: np.ndarray):
        recorded.append(RecordedQP(self, tuple(np.array(a, float, copy=True) for a in args)))
        return original(self, *args)

    with mock.patch.object(StructuredQP, "solve", spy):
        closed_loop(RobotModel(), HTMPCParams(constraint="cbf"), 2, seconds, None, 1, "recording QPs")
    return recorded


def _csc(sparsity, nz: np.ndarray) -> sp.csc_matrix:
    return sp.csc_matrix((nz, np.asarray(sparsity.row()), np.asarray(sparsity.colind())),
                         shape=(sparsity.size1(), sparsity.size2()))


@dataclass(frozen=True)
class DenseForm:
    """A recorded QP as min ½ zᵀHz + gᵀz, A z (lba ≤ · ≤ uba), lbx ≤ z ≤ ubx with scipy matrices."""

    H: sp.csc_matrix
    g: np.ndarray
    A: sp.csc_matrix
    lba: np.ndarray
    uba: np.ndarray
    lbx: np.ndarray
    ubx: np.ndarray

    @classmethod
    def of(cls, rec: RecordedQP) -> DenseForm:
        h, g, a, lba, uba, lbx, ubx, _ = rec.args
        return cls(_csc(rec.qp.H_sp, h), g, _csc(rec.qp.A_sp, a), lba, uba, lbx, ubx)

    def problem(self):
        """The same QP as a `qpsolvers.Problem`: equality rows apart, two-sided rows split, infinite row sides
        dropped (infinite variable bounds stay `inf`: PIQP and ProxQP mistake a large finite one for a bound)."""
        import qpsolvers

        eq = self.lba == self.uba
        upper, lower = ~eq & np.isfinite(self.uba), ~eq & np.isfinite(self.lba)
        G = sp.vstack([self.A[upper], -self.A[lower]]).tocsc()
        h = np.concatenate([self.uba[upper], -self.lba[lower]])
        return qpsolvers.Problem(self.H, self.g, G, h, self.A[eq].tocsc(), self.lba[eq],
                                 self.lbx, self.ubx)

    def objective(self, z: np.ndarray) -> float:
        return float(0.5 * z @ (self.H @ z) + self.g @ z)

    def violation(self, z: np.ndarray) -> float:
        """Largest violation of any row or bound (the dynamics rows included)."""
        Az = self.A @ z
        return float(max(np.max(self.lba - Az), np.max(Az - self.uba), np.max(self.lbx - z), np.max(z - self.ubx),
                         0.0))

    def active_collision_rows(self, z: np.ndarray, qp: StructuredQP) -> int:
        """Collision rows (node and step rows) at their bound at z."""
        rows = np.concatenate([qp.row_col.ravel(), qp.row_step])
        Az = self.A[rows] @ z
        return int(np.sum(np.isfinite(self.lba[rows]) & (Az - self.lba[rows] < 1e-5)))


def _iterations(extras: dict) -> float:
    """The iteration count from a `qpsolvers` solution's extras, whatever the solver calls it."""
    info = extras.get("info")
    for obj in (info, extras):
        for key in ("iter", "iterations", "iter_count"):
            value = obj.get(key) if isinstance(obj, dict) else getattr(obj, key, None)
            if value is not None:
                return float(value)
    return float("nan")


def _solver_seconds(extras: dict) -> float:
    """The solver's own run time (s) where it reports one."""
    info = extras.get("info")
    for obj in (info, extras):
        for key, scale in (("run_time", 1.0), ("solve_time", 1.0), ("solve_time_s", 1.0)):
            value = obj.get(key) if isinstance(obj, dict) else getattr(obj, key, None)
            if value is not None:
                return float(value) * scale
    return float("nan")


Runner = Callable[[RecordedQP], tuple[np.ndarray | None, float, float, float]]
"""Solves a recorded QP: (z or None, wall ms from the controller's arrays, the solver's own ms, iterations)."""


def qpsolvers_runner(name: str, options: dict[str, float]) -> Runner:
    """A solver through `qpsolvers` (a fresh set-up per QP, as `qpsolvers` does)."""
    import qpsolvers

    def run(rec: RecordedQP) -> tuple[np.ndarray | None, float, float, float]:
        t0 = time.perf_counter()
        problem = DenseForm.of(rec).problem()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = qpsolvers.solve_problem(problem, name, **options)
        ms = (time.perf_counter() - t0) * 1e3
        solver_s = _solver_seconds(sol.extras)
        if name == "proxqp" and np.isfinite(solver_s):
            solver_s *= 1e-6  # ProxQP reports microseconds
        z = sol.x if sol.found and sol.x is not None else None
        return z, ms, solver_s * 1e3, _iterations(sol.extras)

    return run


class PiqpMultistage:
    """PIQP's own interface with its block-tridiagonal KKT solver (`sparse_multistage`), one solver per QP layout
    set up once and updated in place: what a controller using PIQP would do. The fixed initial state becomes
    equality rows (an interior point wants no equal bounds)."""

    def __init__(self) -> None:
        self._solvers: dict[int, object] = {}

    def __call__(self, rec: RecordedQP) -> tuple[np.ndarray | None, float, float, float]:
        import piqp

        t0 = time.perf_counter()
        form = DenseForm.of(rec)
        eq, fixed = form.lba == form.uba, form.lbx == form.ubx
        A = sp.vstack([form.A[eq], sp.eye(len(form.g), format="csc")[fixed]]).tocsc()
        b = np.concatenate([form.lba[eq], form.lbx[fixed]])
        args = (form.H, form.g, A, b, form.A[~eq].tocsc(), form.lba[~eq], form.uba[~eq],
                np.where(fixed, -np.inf, form.lbx), np.where(fixed, np.inf, form.ubx))
        solver = self._solvers.get(id(rec.qp))
        if solver is None:
            solver = piqp.SparseSolver()
            solver.settings.eps_abs, solver.settings.eps_rel = TOL, 0.0
            solver.settings.kkt_solver = piqp.KKTSolver.sparse_multistage
            solver.settings.compute_timings = True
            solver.setup(*args)
            self._solvers[id(rec.qp)] = solver
        else:
            solver.update(*args)
        status = solver.solve()
        ms = (time.perf_counter() - t0) * 1e3
        info = solver.result.info
        z = solver.result.x.copy() if status == piqp.PIQP_SOLVED else None
        return z, ms, info.run_time * 1e3, float(info.iter)


def reference(form: DenseForm) -> np.ndarray | None:
    """A tight solve (Clarabel at `REFERENCE_TOL`): the objective every solver is compared with."""
    import qpsolvers

    sol = qpsolvers.solve_problem(form.problem(), "clarabel", tol_feas=REFERENCE_TOL, tol_gap_abs=REFERENCE_TOL,
                                  tol_gap_rel=REFERENCE_TOL, max_iter=500)
    return sol.x if sol.found else None


def solve_all(recorded: list[RecordedQP], solvers: list[str]) -> tuple[dict[str, SolverLog], dict[str, float]]:
    """Every QP through every solver; returns the per-solver logs and counts of the QP set."""
    logs = {name: SolverLog() for name in ["hpipm_casadi", "piqp_multistage", *solvers]}
    runners: dict[str, Runner] = {name: qpsolvers_runner(name, SOLVER_OPTIONS[name]) for name in solvers}
    runners["piqp_multistage"] = PiqpMultistage()
    counts = {"qps": float(len(recorded)), "level2_qps": 0.0, "qps_with_active_collision_rows": 0.0,
              "reference_failures": 0.0}
    for rec in recorded:
        form = DenseForm.of(rec)
        z_ref = reference(form)
        if z_ref is None:
            counts["reference_failures"] += 1
            continue
        f_ref = form.objective(z_ref)
        counts["level2_qps"] += rec.level == 2
        counts["qps_with_active_collision_rows"] += form.active_collision_rows(z_ref, rec.qp) > 0
        sol = rec.qp.solve(*rec.args)
        _log(logs["hpipm_casadi"], form, sol.z if sol.success else None, sol.solve_ms, sol.hpipm_ms,
             float(sol.iterations), f_ref)
        for name, run in runners.items():
            z, ms, solver_ms, iterations = run(rec)
            _log(logs[name], form, z, ms, solver_ms, iterations, f_ref)
    return logs, counts


def _log(log: SolverLog, form: DenseForm, z: np.ndarray | None, ms: float, solver_ms: float, iterations: float,
         f_ref: float) -> None:
    if z is None or not np.all(np.isfinite(z)):
        log.failures += 1
        return
    log.ms.append(ms)
    log.solver_ms.append(solver_ms)
    log.iterations.append(iterations)
    log.violation.append(form.violation(z))
    log.gap.append(abs(form.objective(z) - f_ref) / max(1.0, abs(f_ref)))


def main(argv: list[str] | None = None) -> None:
    args = bench_args(__doc__.splitlines()[0], argv)
    load_before = os.getloadavg()[0]
    recorded = record_qps(2.0 if args.quick else 14.0)
    solvers = ["piqp", "daqp", "proxqp", "osqp", "clarabel"]
    logs, counts = solve_all(recorded, solvers)
    figures: dict[str, float] = dict(counts)
    units: dict[str, str] = {k: "" for k in counts}
    for name, log in logs.items():
        figures.update({
            f"{name}_median_ms": percentile(log.ms, 50),
            f"{name}_p99_ms": percentile(log.ms, 99),
            f"{name}_solver_median_ms": percentile(log.solver_ms, 50),
            f"{name}_iterations_median": percentile(log.iterations, 50),
            f"{name}_violation_max": float(np.max(log.violation)) if log.violation else float("nan"),
            f"{name}_objective_gap_max": float(np.max(log.gap)) if log.gap else float("nan"),
            f"{name}_failures": float(log.failures),
        })
        units.update({f"{name}_median_ms": "ms", f"{name}_p99_ms": "ms", f"{name}_solver_median_ms": "ms",
                      f"{name}_iterations_median": "", f"{name}_violation_max": "",
                      f"{name}_objective_gap_max": "rel", f"{name}_failures": ""})
    fastest = min((n for n in logs if logs[n].failures == 0), key=lambda n: percentile(logs[n].ms, 50))
    others = [n for n in logs if n != "hpipm_casadi"]
    figures["fastest_other_over_hpipm_x"] = min(percentile(logs[n].ms, 50) for n in others) / figures[
        "hpipm_casadi_median_ms"]
    units["fastest_other_over_hpipm_x"] = "x"
    figures["load_avg_before"], figures["load_avg_after"] = load_before, os.getloadavg()[0]
    write_result("qp_solvers", figures, units, {"hpipm_casadi_failures": "0"}, quick=args.quick,
                 extra={"fastest_without_failures": fastest, "tolerance": TOL, "reference_tolerance": REFERENCE_TOL})


if __name__ == "__main__":
    main()
