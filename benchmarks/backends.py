"""One full cell through every backend in one run: how much faster the default is than Basilisk.

Run: ``python benchmarks/backends.py [--out benchmarks/results/backends.json]``

Times one whole ``pd`` cell (500 episodes x 400 steps, held-out ``sign`` by default) through
``evaluate_cell`` on the default ``numpy`` backend (the fused kernel), the ``reference`` numpy
path and Basilisk, in the same process, best of ``--repeats``. The Basilisk time includes
building its 500 hubs: that is part of what running a cell on it costs. Each backend's gate
counts and median final error are printed alongside, so a fast but wrong backend cannot pass
unnoticed. Absolute figures depend on the machine and its load; the ratio is the portable number.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

from scftc_cli.evaluate import Cell, evaluate_cell
from scftc_cli.records import CellResult
from scftc_cli.registry import make_controller
from scftc_cli.sim import BACKENDS
from scftc_cli.versions.v1.spec import V1 as SPEC


def time_cell(backend: str, cell: Cell, controller: str, repeats: int) -> tuple[float, CellResult]:
    """Best wall time (s) of one full cell on ``backend``, and the scored cell."""
    make = lambda _cell: make_controller(controller)  # noqa: E731
    evaluate_cell(make, SPEC, cell, n_faults=1, n_seeds=1, backend=backend)  # warm-up (JIT)
    best = float("inf")
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = evaluate_cell(make, SPEC, cell, backend=backend).result
        best = min(best, time.perf_counter() - start)
    return best, result


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=None, help="also write the figures as JSON here")
    parser.add_argument("--controller", default="pd")
    parser.add_argument("--class", dest="fault_class", default="sign", choices=SPEC.fault_classes)
    parser.add_argument("--repeats", type=int, default=1, help="best of this many runs per backend")
    args = parser.parse_args()

    cell = Cell("test", args.fault_class)
    env_steps = SPEC.n_faults * SPEC.n_seeds * SPEC.steps
    rows = {}
    for backend in BACKENDS:
        seconds, result = time_cell(backend, cell, args.controller, args.repeats)
        k = {gate: getattr(result, gate).k for gate in ("settled", "operational", "touch_once")}
        median_deg = result.final_error_deg.median
        rows[backend] = {
            "seconds": seconds,
            "env_steps_per_s": env_steps / seconds,
            "k": k,
            "median_final_error_deg": median_deg,
        }
        print(
            f"{backend:>9}: {seconds:8.3f} s  {env_steps / seconds:12,.0f} env-steps/s  k = {k}  "
            f"median final error {median_deg:.6f} deg"
        )
    ratio = rows["numpy"]["env_steps_per_s"] / rows["basilisk"]["env_steps_per_s"]
    same_k = rows["numpy"]["k"] == rows["basilisk"]["k"]
    print(f"numpy / basilisk: {ratio:.1f}x faster (same k on every gate: {same_k})")

    if args.out is not None:
        from scftc_cli.versions.v1.sim.basilisk import basilisk_version

        doc = {
            "benchmark_version": SPEC.version,
            "cell": {"split": cell.split, "class": cell.fault_class, "controller": args.controller},
            "episodes": SPEC.n_faults * SPEC.n_seeds,
            "env_steps": env_steps,
            "repeats": args.repeats,
            "backends": rows,
            "numpy_over_basilisk": ratio,
            "same_k": same_k,
            "basilisk_version": basilisk_version(),
            "machine": platform.processor() or platform.machine(),
            "python": platform.python_version(),
        }
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(doc, indent=2) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
