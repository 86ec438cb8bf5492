"""The by-fault statistics (``scftc_cli/statistics.py``): tiny matrices worked by hand, brute-force
enumeration of every resample, sign pattern and split, scipy's Monte-Carlo versions of the same
procedures, and synthetic cells whose clustering is known by construction."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from scftc_cli.scoring import wilson_interval
from scftc_cli.statistics import (
    PROFILE_TAUS_DEG,
    bootstrap_distribution,
    bootstrap_interval,
    design_effect,
    interval_by_fault,
    paired_by_fault,
    per_fault_counts,
    performance_profile,
    pooled_profile,
    profile_by_fault,
    profile_counts,
    profile_intervals,
    settled_at,
    two_sample_by_fault,
    with_thresholds,
)


# ------------------------------------------------------------------------------- the bootstrap
def test_bootstrap_distribution_of_three_faults_by_hand():
    # one fault's count is 0, 1 or 2 with probability 1/3 each; three draws sum to 0..6 in
    # 1, 3, 6, 7, 6, 3, 1 of the 27 equally likely resamples
    pmf = bootstrap_distribution([0, 1, 2], 2)
    np.testing.assert_allclose(pmf, np.array([1, 3, 6, 7, 6, 3, 1]) / 27, atol=1e-15)
    # 80 %: P(T <= 0) = 1/27 < 0.1 <= P(T <= 1) = 4/27; P(T <= 4) = 23/27 < 0.9 <= P(T <= 5)
    assert bootstrap_interval([0, 1, 2], 2, confidence=0.8) == (1 / 6, 5 / 6)


def test_bootstrap_distribution_is_every_resample_enumerated():
    counts, seeds = np.array([0, 3, 3, 1, 0]), 3
    m = counts.size
    totals = [counts[list(pick)].sum() for pick in itertools.product(range(m), repeat=m)]
    expected = np.bincount(totals, minlength=seeds * m + 1) / m**m
    np.testing.assert_allclose(bootstrap_distribution(counts, seeds), expected, atol=1e-14)


def test_strata_are_resampled_separately():
    # stratum 1: faults 0 and 2 of 2 -> 0, 2 or 4 (1/4, 1/2, 1/4); stratum 2 always passes 2
    stratified = bootstrap_distribution([[0, 2], [1, 1]], 2)
    np.testing.assert_allclose(stratified, [0, 0, 0.25, 0, 0.5, 0, 0.25, 0, 0], atol=1e-15)
    assert bootstrap_interval([[0, 2], [1, 1]], 2) == (2 / 8, 6 / 8)
    # ragged strata (lists of arrays) give the same as a 2-D array
    np.testing.assert_allclose(bootstrap_distribution([np.array([0, 2]), np.array([1, 1])], 2), stratified)
    # a hard class and an easy one: stratified, every resample keeps one of each (a point at 4 of
    # 8); pooled without strata, a resample may draw the hard class twice (0) or the easy one (8)
    np.testing.assert_allclose(bootstrap_distribution([[0, 0], [2, 2]], 2), np.eye(9)[4], atol=1e-15)
    pooled = bootstrap_distribution([0, 0, 2, 2], 2)
    assert pooled[0] == pytest.approx(1 / 16) and pooled[8] == pytest.approx(1 / 16)


def test_the_exact_bootstrap_is_the_limit_of_scipys():
    """``scipy.stats.bootstrap`` (percentile, one sample per class: stratified) lands within a step
    of the exact bounds at 10 000 resamples; the exact ones have no Monte-Carlo error at all."""
    from scipy.stats import bootstrap

    rng = np.random.default_rng(7)
    seeds = 10
    strata = [
        np.where(rng.random(50) < q, rng.binomial(seeds, 0.9, 50), rng.binomial(seeds, 0.05, 50))
        for q in (0.2, 0.6)
    ]
    n = seeds * 100
    low, high = bootstrap_interval(strata, seeds)

    def rate(a: np.ndarray, b: np.ndarray, axis: int) -> np.ndarray:
        return (a.sum(axis=axis) + b.sum(axis=axis)) / n

    lows, highs = [], []
    for seed in range(5):
        ci = bootstrap(
            tuple(strata),
            rate,
            method="percentile",
            n_resamples=10_000,
            vectorized=True,
            rng=np.random.default_rng(seed),
        ).confidence_interval
        lows.append(ci.low)
        highs.append(ci.high)
    assert np.all(np.abs(np.array(lows) - low) <= 2 / n) and np.all(np.abs(np.array(highs) - high) <= 2 / n)
    # the Monte-Carlo bounds themselves move from seed to seed at this resample count
    assert len(set(lows) | set(highs)) > 2


# --------------------------------------------------------------------- the by-fault interval
def test_interval_at_zero_and_all_is_wilson_over_the_faults():
    assert interval_by_fault(np.zeros(50, dtype=int), 10) == wilson_interval(0, 50)
    assert interval_by_fault(np.full(50, 10), 10) == wilson_interval(50, 50)
    assert interval_by_fault(np.zeros(50, dtype=int), 10)[1] > wilson_interval(0, 500)[1]
    assert bootstrap_interval(np.zeros(50, dtype=int), 10) == (0.0, 0.0)
    assert design_effect(np.zeros(50, dtype=int), 10) is None and design_effect(np.full(50, 10), 10) is None


def test_faults_all_alike_give_wilson_not_a_point():
    counts = np.full(50, 4)  # every fault passes 4 of 10: the bootstrap sees no spread at all
    assert bootstrap_interval(counts, 10) == (0.4, 0.4)
    assert interval_by_fault(counts, 10) == wilson_interval(200, 500)
    assert design_effect(counts, 10) == pytest.approx(0.0, abs=1e-12)


def test_design_effect_by_hand():
    # r = (0, 1): var 1/4 over 2 faults = 1/8, binomial 1/4 / 4 = 1/16
    assert design_effect([0, 2], 2) == pytest.approx(2.0)
    # r = (0, 1/2, 1): var 1/6 over 3 faults = 1/18, binomial 1/4 / 6 = 1/24
    assert design_effect([0, 1, 2], 2) == pytest.approx(4 / 3)
    # stratified: stratum 2 holds no spread, stratum 1 weighs a half: (1/2)^2 (1/4) / 2 = 1/32 over 1/32
    assert design_effect([[0, 2], [1, 1]], 2) == pytest.approx(1.0)


def test_all_or_nothing_faults_have_design_effect_seeds_and_a_wide_interval():
    rng = np.random.default_rng(3)
    seeds = 10
    counts = np.where(rng.random(50) < 0.4, seeds, 0)
    k = int(counts.sum())
    assert design_effect(counts, seeds) == pytest.approx(seeds)
    low, high = interval_by_fault(counts, seeds)
    w_low, w_high = wilson_interval(k, 500)
    assert (high - low) > 2.5 * (w_high - w_low)  # sqrt(10) in the limit
    # it is about the interval of k / seeds faults out of 50
    f_low, f_high = wilson_interval(k // seeds, 50)
    assert abs((high - low) - (f_high - f_low)) < 0.05


def test_outcomes_independent_of_the_fault_give_wilson_and_design_effect_one():
    """Every fault settles each episode with the same probability: nothing clusters."""
    rng = np.random.default_rng(11)
    seeds, ratios, effects = 10, [], []
    for _ in range(200):
        counts = rng.binomial(seeds, 0.3, 50)
        k = int(counts.sum())
        low, high = interval_by_fault(counts, seeds)
        w_low, w_high = wilson_interval(k, 500)
        ratios.append((high - low) / (w_high - w_low))
        effects.append(design_effect(counts, seeds))
    assert 0.9 < np.mean(effects) < 1.1
    assert 1.0 <= np.mean(ratios) < 1.1 and min(ratios) >= 1.0  # never below Wilson


def test_by_fault_interval_covers_where_wilson_does_not():
    """Simulated clustered cells (per-fault probabilities from a beta with intra-fault correlation
    0.5, mean 30 %): the by-fault interval holds its coverage, Wilson's does not."""
    rng = np.random.default_rng(5)
    mean, rho, seeds, faults = 0.3, 0.5, 10, 50
    a = mean * (1 / rho - 1)
    b = (1 - mean) * (1 / rho - 1)
    hits_fault = hits_wilson = 0
    reps = 400
    for _ in range(reps):
        counts = rng.binomial(seeds, rng.beta(a, b, faults))
        low, high = interval_by_fault(counts, seeds)
        hits_fault += low <= mean <= high
        w_low, w_high = wilson_interval(int(counts.sum()), seeds * faults)
        hits_wilson += w_low <= mean <= w_high
    assert hits_fault / reps > 0.9 and hits_wilson / reps < 0.75


def test_counts_are_checked():
    with pytest.raises(ValueError, match="more than"):
        interval_by_fault([0, 11], 10)
    with pytest.raises(ValueError, match=">= 0"):
        design_effect([-1, 2], 10)
    with pytest.raises(ValueError, match="at least one fault"):
        interval_by_fault([[1, 2], []], 10)


# ------------------------------------------------------------------------ per-fault counts
def test_per_fault_counts_group_fault_major_episodes():
    passed = np.array([1, 1, 0, 0, 0, 0, 1, 0, 1], dtype=bool)
    fault_index = np.repeat([0, 1, 2], 3)
    counts, seeds = per_fault_counts(passed, fault_index)
    assert counts.tolist() == [2, 0, 2] and seeds == 3
    shuffled = np.random.default_rng(0).permutation(9)
    again, _ = per_fault_counts(passed[shuffled], fault_index[shuffled])
    assert again.tolist() == [2, 0, 2]
    with pytest.raises(ValueError, match="unequal"):
        per_fault_counts(passed[:-1], fault_index[:-1])


# ------------------------------------------------------------------------- the paired test
def _brute_sign_flip(a: np.ndarray, b: np.ndarray) -> float:
    d = (a - b)[a != b]
    observed = abs(d.sum())
    patterns = np.array(list(itertools.product((-1, 1), repeat=d.size)))
    return float(np.mean(np.abs(patterns @ np.abs(d)) >= observed))


def test_sign_flip_by_hand():
    # one fault differs by 3: the two patterns give +-3, both as extreme
    assert paired_by_fault([3, 1], [0, 1], 3) == 1.0
    # three faults all favour A by 1: only +3 and -3 of 8 patterns reach |3|
    assert paired_by_fault([1, 1, 1], [0, 0, 0], 1) == pytest.approx(2 / 8)
    # A and B alike on every fault
    assert paired_by_fault([2, 0, 5], [2, 0, 5], 5) == 1.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sign_flip_is_every_sign_pattern_enumerated(seed: int):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 11, 14)
    b = np.where(rng.random(14) < 0.3, a, rng.integers(0, 11, 14))  # some faults alike
    assert paired_by_fault(a, b, 10) == pytest.approx(_brute_sign_flip(a, b), abs=1e-12)


def test_sign_flip_matches_scipy_exact_and_monte_carlo():
    from scipy.stats import permutation_test

    def stat(x: np.ndarray, axis: int) -> np.ndarray:
        return np.sum(x, axis=axis)

    rng = np.random.default_rng(4)
    a, b = rng.integers(0, 11, 10), rng.integers(0, 11, 10)
    d = (a - b)[a != b]
    exact = permutation_test((d,), stat, permutation_type="samples", vectorized=True, n_resamples=2**d.size)
    assert paired_by_fault(a, b, 10) == pytest.approx(exact.pvalue, abs=1e-12)
    # 40 differing faults: 2**40 patterns, scipy samples; ours is exact for any number of faults
    a = rng.integers(0, 11, 50)
    b = np.clip(a - rng.integers(-2, 4, 50), 0, 10)
    d = (a - b)[a != b]
    assert d.size > 30
    draws = 200_000
    mc = permutation_test(
        (d,),
        stat,
        permutation_type="samples",
        vectorized=True,
        n_resamples=draws,
        rng=np.random.default_rng(0),
    ).pvalue
    p = paired_by_fault(a, b, 10)
    assert 1e-4 < p < 0.9  # a case where the Monte-Carlo error means something
    assert abs(mc - p) < 4 * math.sqrt(p * (1 - p) / draws) + 1 / draws


def test_few_differing_faults_cannot_be_significant():
    """The episode-level McNemar test sees 50 discordant episodes here; the faults are 5."""
    a = np.array([10] * 5 + [3] * 45)
    b = np.array([0] * 5 + [3] * 45)
    assert paired_by_fault(a, b, 10) == pytest.approx(2 / 2**5)


# --------------------------------------------------------------------- the two-sample test
def _brute_two_sample(a: list[np.ndarray], b: list[np.ndarray]) -> float:
    m_a, m_b = sum(r.size for r in a), sum(r.size for r in b)
    observed = abs(sum(r.sum() for r in a) * m_b - sum(r.sum() for r in b) * m_a)
    per_class = []
    for ra, rb in zip(a, b, strict=True):
        pooled = np.concatenate([ra, rb])
        total = pooled.sum()
        per_class.append(
            [
                (pooled[list(pick)].sum(), total)
                for pick in itertools.combinations(range(pooled.size), ra.size)
            ]
        )
    hits = count = 0
    for combo in itertools.product(*per_class):
        k_a = sum(x for x, _ in combo)
        k_b = sum(t for _, t in combo) - k_a
        hits += abs(k_a * m_b - k_b * m_a) >= observed
        count += 1
    return hits / count


@pytest.mark.parametrize("seed", [0, 1])
def test_two_sample_is_every_split_enumerated(seed: int):
    rng = np.random.default_rng(seed)
    a = [rng.integers(0, 4, 4), rng.integers(0, 4, 3)]
    b = [rng.integers(0, 4, 3), rng.integers(2, 4, 4)]
    assert two_sample_by_fault(a, b, 3) == pytest.approx(_brute_two_sample(a, b), abs=1e-12)


def test_two_sample_by_hand_and_symmetric():
    # one class, faults (2) vs (0): the two splits give |2 - 0| either way
    assert two_sample_by_fault([2], [0], 2) == 1.0
    # (2, 2) vs (0, 0): of C(4, 2) = 6 splits only the observed one and its mirror are as extreme
    assert two_sample_by_fault([2, 2], [0, 0], 2) == pytest.approx(2 / 6)
    rng = np.random.default_rng(9)
    a, b = rng.integers(0, 11, (3, 20)), rng.integers(0, 11, (3, 25))
    assert two_sample_by_fault(a, b, 10) == pytest.approx(two_sample_by_fault(b, a, 10), abs=1e-12)


def test_two_sample_matches_a_monte_carlo_permutation():
    rng = np.random.default_rng(2)
    a = [np.where(rng.random(50) < q, 10, rng.integers(0, 3, 50)) for q in (0.5, 0.8)]
    b = [np.where(rng.random(50) < q, 10, rng.integers(0, 3, 50)) for q in (0.35, 0.7)]
    p = two_sample_by_fault(a, b, 10)
    draws, hits = 20_000, 0
    observed = abs(sum(r.sum() for r in a) - sum(r.sum() for r in b))
    k_a = np.zeros(draws, dtype=np.int64)
    for ra, rb in zip(a, b, strict=True):
        pooled = np.broadcast_to(np.concatenate([ra, rb]), (draws, 100))
        k_a += rng.permuted(pooled, axis=1)[:, :50].sum(axis=1)
    total = sum(r.sum() for r in a + b)
    hits = np.count_nonzero(np.abs(2 * k_a - total) >= observed)
    assert 1e-3 < p < 0.9
    assert abs(hits / draws - p) < 4 * math.sqrt(p * (1 - p) / draws)


def test_two_sample_is_less_sure_than_fisher_when_faults_cluster():
    from scipy.stats import fisher_exact

    a = np.array([10] * 30 + [0] * 20)  # 300 of 500: thirty faults all-or-nothing
    b = np.array([10] * 24 + [0] * 26)  # 240 of 500
    _, fisher = fisher_exact([[300, 200], [240, 260]])
    assert fisher < 0.001 < 0.1 < two_sample_by_fault(a, b, 10)


# ----------------------------------------------------------------- profiles and sensitivity
def test_performance_profile_by_hand():
    errors = np.array([0.05, 0.2, 3.0, 170.0])
    np.testing.assert_array_equal(
        performance_profile(errors, np.array([0.01, 0.2, 5.0, 180.0])), [0, 0.5, 0.75, 1]
    )
    assert PROFILE_TAUS_DEG.size == 40 and PROFILE_TAUS_DEG[0] == pytest.approx(0.01)
    assert PROFILE_TAUS_DEG[-1] == pytest.approx(180.0)
    assert np.all(np.diff(performance_profile(np.random.default_rng(0).exponential(1, 100))) >= 0)


def test_pooled_profile_from_stored_counts_is_the_profile_of_the_cells():
    rng = np.random.default_rng(1)
    cells = [rng.lognormal(0, 2, 500) for _ in range(3)]
    counts = np.stack([profile_counts(c) for c in cells])
    np.testing.assert_allclose(pooled_profile(counts, np.full(3, 500)), performance_profile(cells))
    np.testing.assert_allclose(performance_profile(cells), performance_profile(np.concatenate(cells)))


def test_with_thresholds_puts_each_gate_on_the_grid_exactly():
    taus = with_thresholds(PROFILE_TAUS_DEG, (0.2, 5.0))
    assert taus.size == 42 and np.all(np.diff(taus) > 0)
    assert 0.2 in taus and 5.0 in taus and set(PROFILE_TAUS_DEG) <= set(taus)
    assert with_thresholds(PROFILE_TAUS_DEG, (PROFILE_TAUS_DEG[3],)).size == 40  # no repeats


def test_profile_by_fault_splits_the_profile_and_its_band_contains_it():
    rng = np.random.default_rng(2)
    seeds, n_faults = 10, 50
    scale = np.repeat(rng.lognormal(-1, 1.5, n_faults), seeds)  # faults alike within, unlike across
    worst = scale * rng.lognormal(0, 0.3, seeds * n_faults)
    fault_index = np.repeat(np.arange(n_faults), seeds)
    taus = with_thresholds(PROFILE_TAUS_DEG, (0.2, 5.0))
    counts, got_seeds = profile_by_fault(worst, fault_index, taus)
    k = profile_counts(worst, taus)
    assert counts.shape == (taus.size, n_faults) and got_seeds == seeds
    np.testing.assert_array_equal(counts.sum(axis=1), k)
    assert np.all(np.diff(counts, axis=0) >= 0) and np.all(np.diff(k) >= 0)  # monotone, per fault too
    # each threshold's count of the settled gate at that tolerance: settled_at, fault by fault
    i = int(np.flatnonzero(taus == 0.2)[0])
    assert k[i] == settled_at(worst, (0.2,))[0]
    np.testing.assert_array_equal(counts[i], per_fault_counts(worst <= 0.2, fault_index)[0])
    bands = profile_intervals(counts, seeds)
    rate = k / worst.size
    assert np.all(bands[:, 0] <= rate) and np.all(rate <= bands[:, 1])
    for j in (0, i, taus.size // 2, taus.size - 1):
        assert tuple(bands[j]) == interval_by_fault(counts[j], seeds)
    # several classes pooled: (t, n_strata, n_faults), one stratified interval a threshold
    pooled = profile_intervals(np.stack([counts, counts[:, ::-1]], axis=1), seeds)
    assert tuple(pooled[i]) == interval_by_fault([counts[i], counts[i][::-1]], seeds)


def test_settled_at_is_the_settled_gate_at_each_threshold():
    worst = np.array([0.05, 0.1, 0.15, 0.2, 0.2000001, 0.7, 3.0])
    assert settled_at(worst).tolist() == [2, 4, 5, 6]


@pytest.mark.parametrize(
    "p_values",
    [[0.01, 0.04, 0.03, 0.2], [0.5], [0.001, 0.001, 0.9, 0.04, 1.0], [0.02, 0.02], []],
)
def test_holm_matches_statsmodels(p_values: list[float]):
    from statsmodels.stats.multitest import multipletests

    from scftc_cli.statistics import holm

    expected = [float(x) for x in multipletests(p_values, method="holm")[1]] if p_values else []
    assert holm(p_values) == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize(("a_only", "b_only"), [(0, 0), (8, 1), (1, 8), (11, 0), (42, 42), (188, 11), (3, 4)])
def test_the_exact_mcnemar_matches_statsmodels(a_only: int, b_only: int):
    from statsmodels.stats.contingency_tables import mcnemar

    from scftc_cli.study.compare import mcnemar_exact

    expected = float(mcnemar(np.array([[0, a_only], [b_only, 0]]), exact=True).pvalue)
    assert mcnemar_exact(a_only, b_only) == pytest.approx(expected, rel=1e-12)
