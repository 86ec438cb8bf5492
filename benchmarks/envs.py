"""Throughput of the gymnasium environments, the fused kernel next to the plain numpy plant, in one run.

Run: ``python benchmarks/envs.py [--out benchmarks/results/envs.json] [--quick]``

Zero actions, 2 x 400 steps per measurement (each includes the same-step autoreset that draws the
next episodes), best of a few repeats. ``backend="numpy"`` is the fused numba kernel (what the
environment uses); ``backend="reference"`` is the readable numpy plant the environment stepped
before. Ratios are the portable numbers; absolute figures depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import scftc_cli  # noqa: F401  (registers the environments)

STEPS = 800


def vector_rate(num_envs: int, backend: str, repeats: int) -> float:
    env = gym.make_vec(
        "scftc/AttitudeFTC-v1", num_envs=num_envs, vectorization_mode="vector_entry_point", backend=backend
    )
    zeros = np.zeros((num_envs, 3), dtype=np.float32)
    env.reset(seed=0)
    for _ in range(3):
        env.step(zeros)  # warm-up (JIT cache load, allocations)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(STEPS):
            env.step(zeros)
        best = min(best, time.perf_counter() - start)
    return num_envs * STEPS / best


def single_step_us(repeats: int) -> float:
    env = gym.make("scftc/AttitudeFTC-v1")
    env.reset(seed=0)
    action = np.zeros(3, dtype=np.float32)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(STEPS):
            _, _, _, truncated, _ = env.step(action)
            if truncated:
                env.reset()
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / STEPS


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/envs.json"))
    parser.add_argument("--quick", action="store_true", help="one repeat")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    rows = []
    for n in (256, 8192):
        fused = vector_rate(n, "numpy", repeats)
        reference = vector_rate(n, "reference", repeats)
        rows.append({"num_envs": n, "fused_env_steps_per_s": fused, "numpy_env_steps_per_s": reference})
        print(
            f"num_envs {n:>5}: fused {fused / 1e6:6.2f} M env-steps/s | "
            f"numpy plant {reference / 1e6:5.2f} M | x{fused / reference:.1f}"
        )
    single = single_step_us(repeats)
    print(f"single environment: {single:.0f} us per step")
    doc = {
        "machine": platform.processor() or platform.machine(),
        "vector": rows,
        "single_env_us_per_step": single,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
