"""The bit patterns of float64 arrays, for the tests that hold compiled kernels to numpy's bits.

``np.testing.assert_array_equal`` on floats treats -0.0 as 0.0 and NaN as NaN whatever its payload;
on the int64 views every bit counts."""

from __future__ import annotations

from typing import Any

import numpy as np


def bits(a: Any) -> np.ndarray:
    """``a``'s float64 entries as int64 bit patterns; an array of another dtype as it is."""
    a = np.ascontiguousarray(a)
    return a.view(np.int64) if a.dtype == np.float64 else a
