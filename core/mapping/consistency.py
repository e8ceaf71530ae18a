"""POCD consistency update by moment matching (docs/method.md, eqs. 1–4).

The belief of an object is q(l, v) = N(l | mu, sigma²) · Beta(v | alpha, beta) (eq. 1): l its
geometric change, v its consistency. A measurement z = (Delta, s) has the likelihood

    [v N(Delta | l, tau²) + (1 − v) U(Delta | −Delta_max, Delta_max)] · v^(k s) (1 − v)^(k (1 − s))

(eqs. 2–3). `update` projects the exact posterior back onto the Gaussian × Beta family by matching
E[l], Var[l], E[v] and E[v²] (eq. 4). Pure functions on `Posterior`.

Pitfalls measured and handled here:
- A Delta beyond ±Delta_max has U(Delta) = 0 and the normalisation would turn it into a pure inlier;
  `forced_outlier` is therefore the outlier branch alone (C1 = 0, C2 = 1): alpha' = alpha + k s,
  beta' = beta + k (1 − s) + 1, mu and sigma unchanged. Our evidence-weighted variant adds `weight`
  instead of 1 to beta (weight 1 is exactly the paper's forced outlier).
- A Delta beyond ±Delta_max given to `update` is clipped to the support's edge (it is then the most
  outlying measurement the model can express), never silently made an inlier.
- Underflow. Under the cap, every inlier shrinks beta by about cap / (cap + 1): after a few thousand
  frames of a box in plain view beta is 1e-300 and then 0, and the log-Beta differences of the textbook
  eta1 and eta2 became inf − inf; the NaN was read as a pure outlier, and a still box lost consistency
  (docs/decisions.md, "Branch weights without Beta functions"). The normalisation only needs the ratio
  eta1 / eta2, which is exactly (alpha + k s) / (beta + k (1 − s)) (B(x + 1, y) / B(x, y + 1) = x / y): no
  Beta functions, no cancellation. alpha and beta are floored at `EVIDENCE_FLOOR` pseudo-counts, so that E[v] and Var[v]
  stay defined; a millionth of an observation changes no decision (one forced outlier adds ≥ 1e-2).
"""

from __future__ import annotations

import math

from core.types import Posterior

EVIDENCE_FLOOR = 1e-6
"""alpha and beta never fall below this many pseudo-observations (no underflow to 0, see above)."""


def normal_pdf(x: float, mean: float, var: float) -> float:
    """N(x | mean, var)."""
    return math.exp(-0.5 * (x - mean) ** 2 / var) / math.sqrt(2.0 * math.pi * var)


def uniform_pdf(x: float, delta_max: float) -> float:
    """U(x | −Delta_max, Delta_max)."""
    return 1.0 / (2.0 * delta_max) if abs(x) <= delta_max else 0.0


def branch_weights(post: Posterior, delta: float, s: float, k: float, tau: float,
                   delta_max: float) -> tuple[float, float]:
    """(C1, C2): normalised weights of the inlier and outlier branches (step 2).

    eta1 / eta2 = B(a + 1, b) / B(a, b + 1) = a / b with a = alpha + k s, b = beta + k (1 − s): the common
    factor B(alpha, beta) and the Beta functions cancel in the normalisation (module docstring)."""
    eta1 = post.alpha + k * s
    eta2 = post.beta + k * (1.0 - s)
    c1 = eta1 * normal_pdf(delta, post.mu, post.sigma**2 + tau**2)
    c2 = eta2 * uniform_pdf(delta, delta_max)
    total = c1 + c2
    if total <= 0.0 or not math.isfinite(total):
        return 0.0, 1.0
    return c1 / total, c2 / total


def match_beta(alpha: float, beta: float, c1: float, c2: float, s: float, k: float) -> tuple[float, float]:
    """alpha', beta' of the Beta matching E[v] (theta) and E[v²] (S) of the mixture (step 4).

    Algebraically the textbook alpha' = (theta S − theta²)/(theta² − S), beta' = alpha'(1 − theta)/theta,
    evaluated through the branch means and variances so that it stays exact when Var[v] = S − theta²
    is tiny (a long run of inliers under the cap drives beta towards 0).
    """
    a = alpha + k * s
    b = beta + k * (1.0 - s)
    d1 = alpha + beta + k + 1.0
    m1, m2 = (a + 1.0) / d1, a / d1  # E[v] of Beta(a + 1, b) and of Beta(a, b + 1)
    n1, n2 = b / d1, (b + 1.0) / d1  # 1 − m1, 1 − m2 without cancellation
    theta = c1 * m1 + c2 * m2
    one_minus_theta = c1 * n1 + c2 * n2
    var = (c1 * m1 * n1 + c2 * m2 * n2) / (d1 + 1.0) + c1 * c2 * (m1 - m2) ** 2
    total = theta * one_minus_theta / var - 1.0
    return theta * total, one_minus_theta * total


def update(post: Posterior, delta: float, s: float = 0.0, k: float = 0.0, tau: float = 0.2,
           delta_max: float = 4.0) -> Posterior:
    """One POCD measurement update of q(l, v) by Delta (m) and semantic label s with weight k."""
    delta = min(max(delta, -delta_max), delta_max)
    c1, c2 = branch_weights(post, delta, s, k, tau, delta_max)
    var0 = post.sigma**2
    g2 = 1.0 / (1.0 / var0 + 1.0 / tau**2)
    m = g2 * (post.mu / var0 + delta / tau**2)
    mu = c1 * m + c2 * post.mu
    var = c1 * (m**2 + g2) + c2 * (post.mu**2 + var0) - mu**2
    alpha, beta = match_beta(post.alpha, post.beta, c1, c2, s, k)
    return Posterior(mu=mu, sigma=math.sqrt(max(var, 1e-12)), alpha=max(alpha, EVIDENCE_FLOOR),
                     beta=max(beta, EVIDENCE_FLOOR))


def forced_outlier(post: Posterior, s: float = 0.0, k: float = 0.0, weight: float = 1.0) -> Posterior:
    """An object that should have been seen but was not: the outlier branch alone (C1 = 0, C2 = 1).

    alpha' = alpha + k s, beta' = beta + k (1 − s) + weight; mu and sigma unchanged. weight = 1 is POCD's.
    """
    return Posterior(mu=post.mu, sigma=post.sigma, alpha=post.alpha + k * s, beta=post.beta + k * (1.0 - s) + weight)


def cap(post: Posterior, limit: float) -> Posterior:
    """Rescale alpha and beta (ratio, hence E[v], kept) so that neither exceeds `limit`."""
    largest = max(post.alpha, post.beta)
    if largest <= limit:
        return post
    f = limit / largest
    return Posterior(mu=post.mu, sigma=post.sigma, alpha=post.alpha * f, beta=post.beta * f)
