"""Statistics whose unit is the fault: pure functions over per-fault counts.

A cell's ``n = n_faults x seeds`` episodes are ``n_faults`` faults, each flown from ``seeds``
initial conditions (fault-major: episode ``e`` is fault ``e // seeds``). Whether an episode
settles depends mostly on its fault, so the ``seeds`` episodes of one fault are not independent
trials: the Wilson interval and the exact McNemar and Fisher tests, which treat the ``n`` episodes
as independent, are too narrow and too confident. Everything here resamples, permutes or flips
whole faults instead; the faults of a cell are independent draws from the class's fault
distribution, so they are the units the benchmark samples.

The inputs are per-fault counts (``counts: (n_faults,) int``, the episodes of each fault that
pass a gate, each in ``0..seeds``) or, for several classes pooled, one row per class
(``(n_strata, n_faults) int``, or a list of ``(n_faults_s,) int`` arrays); the outputs are
rates as fractions in ``[0, 1]`` and p-values.

Every function here is exact: no Monte-Carlo resampling, no seed, no resampling error. The
quantities are sums of small integers (a fault passes ``0..seeds`` episodes), so the bootstrap
and permutation distributions they need are convolutions over an integer support that numpy
computes exactly (to float rounding) in well under a millisecond per cell:

- the cluster bootstrap distribution of a cell's passing count is the ``n_faults``-fold
  convolution of the empirical distribution of one fault's count, convolved over the strata when
  classes are pooled: the bootstrap with infinitely many resamples (``bootstrap_distribution``);
- the sign-flip null distribution of a paired difference is the convolution of the per-fault
  ``+-d_i`` (``paired_by_fault``);
- the stratified two-sample permutation distribution is, per class, the distribution of the sum
  of a random subset of the pooled faults (a subset-sum recursion), convolved over the classes
  (``two_sample_by_fault``).

Libraries, and why: numpy alone, because the exact answers are cheaper than resampling and keep
``scipy.stats`` (about 0.7 s to import) off ``scftc eval``'s start-up. scipy is the reference
the tests check against: ``scipy.stats.bootstrap`` with one sample per class (resampled
independently, i.e. stratified; percentile method) converges to ``bootstrap_interval``, and
``scipy.stats.permutation_test(permutation_type="samples")``, the sign-flip test, gives the same
p-values as ``paired_by_fault`` (exactly where it enumerates, within its Monte-Carlo error where
it samples). At 10 000 resamples ``scipy.stats.bootstrap`` moves the bounds of a 500-episode
cell by a whole step of 1/500 from seed to seed; the exact distribution does not move.
rliable (Agarwal et al. 2021) is the obvious alternative: its stratified bootstrap resamples
runs within each task, the same design with runs for faults and tasks for classes, and its
performance profile is ``performance_profile`` below (with "error <= tau" for "score > tau"). It
would pull jax, arch, seaborn and pandas into the base install for a hundred lines of arithmetic,
and its intervals are Monte Carlo.

Percentile, not BCa, intervals: BCa's acceleration and bias terms are undefined when every
resample gives the same rate (all faults settle, or none) and unstable when nearly every fault
does, which is exactly where this benchmark's best and worst controllers sit.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

Counts = np.ndarray | Sequence[np.ndarray] | Sequence[Sequence[int]]
"""Per-fault counts: ``(n_faults,)`` for one class, ``(n_strata, n_faults)`` or a list of
``(n_faults_s,)`` arrays for several classes pooled (each row one stratum)."""

PROFILE_TAUS_DEG = np.geomspace(0.01, 180.0, 40)
"""``(40,)`` thresholds (deg) on which a performance profile is stored: log-spaced from 0.01 deg
(well under the settled gate) to 180 deg (every error is within it)."""

SENSITIVITY_GATES_DEG = (0.1, 0.2, 0.5, 1.0)
"""Settled-gate thresholds (deg) of the gate-sensitivity table; 0.2 is the benchmark's gate."""


def strata_of(counts: Counts) -> list[np.ndarray]:
    """``counts`` as a list of ``(n_faults_s,)`` int arrays, one per stratum (one for a 1-D input).

    Raises:
        ValueError: a negative count, an empty stratum, or more than two dimensions.
    """
    if isinstance(counts, np.ndarray):
        if counts.ndim not in (1, 2):
            raise ValueError(f"counts must be (n_faults,) or (n_strata, n_faults), got {counts.shape}")
        rows = [counts] if counts.ndim == 1 else list(counts)
    elif len(counts) and np.ndim(counts[0]) == 0:
        rows = [np.asarray(counts)]
    else:
        rows = [np.asarray(row) for row in counts]
    out = [np.asarray(row, dtype=np.int64).ravel() for row in rows]
    if not out or any(row.size == 0 for row in out):
        raise ValueError("every stratum needs at least one fault")
    if any(np.any(row < 0) for row in out):
        raise ValueError("counts must be >= 0")
    return out


def _check_seeds(strata: list[np.ndarray], seeds: int) -> None:
    if seeds < 1:
        raise ValueError(f"seeds must be >= 1, got {seeds}")
    if any(np.any(row > seeds) for row in strata):
        raise ValueError(f"a fault cannot pass more than its {seeds} episodes")


def per_fault_counts(passed: np.ndarray, fault_index: np.ndarray) -> tuple[np.ndarray, int]:
    """``(counts (n_faults,) int, seeds)``: the passing episodes of each fault, faults in
    ascending index order, from per-episode outcomes.

    Args:
        passed: ``(n,)`` bool, one gate's outcome per episode.
        fault_index: ``(n,)`` int, the fault of each episode (any order).

    Raises:
        ValueError: the faults do not all hold the same number of episodes (the statistics here
            assume a full faults x seeds design).
    """
    passed, fault_index = np.asarray(passed, dtype=bool), np.asarray(fault_index)
    if passed.shape != fault_index.shape or passed.ndim != 1:
        raise ValueError(f"passed {passed.shape} and fault_index {fault_index.shape} must be (n,) alike")
    _, which, sizes = np.unique(fault_index, return_inverse=True, return_counts=True)
    if np.any(sizes != sizes[0]):
        raise ValueError(f"faults hold unequal numbers of episodes ({sizes.min()} to {sizes.max()})")
    counts = np.bincount(which, weights=passed, minlength=sizes.size).astype(np.int64)
    return counts, int(sizes[0])


def bootstrap_distribution(counts: Counts, seeds: int) -> np.ndarray:
    """``(seeds * n_faults + 1,)`` float: the exact distribution of the pooled passing count under
    the by-fault bootstrap (each stratum's faults resampled with replacement, independently of the
    other strata); entry ``t`` is the probability that a resample passes ``t`` episodes in all.

    The count of a resample is a sum of ``n_faults_s`` independent draws from each stratum's
    empirical distribution of per-fault counts (values ``0..seeds``), so its distribution is their
    convolution: the bootstrap with infinitely many resamples.
    """
    strata = strata_of(counts)
    _check_seeds(strata, seeds)
    total = np.ones(1)
    for row in strata:
        one = np.bincount(row, minlength=seeds + 1) / row.size  # (seeds + 1,) one fault's count
        power, base, m = np.ones(1), one, row.size  # one ** m by repeated squaring
        while m:
            if m & 1:
                power = np.convolve(power, base)
            m >>= 1
            if m:
                base = np.convolve(base, base)
        total = np.convolve(total, power)
    return np.clip(total, 0.0, None)


def _quantile(pmf: np.ndarray, q: float) -> int:
    """The smallest ``t`` with ``P(T <= t) >= q`` (the inverse CDF), with a 1e-12 allowance for the
    rounding of the convolutions."""
    return int(np.argmax(np.cumsum(pmf) >= q - 1e-12))


def bootstrap_interval(counts: Counts, seeds: int, *, confidence: float = 0.95) -> tuple[float, float]:
    """``(low, high)``: the percentile interval of the exact by-fault bootstrap (whole faults
    resampled with replacement, within each stratum): the ``(1 -/+ confidence) / 2`` quantiles
    (inverse CDF) of the resampled passing rate. A point at ``k = 0`` and ``k = n``.

    Args:
        counts, seeds: as ``interval_by_fault``.
    """
    strata = strata_of(counts)
    _check_seeds(strata, seeds)
    n = seeds * sum(row.size for row in strata)
    pmf = bootstrap_distribution(strata, seeds)
    alpha = 1.0 - confidence
    return _quantile(pmf, alpha / 2) / n, _quantile(pmf, 1 - alpha / 2) / n


def interval_by_fault(counts: Counts, seeds: int, *, confidence: float = 0.95) -> tuple[float, float]:
    """The by-fault interval of a cell's (or several classes' pooled) passing rate.

    For ``0 < k < n``: the percentile interval of the exact cluster bootstrap over faults
    (``bootstrap_interval``; stratified by class when several are pooled), widened where needed to
    contain the Wilson interval of ``(k, n)``. The floor is the model's, not a patch: if a fault
    passes each of its episodes independently with its own probability ``p_i``, the variance of
    the cell rate is the binomial one times ``1 + (seeds - 1) var(p_i) / (p (1 - p)) >= 1``, so an
    interval narrower than Wilson's only reflects faults that happened to look alike (at the
    extreme, every fault passing the same number of episodes gives a bootstrap interval of zero
    width).

    For ``k = 0`` or ``k = n`` every resample repeats the observed rate and the data say nothing
    about how outcomes cluster by fault. We report the Wilson interval with the number of faults
    as the sample size (``0`` or ``n_faults`` of ``n_faults``), the bound for the worst case in
    which every fault is all-or-nothing (design effect ``seeds``): [0, 7.1] % at ``k = 0`` for
    50 faults, against Wilson's [0, 0.8] % over 500 independent episodes.

    Coverage (``benchmarks/by_fault_coverage.py``; docs/statistics.md): on simulated 50 x 10 cells
    whose per-fault probabilities range from all alike to all-or-nothing, it covers the class's rate
    92-96 % of the time at rates of 10 % and above, where Wilson's covers 47-95 %; at 2-5 %, where
    only a handful of faults settle anything, 85-98 % (Wilson's 40-96 %).

    Args:
        counts: ``(n_faults,)`` int passing episodes per fault, or ``(n_strata, n_faults)`` (a list
            of ``(n_faults_s,)`` arrays) for classes pooled; each entry in ``0..seeds``.
        seeds: episodes per fault (initial conditions).
        confidence: two-sided coverage.

    Returns:
        ``(low, high)``, fractions in ``[0, 1]``.
    """
    from scftc_cli.scoring import wilson_interval  # scoring imports this module: import late

    strata = strata_of(counts)
    _check_seeds(strata, seeds)
    n_faults = sum(row.size for row in strata)
    k, n = sum(int(row.sum()) for row in strata), seeds * n_faults
    if k in (0, n):
        return wilson_interval(0 if k == 0 else n_faults, n_faults, confidence)
    low, high = bootstrap_interval(strata, seeds, confidence=confidence)
    w_low, w_high = wilson_interval(k, n, confidence)
    return min(low, w_low), max(high, w_high)


def design_effect(counts: Counts, seeds: int) -> float | None:
    """The variance of the pooled passing rate under the by-fault design over its binomial
    variance ``p (1 - p) / n``: how many times fewer independent episodes the cell is worth
    (Kish's design effect; ``n / deff`` is its effective sample size).

    The numerator is the variance of the by-fault bootstrap distribution (stratified when several
    classes are pooled): ``sum_s (m_s seeds / n)^2 var_s(r) / m_s`` with ``r`` the per-fault rates
    ``counts / seeds`` and ``var_s`` their population variance in stratum ``s`` (``m_s`` faults).
    It is ``seeds`` when every fault is all-or-nothing, near 1 when outcomes do not depend on the
    fault, and below 1 when the faults are more alike than independent episodes would be.

    Args:
        counts: as ``interval_by_fault``.
        seeds: episodes per fault.

    Returns:
        The ratio, or ``None`` where ``p`` is 0 or 1 (both variances vanish).
    """
    strata = strata_of(counts)
    _check_seeds(strata, seeds)
    n = seeds * sum(row.size for row in strata)
    p = sum(int(row.sum()) for row in strata) / n
    if p in (0.0, 1.0):
        return None
    clustered = sum((row.size * seeds / n) ** 2 * np.var(row / seeds) / row.size for row in strata)
    return float(clustered / (p * (1 - p) / n))


def paired_by_fault(a_counts: np.ndarray, b_counts: np.ndarray, seeds: int) -> float:
    """Two controllers on the same faults: the exact two-sided sign-flip permutation test whose
    unit is the fault.

    The statistic is the difference of the settled counts, ``t = sum(a - b)``, a multiple of the
    difference of the settled rates. Under the null hypothesis the two controllers' counts on a
    fault are exchangeable (on no fault is one better), so each per-fault difference
    ``d_i = a_i - b_i`` is as likely to carry either sign, and the p-value is the share of the
    ``2**m`` sign patterns of the ``m`` non-zero differences with ``|sum_i +-d_i| >= |t|``
    (faults with ``d_i = 0`` change nothing). The share is computed exactly, for any ``m``, from the
    distribution of ``sum_i +-d_i`` (a convolution over the integers ``-sum|d|..sum|d|``), not by
    enumerating or sampling the patterns. The smallest possible p-value is ``2 / 2**m``: with few
    faults on which the two differ, no difference can be significant, however many episodes.

    Args:
        a_counts, b_counts: ``(n_faults,)`` int, each fault's settled episodes for A and for B, the
            faults in the same order (the same episodes: the public draw).
        seeds: episodes per fault (checks the counts).

    Returns:
        The two-sided p-value in ``(0, 1]``; 1 when A and B settle alike on every fault.
    """
    a, b = strata_of(a_counts), strata_of(b_counts)
    if len(a) != 1 or len(b) != 1 or a[0].shape != b[0].shape:
        raise ValueError("a_counts and b_counts must be (n_faults,) arrays of the same faults")
    _check_seeds(a + b, seeds)
    d = a[0] - b[0]
    observed = abs(int(d.sum()))
    steps = np.abs(d[d != 0])
    offset = int(steps.sum())
    pmf = np.zeros(2 * offset + 1)  # pmf[offset + s] = P(sum_i +-d_i = s)
    pmf[offset] = 1.0
    for v in steps:
        flipped = np.zeros_like(pmf)
        flipped[: pmf.size - v] += 0.5 * pmf[v:]
        flipped[v:] += 0.5 * pmf[: pmf.size - v]
        pmf = flipped
    support = np.arange(-offset, offset + 1)
    return float(min(1.0, pmf[np.abs(support) >= observed].sum()))


def _subset_sum_distribution(values: np.ndarray, size: int) -> np.ndarray:
    """``(sum(values) + 1,)`` float: the distribution of the sum of a uniformly random ``size``-subset
    of ``values`` (non-negative ints), by the recursion over items ``N[j, s] += N[j - 1, s - v]``
    (``N[j, s]`` counts the ``j``-subsets summing to ``s``; float counts stay exact to rounding)."""
    total = int(values.sum())
    ways = np.zeros((size + 1, total + 1))
    ways[0, 0] = 1.0
    for v in values:
        ways[1:, v:] = ways[1:, v:] + ways[:-1, : total + 1 - v]
        if ways[size].max() > 1e250:  # beyond ~1000 faults: rescale (only ratios matter)
            ways /= ways.max()
    return ways[size] / ways[size].sum()


def two_sample_by_fault(a_strata: Counts, b_strata: Counts, seeds: int) -> float:
    """Two independent draws (two board entries' sealed draws: different faults): the exact
    two-sided permutation test of the pooled settled rate, stratified by class, whose unit is the
    fault.

    The statistic is the difference of the pooled rates, ``K_a / N_a - K_b / N_b``. Under the null
    hypothesis both entries' per-fault counts in a class come from the same distribution, so the
    faults of the two entries are exchangeable within each class: a permutation pools a class's
    faults of both entries and deals them out again in the original numbers, class by class. The
    p-value is the share of all such permutations whose ``|difference|`` is at least the observed
    one, computed exactly: per class the distribution of A's share of the pooled faults is a
    subset-sum distribution, and the classes are independent, so their distributions convolve.
    Unlike Fisher's exact test on the pooled ``(K, N)``, it treats a fault's ``seeds`` episodes as
    one unit and keeps each class's difficulty to itself.

    Args:
        a_strata, b_strata: per class, the per-fault settled counts of each entry:
            ``(n_strata, n_faults)`` or a list of ``(n_faults_s,)`` arrays, the classes in the
            same order for both (the numbers of faults may differ); a 1-D array is one class.
        seeds: episodes per fault, the same for both.

    Returns:
        The two-sided p-value in ``(0, 1]``.
    """
    a, b = strata_of(a_strata), strata_of(b_strata)
    if len(a) != len(b):
        raise ValueError(f"{len(a)} strata for A, {len(b)} for B: pass the same classes for both")
    _check_seeds(a + b, seeds)
    m_a, m_b = sum(r.size for r in a), sum(r.size for r in b)
    k_a, k_b = sum(int(r.sum()) for r in a), sum(int(r.sum()) for r in b)
    total = k_a + k_b
    null = np.ones(1)  # P(A's pooled count = k) under the permutations
    for ra, rb in zip(a, b, strict=True):
        null = np.convolve(null, _subset_sum_distribution(np.concatenate([ra, rb]), ra.size))
    k = np.arange(null.size)
    # m_a m_b seeds times the rate difference: an integer, so the comparison has no rounding
    return float(min(1.0, null[np.abs(k * m_b - (total - k) * m_a) >= abs(k_a * m_b - k_b * m_a)].sum()))


def performance_profile(
    final_error_deg: np.ndarray | Sequence[np.ndarray], taus_deg: np.ndarray = PROFILE_TAUS_DEG
) -> np.ndarray:
    """``(t,)`` the fraction of episodes whose final pointing error is ``<= tau`` for each ``tau`` in
    ``taus_deg`` (deg); rliable's performance profile with "error <= tau" for "score > tau".

    With several cells (a list of ``(n_c,)`` arrays) it is the mean of the cells' profiles, each
    cell weighing the same (rliable's convention; equal to pooling the episodes when every cell
    holds the same ``n``, as on this benchmark).
    """
    cells = [final_error_deg] if isinstance(final_error_deg, np.ndarray) else list(final_error_deg)
    taus = np.asarray(taus_deg, dtype=float)
    return np.mean([np.mean(np.asarray(c)[:, None] <= taus[None, :], axis=0) for c in cells], axis=0)


def profile_counts(final_error_deg: np.ndarray, taus_deg: np.ndarray = PROFILE_TAUS_DEG) -> np.ndarray:
    """``(t,)`` int: episodes of one cell whose error is ``<= tau``, for each ``tau``: what a board
    stores per cell (integers on a fixed grid, exact, and pooled over cells by ``pooled_profile``).
    Given the final errors it is the final-error profile (``FinalError.profile``, on
    ``PROFILE_TAUS_DEG``); given each episode's largest error over the final dwell of every pointing
    window it is the ranked gate's profile (``SettledProfile``), equal at the settled tolerance to
    the settled count."""
    errors = np.asarray(final_error_deg, dtype=float)
    return np.count_nonzero(errors[:, None] <= np.asarray(taus_deg, dtype=float)[None, :], axis=0)


def with_thresholds(taus_deg: np.ndarray, thresholds_deg: Sequence[float]) -> np.ndarray:
    """``(t',)`` the grid ``taus_deg`` (deg) with ``thresholds_deg`` inserted, sorted and without
    repeats: a profile on it reads each threshold exactly, not at the nearest grid point."""
    return np.union1d(np.asarray(taus_deg, dtype=float), np.asarray(thresholds_deg, dtype=float))


def profile_by_fault(
    error_deg: np.ndarray, fault_index: np.ndarray, taus_deg: np.ndarray = PROFILE_TAUS_DEG
) -> tuple[np.ndarray, int]:
    """``(counts (t, n_faults) int, seeds)``: for each ``tau`` of ``taus_deg`` (deg), the episodes
    of each fault (ascending fault index, as ``per_fault_counts``) whose error is ``<= tau``.

    Args:
        error_deg: ``(n,)`` one error per episode (deg); a profile of the ranked gate passes each
            episode's largest error over the final dwell of every pointing window.
        fault_index: ``(n,)`` int, the fault of each episode.
    """
    errors, taus = np.asarray(error_deg, dtype=float), np.asarray(taus_deg, dtype=float)
    rows = [per_fault_counts(errors <= tau, fault_index) for tau in taus]
    seeds = rows[0][1] if rows else 1
    return np.array([counts for counts, _ in rows], dtype=np.int64).reshape(taus.size, -1), seeds


def profile_intervals(counts: np.ndarray, seeds: int, *, confidence: float = 0.95) -> np.ndarray:
    """``(t, 2)`` the by-fault interval (``interval_by_fault``) of a profile at each threshold: the
    band around it.

    Args:
        counts: ``(t, n_faults)`` int, the passing episodes of each fault at each threshold
            (``profile_by_fault``), or ``(t, n_strata, n_faults)`` for classes pooled.
        seeds: episodes per fault.

    Returns:
        ``[low, high]`` fractions per threshold; each contains the profile's rate there (it is
        never narrower than Wilson's, which contains ``k / n``). Thresholds whose per-fault counts
        repeat (the flat tails of a profile) are computed once.
    """
    done: dict[bytes, tuple[float, float]] = {}
    out = np.empty((len(counts), 2))
    for i, row in enumerate(np.asarray(counts, dtype=np.int64)):
        key = row.tobytes()
        if key not in done:
            done[key] = interval_by_fault(row, seeds, confidence=confidence)
        out[i] = done[key]
    return out


def pooled_profile(counts: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``(t,)`` the performance profile of several cells from their stored ``profile_counts``.

    Args:
        counts: ``(cells, t)`` int, each cell's ``profile_counts`` on the same ``tau`` grid.
        n: ``(cells,)`` int, each cell's episodes.

    Returns:
        The mean over cells of ``counts / n`` (``performance_profile`` of the cells' errors).
    """
    counts, n = np.asarray(counts, dtype=float), np.asarray(n, dtype=float)
    return np.mean(counts / n[:, None], axis=0)


def settled_at(
    dwell_max_error_deg: np.ndarray, gates_deg: Sequence[float] = SENSITIVITY_GATES_DEG
) -> np.ndarray:
    """``(g,)`` int: episodes whose largest error over the final dwell window is ``<= gate``, for
    each gate (deg): the settled count had the gate been that threshold (the dwell unchanged).
    At the benchmark's own gate it is the cell's settled ``k``."""
    worst = np.asarray(dwell_max_error_deg, dtype=float)
    return np.count_nonzero(worst[:, None] <= np.asarray(gates_deg, dtype=float)[None, :], axis=0)


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's (1979) step-down adjustment of ``p_values``, returned in the input order: the
    ``i``-th smallest p-value times ``m - i`` (``i`` from 0), made non-decreasing in that order and
    capped at 1. It controls the family-wise error rate over the ``m`` tests under any dependence.
    (statsmodels' ``multipletests(method="holm")`` gives the same numbers; the tests check it; this
    one keeps ``scipy.stats`` off the board's start-up.)"""
    p = np.asarray(p_values, dtype=float)
    if p.size == 0:
        return []
    order = np.argsort(p, kind="stable")
    stepped = np.minimum(1.0, np.maximum.accumulate(p[order] * (p.size - np.arange(p.size))))
    adjusted = np.empty_like(p)
    adjusted[order] = stepped
    return [float(x) for x in adjusted]
