"""Gates and statistics: pure functions over arrays (SPEC section 3).

The gates read the *true* pointing error; ``error_deg`` is ``(n, steps)`` for steps 1..steps.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import binomtest

from scftc_cli.records import CellResult, FinalError, GateStat
from scftc_cli.sim.rollout import Rollout
from scftc_cli.spec import SPEC


def settled(
    error_deg: np.ndarray, threshold_deg: float = SPEC.gates.settled_deg,
    dwell_steps: int = SPEC.gates.dwell_steps,
) -> np.ndarray:
    """``(n,)`` bool: the error stays within ``threshold_deg`` for all of the final dwell steps."""
    return np.all(error_deg[:, -dwell_steps:] <= threshold_deg, axis=1)


def operational(
    error_deg: np.ndarray, threshold_deg: float = SPEC.gates.operational_deg,
    dwell_steps: int = SPEC.gates.dwell_steps,
) -> np.ndarray:
    """``(n,)`` bool: the coarse gate, within ``threshold_deg`` over the final dwell steps."""
    return settled(error_deg, threshold_deg, dwell_steps)


def touch_once(error_deg: np.ndarray, threshold_deg: float = SPEC.gates.touch_deg) -> np.ndarray:
    """``(n,)`` bool: the error touched ``threshold_deg`` at least once (reported to show why a
    transient minimum misleads)."""
    return np.min(error_deg, axis=1) <= threshold_deg


def wilson_interval(k: int, n: int, confidence: float = SPEC.confidence) -> tuple[float, float]:
    """Wilson score interval of ``k`` successes in ``n`` trials (scipy)."""
    ci = binomtest(int(k), int(n)).proportion_ci(confidence, method="wilson")
    return float(ci.low), float(ci.high)


def gate_stat(passed: np.ndarray) -> GateStat:
    """Summarize ``(n,)`` bool outcomes as k, rate and Wilson interval."""
    k, n = int(np.count_nonzero(passed)), int(passed.size)
    low, high = wilson_interval(k, n)
    return GateStat(k=k, rate=k / n, ci_low=low, ci_high=high)


def gate_outcomes(rollout: Rollout) -> dict[str, np.ndarray]:
    """``(n,)`` bool outcome of each gate from the statistics accumulated during a rollout."""
    gates = SPEC.gates
    return {
        "settled": rollout.dwell_max_error_deg <= gates.settled_deg,
        "operational": rollout.dwell_max_error_deg <= gates.operational_deg,
        "touch_once": rollout.min_error_deg <= gates.touch_deg,
    }


def score_cell(rollout: Rollout, split: str, fault_class: str, sensor: str | None) -> CellResult:
    """The scored cell of a rollout."""
    outcomes = gate_outcomes(rollout)
    return CellResult(
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        n=rollout.final_error_deg.size,
        **{gate: gate_stat(passed) for gate, passed in outcomes.items()},
        final_error_deg=FinalError(
            median=float(np.median(rollout.final_error_deg)),
            mean=float(np.mean(rollout.final_error_deg)),
        ),
    )
