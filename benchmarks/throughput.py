"""Throughput of the simulator and the evaluation path, measured side by side in one process.

Run: ``python benchmarks/throughput.py [--out benchmarks/results/throughput.json] [--quick]``

Measures (best of a few repeats, wall clock):
- env-steps/s of the dynamics with ``pd`` in the loop at batch 1, 500, 10 000 and 100 000, for
  the default fused backend and the numpy reference (the naive-RK4 yardstick);
- the per-step overhead of ``rma_dob`` (GRU inference + observer) at batch 500, as time per
  step relative to ``pd`` on the same episodes;
- the wall time of a full ``--class all`` evaluation (4 cells x 500 episodes) for ``pd`` and
  ``rma_dob``;
Basilisk's speed is ``benchmarks/backends.py``'s business. Ratios are the portable numbers;
absolute figures depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from scftc_cli.evaluate import Cell, evaluate_cells
from scftc_cli.registry import make_controller, registry
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v1.sim.faults import RigidEpisodes
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1

STEPS = V1.steps


def tiled_episodes(n: int) -> RigidEpisodes:
    """``n`` episodes made by tiling the held-out ``gain`` cell (drawing 100 000 fresh seeds would
    time the sampler, not the simulator)."""
    cell = TESTBED.draw("test", "gain")
    return cell.subset(np.arange(n) % cell.n)


def best_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def env_steps_per_s(controller: str, n: int, backend: str, repeats: int) -> float:
    episodes = tiled_episodes(n)
    rollout(make_controller(controller), episodes.subset(slice(0, min(n, 8))), backend=backend)
    seconds = best_time(lambda: rollout(make_controller(controller), episodes, backend=backend), repeats)
    return n * STEPS / seconds


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/throughput.json"))
    parser.add_argument("--quick", action="store_true", help="fewer repeats, skip batch 100 000")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    batches = (1, 500, 10_000) if args.quick else (1, 500, 10_000, 100_000)
    results: dict = {"machine": platform.processor() or platform.machine(), "steps": STEPS}

    rows = []
    for n in batches:
        fast = env_steps_per_s("pd", n, "numpy", repeats)
        ref = env_steps_per_s("pd", n, "reference", 1 if n >= 10_000 else repeats)
        rows.append(
            {
                "batch": n,
                "fast_env_steps_per_s": fast,
                "reference_env_steps_per_s": ref,
                "speedup": fast / ref,
            }
        )
        print(
            f"pd batch {n:>7}: fast {fast / 1e6:8.2f} M env-steps/s | numpy reference "
            f"{ref / 1e6:6.2f} M | x{fast / ref:5.1f}"
        )
    results["pd_throughput"] = rows

    have_rma_dob = "rma_dob" in registry()
    if have_rma_dob:
        episodes = TESTBED.draw("test", "gain_bias")
        t_pd = best_time(lambda: rollout(make_controller("pd"), episodes), repeats)
        t_rma = best_time(lambda: rollout(make_controller("rma_dob"), episodes), repeats)
        results["rma_dob_overhead"] = {
            "batch": 500,
            "pd_ms_per_step": 1e3 * t_pd / STEPS,
            "rma_dob_ms_per_step": 1e3 * t_rma / STEPS,
            "overhead_ms_per_step": 1e3 * (t_rma - t_pd) / STEPS,
        }
        print(
            f"rma_dob at batch 500: {1e3 * t_rma / STEPS:.3f} ms/step vs pd {1e3 * t_pd / STEPS:.3f} ms/step"
        )

    cells = [Cell("test", c) for c in V1.fault_classes]
    for name in ("pd", "rma_dob") if have_rma_dob else ("pd",):
        seconds = best_time(lambda name=name: evaluate_cells(lambda _c: make_controller(name), V1, cells), 1)
        results[f"eval_class_all_{name}_s"] = seconds
        print(f"eval --controller {name} --class all (library, warm): {seconds:.2f} s")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
