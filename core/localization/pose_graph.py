"""A planar pose graph: keyframe poses x_i = (x, y, ψ) in the world, tied by factors, optimised by Gauss–Newton.

Factors, each a residual r with an information Ω = Wᵀ W (W whitens: ‖W r‖² = rᵀ Ω r; Ω may be rank-deficient,
e.g. a registration's masked directions):
  - prior (unary) on x_i:       r = x_i ⊖ z                        (x-y difference, wrapped ψ difference)
  - between x_a → x_b:          r = Rₐᵀ (x_b − x_a ∘ z)            (the same in x_a's frame; Rₐ = R₃(ψ_a))
    (odometry between keyframes, and loop closures: a registration of x_b's frame against keyframes placed
    around x_a), with W given in x_a's frame.
Each step solves the normal equations (Jᵀ J + λ I) δ = −Jᵀ e on the whitened residuals e (scipy.sparse, one
thread: deterministic), x ← x ⊕ δ. Factors carry a kind; `marginal` can leave kinds out (the covariance of a
node as if those factors were not there: what odometry and loop closures alone say).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

DAMPING = 1e-9
"""λ: keeps the normal equations regular where nothing constrains a direction."""


def whitening(information: np.ndarray) -> np.ndarray:
    """W with Wᵀ W = Ω (Ω symmetric positive semi-definite, 3×3)."""
    values, vectors = np.linalg.eigh(0.5 * (information + information.T))
    return np.diag(np.sqrt(np.maximum(values, 0.0))) @ vectors.T


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


class PoseGraph:
    """Nodes (n × 3 poses), prior and between factors, and their Gauss–Newton optimisation."""

    def __init__(self) -> None:
        self.x = np.zeros((0, 3))
        self._prior_i: list[int] = []
        self._prior_z: list[np.ndarray] = []
        self._prior_w: list[np.ndarray] = []
        self._prior_kind: list[str] = []
        self._between_ab: list[tuple[int, int]] = []
        self._between_z: list[np.ndarray] = []
        self._between_w: list[np.ndarray] = []
        self._between_kind: list[str] = []

    @property
    def size(self) -> int:
        return len(self.x)

    def add_node(self, pose: np.ndarray) -> int:
        """A new node at `pose` (its initial value); its index."""
        self.x = np.vstack([self.x, np.asarray(pose, float)[:3]])
        return len(self.x) - 1

    def add_prior(self, i: int, z: np.ndarray, information: np.ndarray, kind: str) -> None:
        """x_i measured at z (world) with information Ω (3 × 3, world x, y, ψ)."""
        self._prior_i.append(i)
        self._prior_z.append(np.asarray(z, float)[:3].copy())
        self._prior_w.append(whitening(information))
        self._prior_kind.append(kind)

    def add_between(self, a: int, b: int, z: np.ndarray, information_a: np.ndarray, kind: str) -> None:
        """x_b measured at x_a ∘ z, information Ω (3 × 3) in x_a's frame."""
        self._between_ab.append((a, b))
        self._between_z.append(np.asarray(z, float)[:3].copy())
        self._between_w.append(whitening(information_a))
        self._between_kind.append(kind)

    def count(self, kind: str) -> int:
        """Factors of this kind."""
        return self._prior_kind.count(kind) + self._between_kind.count(kind)

    def optimize(self, iterations: int, tolerance: float = 1e-6) -> int:
        """Gauss–Newton from the current values; the iterations run (stops once max |δ| < tolerance)."""
        for k in range(iterations):
            J, e = self._linearized(())
            H = (J.T @ J + DAMPING * sp.identity(3 * self.size)).tocsc()
            delta = -spla.spsolve(H, J.T @ e)
            delta = np.asarray(delta, float).reshape(-1, 3)
            self.x = self.x + delta
            self.x[:, 2] = _wrap(self.x[:, 2])
            if float(np.max(np.abs(delta))) < tolerance:
                return k + 1
        return iterations

    def marginal(self, i: int, without: tuple[str, ...] = ()) -> np.ndarray:
        """The covariance (3 × 3) of node i at the current values, factors of the kinds in `without` left out."""
        return self._covariance((i,), without)

    def relative(self, a: int, b: int, without: tuple[str, ...] = ()) -> np.ndarray:
        """The covariance (3 × 3) of x_b − x_a (world x, y, ψ differences) at the current values, factors of the kinds
        in `without` left out: how far b may be from where a's neighbourhood says."""
        if a == b:
            return np.zeros((3, 3))
        joint = self._covariance((a, b), without)
        A = np.hstack([-np.eye(3), np.eye(3)])
        return A @ joint @ A.T

    def _covariance(self, nodes: tuple[int, ...], without: tuple[str, ...]) -> np.ndarray:
        J, _ = self._linearized(without)
        H = (J.T @ J + DAMPING * sp.identity(3 * self.size)).tocsc()
        idx = np.concatenate([np.arange(3 * i, 3 * i + 3) for i in nodes])
        E = np.zeros((3 * self.size, len(idx)))
        E[idx, np.arange(len(idx))] = 1.0
        block = spla.splu(H).solve(E)[idx]
        return 0.5 * (block + block.T)

    def _linearized(self, without: tuple[str, ...]) -> tuple[sp.csr_matrix, np.ndarray]:
        """The whitened Jacobian J (m × 3n) and residuals e at the current values."""
        n = self.size
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        vals: list[np.ndarray] = []
        residuals: list[np.ndarray] = []
        row0 = 0
        keep_p = [k for k, kind in enumerate(self._prior_kind) if kind not in without]
        if keep_p:
            idx = np.array([self._prior_i[k] for k in keep_p])
            Z = np.array([self._prior_z[k] for k in keep_p])
            W = np.array([self._prior_w[k] for k in keep_p])
            r = self.x[idx] - Z
            r[:, 2] = _wrap(r[:, 2])
            residuals.append(np.einsum("kij,kj->ki", W, r).ravel())
            r_i, c_i = _block_index(len(idx), row0, idx)
            rows.append(r_i)
            cols.append(c_i)
            vals.append(W.ravel())
            row0 += 3 * len(idx)
        keep_b = [k for k, kind in enumerate(self._between_kind) if kind not in without]
        if keep_b:
            ab = np.array([self._between_ab[k] for k in keep_b])
            a, b = ab[:, 0], ab[:, 1]
            Z = np.array([self._between_z[k] for k in keep_b])
            W = np.array([self._between_w[k] for k in keep_b])
            xa, xb = self.x[a], self.x[b]
            c, s = np.cos(xa[:, 2]), np.sin(xa[:, 2])
            r = np.empty_like(Z)
            r[:, 0] = xb[:, 0] - xa[:, 0] - (c * Z[:, 0] - s * Z[:, 1])
            r[:, 1] = xb[:, 1] - xa[:, 1] - (s * Z[:, 0] + c * Z[:, 1])
            r[:, 2] = _wrap(xb[:, 2] - xa[:, 2] - Z[:, 2])
            RT = np.zeros((len(a), 3, 3))  # R₃(ψ_a)ᵀ: the residual in x_a's frame
            RT[:, 0, 0], RT[:, 0, 1], RT[:, 1, 0], RT[:, 1, 1], RT[:, 2, 2] = c, s, -s, c, 1.0
            M = W @ RT
            residuals.append(np.einsum("kij,kj->ki", M, r).ravel())
            Ja = np.zeros((len(a), 3, 3))
            Ja[:, 0, 0] = Ja[:, 1, 1] = Ja[:, 2, 2] = -1.0
            Ja[:, 0, 2] = s * Z[:, 0] + c * Z[:, 1]
            Ja[:, 1, 2] = -(c * Z[:, 0] - s * Z[:, 1])
            for block, nodes in ((M @ Ja, a), (M, b)):
                r_i, c_i = _block_index(len(a), row0, nodes)
                rows.append(r_i)
                cols.append(c_i)
                vals.append(block.ravel())
            row0 += 3 * len(a)
        if row0 == 0:
            return sp.csr_matrix((0, 3 * n)), np.zeros(0)
        J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(row0, 3 * n))
        return J, np.concatenate(residuals)


def _block_index(m: int, row0: int, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column indices of m 3 × 3 blocks, block k at rows row0 + 3k… and columns 3·nodes[k]…, row-major."""
    k = np.arange(m)
    i, j = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    rows = (row0 + 3 * k)[:, None, None] + i[None]
    cols = (3 * np.asarray(nodes))[:, None, None] + j[None]
    return rows.ravel(), cols.ravel()
