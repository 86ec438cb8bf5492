"""``icl_adaptive``'s stack curation (v2) with its candidates scored in two passes (``_offer_rows``:
the arithmetic vectorized, then the transcendental calls) gives the bits of scoring them one at a
time (``tests/oracles/v2_icl.py``): stacks filling and full, windows that replace and that do not,
degenerate stacks (every window the same: the closed form's equal-eigenvalue case) and collinear
offset and friction (``s = +-1`` throughout)."""

from __future__ import annotations

import numba
import numpy as np
import pytest

from scftc_cli.versions.v2.controllers.icl import (
    _score,
    _score_finish,
    _score_setup,
    stack_offer,
)
from tests.oracles import v2_icl as oracle


@numba.njit(error_model="numpy")
def _both_scores(entries):  # pragma: no cover - compiled
    out = np.empty((len(entries), 2))
    for k in range(len(entries)):
        m = entries[k]
        out[k, 0] = _score(m[0], m[1], m[2], m[3], m[4], m[5])
        q, p, r, degenerate, tie = _score_setup(m[0], m[1], m[2], m[3], m[4], m[5])
        out[k, 1] = _score_finish(q, p, r, degenerate, tie)
    return out


def test_the_two_pass_score_is_the_score_to_the_bit() -> None:
    """Information matrices of ten random windows, of collinear ones, of equal ones (degenerate)
    and nearly equal ones: ``_score_finish(*_score_setup(M))`` equals ``_score(M)`` bit for bit."""
    rng = np.random.default_rng(7)
    windows = _windows(rng, (200_000, 10), collinear=False)
    windows[50_000:100_000, :, 2] = 1.0  # offset and friction collinear
    windows[100_000:150_000] = windows[100_000:150_000, :1]  # every window the same
    windows[150_000:] = windows[150_000:, :1] + 1e-9 * rng.standard_normal((50_000, 10, 3))
    M = np.einsum("nji,njk->nik", windows, windows)
    entries = np.ascontiguousarray(M[:, [0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]])
    scores = _both_scores(entries)
    assert np.array_equal(scores[:, 0].view(np.int64), scores[:, 1].view(np.int64))


def _windows(rng: np.random.Generator, shape: tuple[int, ...], collinear: bool) -> np.ndarray:
    s = np.where(rng.random(shape) < 0.5, -1.0, 1.0) if not collinear else np.ones(shape)
    if not collinear:
        s = s * rng.uniform(0.2, 1.0, shape)
    return np.stack((rng.uniform(-1.0, 1.0, shape), np.ones(shape), s), axis=-1)


@pytest.mark.parametrize("n", [1, 13, 700])  # one episode, a few, several chunks on the threads
def test_two_pass_curation_gives_the_bits_of_scoring_one_candidate_at_a_time(n: int) -> None:
    rng = np.random.default_rng(n)
    m, size = 4, 10
    ys, us, used = np.zeros((n, m, size, 3)), np.zeros((n, m, size)), np.zeros((n, m, size), dtype=bool)
    ref = (ys.copy(), us.copy(), used.copy())
    replaced = 0
    for k in range(60):
        y = _windows(rng, (n, m), collinear=k < 20)  # offset and friction collinear at first
        if k % 9 == 0:
            y[: n // 2 + 1] = np.array([0.3, 1.0, 1.0])  # every window the same: degenerate stacks
        u = rng.normal(size=(n, m))
        offer = rng.random((n, m)) < 0.8
        before = ys.copy()
        stack_offer(ys, us, used, y, u, offer, 1.0)
        oracle._offer_rows(*ref, y, u, offer, 1.0)
        for got, want in zip((ys, us, used), ref, strict=True):
            assert np.array_equal(
                got.view(np.int64) if got.dtype == np.float64 else got,
                want.view(np.int64) if want.dtype == np.float64 else want,
            ), k
        replaced += int(used.all(axis=-1).any() and (ys != before).any())
    assert used.all()  # the stacks filled, then were curated
    assert replaced > 10  # and windows replaced stored ones
