"""numba's vector width on an AVX-512 CPU: the learned policy's step with 512-bit vectors (the
package's default there, ``scftc_cli.WIDE_VECTORS``) against numba's own 256-bit ones.

Run: ``python benchmarks/vector_width.py [--rows 4250] [--steps 60] [--pairs 6]``

Each width runs in its own process (numba reads its CPU features once, when it loads). On a
machine with two cores or more the two processes run at the same time, one on each core, then
swap cores: both see the same machine, whose speed can otherwise move more between runs than
the effect measured. Each process steps ``scftc-v3``'s committed ``e2e_ppo`` policy on ``rows``
sequences of fixed inputs and reports its fastest step and the SHA-256 of everything it computed,
which must agree: the width changes no bit. The ratio reported is of the medians over the pairs:
this virtual machine also moves between a faster and a slower state (about 1.35x apart) from one
run to the next, which a single pair can straddle. On a CPU without AVX-512 both widths compile
the same code (the ratio is then 1 up to noise).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

CHILD = """
import hashlib, json, sys, time
from pathlib import Path
import numpy as np
from scftc_cli.baselines.policy import load_policy
from scftc_cli.versions import v3
rows, steps = int(sys.argv[1]), int(sys.argv[2])
net = load_policy(Path(v3.__file__).parent / "weights" / "e2e_ppo.npz")
inputs = net.w_ih.shape[0]
x = (np.arange(rows * inputs, dtype=np.float64).reshape(rows, inputs) * 0.6180339887498949) % 1.0 - 0.5
state = net.start(rows)
net.step(x, state)  # compiles (or loads the cache)
digest, best = hashlib.sha256(), float("inf")
for _ in range(steps):
    start = time.perf_counter()
    action = net.step(x, state)
    best = min(best, time.perf_counter() - start)
    digest.update(action.tobytes())
print(json.dumps({"ms": 1e3 * best, "sha256": digest.hexdigest()[:16]}))
"""


def _start(features: str, core: int | None, rows: int, steps: int) -> subprocess.Popen[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_CPU")}
    env["NUMBA_NUM_THREADS"] = "1"
    env["NUMBA_CPU_FEATURES"] = features
    command = [sys.executable, "-c", CHILD, str(rows), str(steps)]
    pin = (lambda: os.sched_setaffinity(0, {core})) if core is not None else None
    return subprocess.Popen(command, env=env, stdout=subprocess.PIPE, text=True, preexec_fn=pin)


def _result(process: subprocess.Popen[str]) -> tuple[float, str]:
    """``(fastest step in ms, sha256 prefix)`` a timing process printed."""
    out, _ = process.communicate()
    if process.returncode:
        raise SystemExit(f"a timing process failed (exit {process.returncode})")
    found = json.loads(out.strip().splitlines()[-1])
    return float(found["ms"]), str(found["sha256"])


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--rows", type=int, default=4250, help="sequences per step (a v3 worker's stack)")
    parser.add_argument("--steps", type=int, default=60, help="steps timed per process (the fastest counts)")
    parser.add_argument("--pairs", type=int, default=6, help="runs of both widths (cores swapped each time)")
    args = parser.parse_args()
    import llvmlite.binding as llvm

    from scftc_cli import WIDE_VECTORS

    # both widths named explicitly: a child given no NUMBA_CPU_FEATURES would get the package's
    # own choice (its pre-import hook), which is the wide one on AVX-512
    narrow = llvm.get_host_cpu_features().flatten()
    wide = f"{narrow},{WIDE_VECTORS}"
    if "+avx512f" not in narrow.split(","):
        print("no AVX-512 here: both widths compile the same code")
    cores = sorted(os.sched_getaffinity(0))
    together = len(cores) >= 2
    timings: dict[str, list[float]] = {"256-bit": [], "512-bit": []}
    for pair in range(args.pairs):
        if together:
            a, b = (cores[0], cores[1]) if pair % 2 == 0 else (cores[1], cores[0])
            runs = [_start(narrow, a, args.rows, args.steps), _start(wide, b, args.rows, args.steps)]
            (slow_ms, slow_sha), (fast_ms, fast_sha) = (_result(p) for p in runs)
            where = f"256-bit on core {a}, 512-bit on core {b}, at once"
        else:
            slow_ms, slow_sha = _result(_start(narrow, None, args.rows, args.steps))
            fast_ms, fast_sha = _result(_start(wide, None, args.rows, args.steps))
            where = "one after the other"
        same = "the same bits" if slow_sha == fast_sha else "DIFFERENT BITS"
        timings["256-bit"].append(slow_ms)
        timings["512-bit"].append(fast_ms)
        print(
            f"pair {pair + 1} ({where}): 256-bit {slow_ms:.2f} ms, 512-bit {fast_ms:.2f} ms a step "
            f"at {args.rows} rows, x{slow_ms / fast_ms:.2f}; {same} ({fast_sha})"
        )
        if slow_sha != fast_sha:
            raise SystemExit(1)
    narrow_ms, wide_ms = (statistics.median(t) for t in timings.values())
    print(
        f"median over {args.pairs} pairs: 256-bit {narrow_ms:.2f} ms, 512-bit {wide_ms:.2f} ms a step, "
        f"x{narrow_ms / wide_ms:.2f}"
    )


if __name__ == "__main__":
    main()
