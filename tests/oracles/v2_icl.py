"""``icl_adaptive``'s stack curation (``scftc_cli/versions/v2/controllers/icl.py``) one candidate
at a time: the readable form of ``_offer_rows``, which scores a full stack's candidates in two
passes. Compiled too (it runs the production ``_score``), but not cached: numba's cache would not
notice a change to the production helpers it calls, which live in another file."""

from __future__ import annotations

import numba
import numpy as np

from scftc_cli.versions.v2.controllers.icl import _information, _score, _store


@numba.njit
def _offer_rows(ys, us, used, y, u, offer, margin):  # pragma: no cover - compiled
    """``icl._offer_rows`` one candidate at a time through ``_score``: offer each window to its
    stack, fill a free slot, else replace the slot whose replacement scores best if that beats
    ``margin`` times the current score."""
    n, m, size = used.shape
    for e in range(n):
        for w in range(m):
            if not offer[e, w]:
                continue
            i0, i1, i2, i3, i4, i5, free = _information(ys, used, e, w)
            if free >= 0:
                _store(ys, us, used, e, w, free, y, u)
                continue
            now = _score(i0, i1, i2, i3, i4, i5)
            best, best_j = -np.inf, -1
            na, no, ns = y[e, w, 0], y[e, w, 1], y[e, w, 2]
            for j in range(size):
                a, one, s = ys[e, w, j, 0], ys[e, w, j, 1], ys[e, w, j, 2]
                score = _score(
                    i0 - a * a + na * na,
                    i1 - a * one + na * no,
                    i2 - a * s + na * ns,
                    i3 - one * one + no * no,
                    i4 - one * s + no * ns,
                    i5 - s * s + ns * ns,
                )
                if score > best:
                    best, best_j = score, j
            if best > margin * now + 1e-12:
                _store(ys, us, used, e, w, best_j, y, u)
