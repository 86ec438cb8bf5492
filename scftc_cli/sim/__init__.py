"""Simulation: the closed loop (``rollout``), what a benchmark version's simulator provides
(``testbed``), episodes and seeds (``episodes``), MRP algebra (``mrp``), and one subpackage per
version (``v1``...)."""

BACKENDS: tuple[str, ...] = ("numpy", "reference", "basilisk")
"""``numpy``: the fused numba kernel (the default, bit-identical to ``reference``); ``reference``:
the readable numpy implementation; ``basilisk``: Basilisk's own dynamics (optional extra)."""
