"""POCD consistency update (docs/method.md, eqs. 1–4): hand-computed cases, the forced outlier, a Delta
beyond ±Delta_max, the exact posterior's moments by numerical integration, and the removal
latencies measured with the paper's cap (docs/decisions.md, "Removal speed")."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.special import betaln
from scipy.stats import beta as beta_dist

from core.mapping.consistency import branch_weights, cap, forced_outlier, update
from core.params import MappingParams
from core.types import Posterior

PRIOR = MappingParams().prior()


def _method_md_alpha_beta(theta: float, S: float) -> tuple[float, float]:
    """The moment match of eq. (4) written literally, Beta functions and all (docs/method.md)."""
    a = (theta * S - theta**2) / (theta**2 - S)
    return a, a * (1 - theta) / theta


def test_inlier_by_hand():
    # Delta = 5 cm, prior (mu 0, sigma 0.5, alpha 2, beta 1), tau 0.2, Delta_max 4, k = 0.
    # g2 = 1/(1/0.25 + 1/0.04) = 1/29, m = g2 · 0.05/0.04 = 1.25/29
    # eta1 = B(3,1)/B(2,1) = 2/3, eta2 = B(2,2)/B(2,1) = 1/3
    # N(0.05 | 0, 0.29) = exp(-0.5·0.0025/0.29)/sqrt(2π·0.29) = 0.737631, U = 1/8
    n = math.exp(-0.5 * 0.0025 / 0.29) / math.sqrt(2 * math.pi * 0.29)
    assert n == pytest.approx(0.737631, abs=1e-6)
    c1 = (2 / 3) * n / ((2 / 3) * n + (1 / 3) / 8)
    assert c1 == pytest.approx(0.921888, abs=1e-6)
    c2 = 1 - c1
    g2, m = 1 / 29, 1.25 / 29
    theta = c1 * 3 / 4 + c2 * 2 / 4
    S = c1 * 12 / 20 + c2 * 6 / 20
    alpha, beta = _method_md_alpha_beta(theta, S)
    assert (alpha, beta) == pytest.approx((2.6158, 0.9652), abs=1e-3)

    post = update(PRIOR, 0.05, s=0.0, k=0.0, tau=0.2, delta_max=4.0)
    assert branch_weights(PRIOR, 0.05, 0.0, 0.0, 0.2, 4.0) == pytest.approx((c1, c2), abs=1e-12)
    assert post.mu == pytest.approx(c1 * m, abs=1e-12)
    assert post.sigma**2 == pytest.approx(c1 * (m**2 + g2) + c2 * 0.25 - (c1 * m) ** 2, abs=1e-12)
    assert (post.alpha, post.beta) == pytest.approx((alpha, beta), rel=1e-9)
    assert post.consistency == pytest.approx(theta, rel=1e-12)
    assert post.consistency > PRIOR.consistency  # an inlier raises E[v]


def test_outlier_by_hand():
    # Delta = 1.5 m: N(1.5 | 0, 0.29) = 0.015309, so the uniform branch dominates.
    n = math.exp(-0.5 * 2.25 / 0.29) / math.sqrt(2 * math.pi * 0.29)
    c1 = (2 / 3) * n / ((2 / 3) * n + (1 / 3) / 8)
    assert c1 == pytest.approx(0.196751, abs=1e-6)
    c2 = 1 - c1
    theta = c1 * 3 / 4 + c2 * 2 / 4
    S = c1 * 12 / 20 + c2 * 6 / 20
    alpha, beta = _method_md_alpha_beta(theta, S)
    post = update(PRIOR, 1.5)
    assert (post.alpha, post.beta) == pytest.approx((alpha, beta), rel=1e-9)
    assert post.consistency == pytest.approx(theta, rel=1e-12)
    assert post.consistency < PRIOR.consistency
    m = (1 / 29) * 1.5 / 0.04
    assert post.mu == pytest.approx(c1 * m, abs=1e-12)


def test_forced_outlier_is_the_outlier_branch_alone():
    post = forced_outlier(PRIOR)
    assert (post.mu, post.sigma, post.alpha, post.beta) == (0.0, 0.5, 2.0, 2.0)
    # with the semantic term: alpha' = alpha + k s, beta' = beta + k(1 − s) + 1
    post = forced_outlier(PRIOR, s=0.0, k=2.0)
    assert (post.alpha, post.beta) == (2.0, 4.0)
    post = forced_outlier(PRIOR, s=1.0, k=2.0)
    assert (post.alpha, post.beta) == (4.0, 2.0)
    # evidence weight w adds w to beta (w = 1 is POCD's)
    assert forced_outlier(PRIOR, weight=2.5).beta == 3.5


def test_delta_beyond_delta_max_is_an_outlier_not_an_inlier():
    # Naively U(10) = 0, so C2 = 0 and the normalisation makes it a pure inlier (alpha grows, mu jumps).
    n = math.exp(-0.5 * 100 / 0.29) / math.sqrt(2 * math.pi * 0.29)
    assert (2 / 3) * n > 0 and (1 / 3) * 0.0 == 0.0  # the naive C1 / (C1 + C2) would be 1
    for delta in (10.0, -10.0, 4.0 + 1e-9):
        post = update(PRIOR, delta)
        assert post.consistency == pytest.approx(forced_outlier(PRIOR).consistency, abs=1e-6)
        assert post.mu == pytest.approx(PRIOR.mu, abs=1e-6)
        assert post.sigma == pytest.approx(PRIOR.sigma, abs=1e-6)


def _exact_moments(post: Posterior, delta: float, s: float, k: float, tau: float, delta_max: float):
    """E[l], Var[l], E[v], E[v²] of the exact posterior by numerical integration.

    The exact density is p(l, v) ∝ N(l | mu, sigma²) Beta(v | alpha, beta) v^(ks) (1 − v)^(k(1 − s))
    [v N(Delta | l, tau²) + (1 − v) U(Delta)]; each marginal is integrated numerically (l on a fine
    grid, v by adaptive quadrature, which copes with the Beta density's endpoints).
    """
    unif = 1 / (2 * delta_max) if abs(delta) <= delta_max else 0.0
    sd = post.sigma
    l = np.linspace(post.mu - 12 * sd, post.mu + 12 * sd, 20001)
    prior_l = np.exp(-0.5 * ((l - post.mu) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))
    lik_l = np.exp(-0.5 * ((delta - l) / tau) ** 2) / math.sqrt(2 * math.pi * tau**2)

    def prior_v(v: float) -> float:
        log = ((post.alpha + k * s - 1) * math.log(v) + (post.beta + k * (1 - s) - 1) * math.log1p(-v)
               - betaln(post.alpha, post.beta))
        return math.exp(log)

    def v_integral(f) -> float:
        return quad(lambda v: prior_v(v) * f(v), 0.0, 1.0, epsabs=1e-13, epsrel=1e-11, limit=200)[0]

    A = np.trapezoid(prior_l * lik_l, l)  # ∫ N(l) N(Delta | l) dl
    B = unif  # ∫ N(l) U dl
    pv = [v_integral(lambda v, n=n: v**n * (v * A + (1 - v) * B)) for n in range(3)]
    w_in, w_out = v_integral(lambda v: v), v_integral(lambda v: 1 - v)
    dens_l = prior_l * (w_in * lik_l + w_out * unif)
    Z = np.trapezoid(dens_l, l)
    El = np.trapezoid(dens_l * l, l) / Z
    Vl = np.trapezoid(dens_l * (l - El) ** 2, l) / Z
    return El, Vl, pv[1] / pv[0], pv[2] / pv[0]


@pytest.mark.parametrize("seed", range(8))
def test_moments_match_numerical_integration(seed):
    rng = np.random.default_rng(seed)
    post = Posterior(mu=rng.uniform(-0.3, 0.3), sigma=rng.uniform(0.05, 0.5), alpha=rng.uniform(1.0, 20.0),
                     beta=rng.uniform(1.0, 20.0))
    delta = rng.uniform(-1.0, 1.0)
    s = float(rng.integers(0, 2))
    k = float(rng.integers(0, 3))
    new = update(post, delta, s=s, k=k, tau=0.2, delta_max=4.0)
    El, Vl, Ev, Ev2 = _exact_moments(post, delta, s, k, 0.2, 4.0)
    assert new.mu == pytest.approx(El, abs=1e-7)
    assert new.sigma**2 == pytest.approx(Vl, rel=1e-6)
    a, b = new.alpha, new.beta
    assert beta_dist.mean(a, b) == pytest.approx(Ev, abs=1e-7)
    assert beta_dist.moment(2, a, b) == pytest.approx(Ev2, abs=1e-7)


def test_cap_keeps_the_ratio():
    post = cap(replace(PRIOR, alpha=50.0, beta=10.0), 25.0)
    assert (post.alpha, post.beta) == pytest.approx((25.0, 5.0))
    assert cap(replace(PRIOR, alpha=5.0, beta=1.0), 25.0) == replace(PRIOR, alpha=5.0, beta=1.0)


def _forced_outliers_to_removal(seen: int, limit: float, weight: float) -> int:
    post, updates = PRIOR, 0
    for _ in range(seen):
        post, updates = cap(update(post, 0.0), limit), updates + 1
    n = 0
    while not (post.consistency < 0.4 and updates > 2):
        post, updates, n = cap(forced_outlier(post, weight=weight), limit), updates + 1, n + 1
    return n


def test_removal_latency_with_the_papers_cap_matches_method_md():
    # docs/decisions.md, "Removal speed": with k = 0 and the cap 25, seen once → 3 forced outliers,
    # 3 times → 6, 30 times → 35.
    assert [_forced_outliers_to_removal(n, 25.0, 1.0) for n in (1, 3, 30)] == [3, 6, 35]


def test_our_cap_and_weight_remove_a_long_seen_box_within_five_clear_frames():
    # MappingParams: cap 10, w_max 3 (full clear view): saturation costs at most 5 frames.
    assert max(_forced_outliers_to_removal(n, 10.0, 3.0) for n in (1, 3, 30, 100, 600)) == 5


@pytest.mark.parametrize(("alpha", "beta", "s", "k"),
                         [(2.0, 1.0, 0.0, 0.0), (7.5, 0.3, 1.0, 2.0), (0.4, 9.0, 0.0, 3.0)])
def test_branch_weights_equal_method_md_eta_by_log_beta(alpha, beta, s, k):
    post = Posterior(mu=0.02, sigma=0.3, alpha=alpha, beta=beta)
    log_b0 = betaln(alpha, beta)
    eta1 = math.exp(betaln(alpha + k * s + 1, beta + k * (1 - s)) - log_b0)
    eta2 = math.exp(betaln(alpha + k * s, beta + k * (1 - s) + 1) - log_b0)
    for delta in (0.0, 0.3, 1.5):
        c1 = eta1 * math.exp(-0.5 * (delta - 0.02) ** 2 / 0.13) / math.sqrt(2 * math.pi * 0.13)
        c2 = eta2 / 8.0
        assert branch_weights(post, delta, s, k, 0.2, 4.0) == pytest.approx((c1 / (c1 + c2), c2 / (c1 + c2)), rel=1e-12)


def test_twenty_thousand_inliers_under_the_cap_never_underflow():
    # 400 s of a still box at 50 updates/s: beta shrinks by ~10/11 an update and reached 0 (then NaN, read as a
    # pure outlier: E[v] fell to 0.91). It must stay a finite belief with E[v] ≥ 0.99 after the first updates.
    rng = np.random.default_rng(0)
    post, lowest = PRIOR, 1.0
    for i in range(20_000):
        post = cap(update(post, float(rng.normal(0.0, 0.02))), 10.0)
        assert math.isfinite(post.alpha) and math.isfinite(post.beta) and post.beta > 0.0
        if i >= 50:
            lowest = min(lowest, post.consistency)
    assert lowest >= 0.99
    # and the box still goes when its place is seen through: the floor keeps the forced outliers effective
    n = 0
    while post.consistency >= 0.4:
        post, n = cap(forced_outlier(post, weight=3.0), 10.0), n + 1
    assert n <= 5
