"""Coverage of the by-fault interval against the Wilson interval on simulated clustered cells.

Run: ``python benchmarks/by_fault_coverage.py [--out benchmarks/results/by_fault_coverage.json]
[--reps 2000]``

A cell is ``faults x seeds`` episodes (50 x 10 as on the benchmark). Each fault ``i`` settles each
of its episodes independently with its own probability ``p_i``, drawn from a beta distribution
with mean ``mu`` and intra-fault correlation ``rho`` (``rho = 0``: every fault the same, outcomes
independent of the fault; ``rho -> 1``: every fault all-or-nothing); the design effect of such a
cell is ``1 + (seeds - 1) rho``. The target is ``mu``, the settled rate over the class's fault
distribution, which is what a held-out cell estimates. For every ``(mu, rho)`` the script draws
``reps`` cells from ``np.random.default_rng(seed)`` and counts how often each interval contains
``mu``, with the mean width. Rates above one half mirror those below (swap settled and not).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from scftc_cli.scoring import wilson_interval
from scftc_cli.statistics import design_effect, interval_by_fault

MEANS = (0.01, 0.02, 0.05, 0.1, 0.3, 0.5)
CORRELATIONS = (0.0, 0.1, 0.3, 0.6, 0.9)


def per_fault_probabilities(rng: np.random.Generator, mean: float, rho: float, faults: int) -> np.ndarray:
    """``(faults,)`` settle probabilities with mean ``mean`` and intra-fault correlation ``rho``."""
    if rho == 0:
        return np.full(faults, mean)
    scale = 1 / rho - 1
    return rng.beta(mean * scale, (1 - mean) * scale, faults)


def coverage(
    mean: float, rho: float, reps: int, faults: int, seeds: int, rng: np.random.Generator
) -> dict[str, float]:
    """Coverage and mean width (fractions) of both intervals, and the mean design effect."""
    hit = {"wilson": 0, "by_fault": 0}
    width = {"wilson": 0.0, "by_fault": 0.0}
    effects = []
    for _ in range(reps):
        counts = rng.binomial(seeds, per_fault_probabilities(rng, mean, rho, faults))
        k = int(counts.sum())
        for name, (low, high) in (
            ("wilson", wilson_interval(k, faults * seeds)),
            ("by_fault", interval_by_fault(counts, seeds)),
        ):
            hit[name] += low <= mean <= high
            width[name] += high - low
        if (effect := design_effect(counts, seeds)) is not None:
            effects.append(effect)
    return {
        "mean": mean,
        "rho": rho,
        "design_effect_model": 1 + (seeds - 1) * rho,
        "design_effect_estimated": float(np.mean(effects)) if effects else float("nan"),
        "coverage_wilson": hit["wilson"] / reps,
        "coverage_by_fault": hit["by_fault"] / reps,
        "width_wilson": width["wilson"] / reps,
        "width_by_fault": width["by_fault"] / reps,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/by_fault_coverage.json"))
    parser.add_argument("--reps", type=int, default=2000)
    parser.add_argument("--faults", type=int, default=50)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    rows = [
        coverage(mean, rho, args.reps, args.faults, args.seeds, rng) for mean in MEANS for rho in CORRELATIONS
    ]
    print("mean   rho  deff(model/est)  coverage Wilson / by fault   width Wilson / by fault (points)")
    for r in rows:
        print(
            f"{r['mean']:5.2f} {r['rho']:4.1f}   "
            f"{r['design_effect_model']:4.1f} / {r['design_effect_estimated']:4.1f}"
            f"       {r['coverage_wilson']:.3f} / {r['coverage_by_fault']:.3f}"
            f"             {100 * r['width_wilson']:5.1f} / {100 * r['width_by_fault']:5.1f}"
        )
    doc = {
        "what": __doc__.splitlines()[0],
        "faults": args.faults,
        "seeds": args.seeds,
        "reps": args.reps,
        "seed": args.seed,
        "seconds": round(time.perf_counter() - start, 1),
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
