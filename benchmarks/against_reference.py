"""Whole commands timed against a reference commit in the same run: the speed of a change as ratios.

Run: ``python benchmarks/against_reference.py --reference REF [--only NAME ...] [--repeats N]
[--out benchmarks/results/against_reference.json]``

Checks the reference commit out into a temporary git worktree and runs each command twice per
repeat, once with this checkout's package and once with the reference's (``PYTHONPATH`` puts the
worktree's ``scftc_cli`` first), alternating which goes first, after one untimed warm-up each (numba
compiles its caches there). Prints and records each side's best wall time and the ratio
this / reference: below 1 is faster. Absolute times depend on the machine and its load; the ratio,
measured side by side, is the portable number.

The commands (``--only`` picks some):
- ``v2-reproduce``: ``scftc reproduce --benchmark scftc-v2 --workers 2``;
- ``v3-reproduce``: ``scftc reproduce --benchmark scftc-v3 --workers 2``;
- ``v2-verify``: ``scftc leaderboard verify --benchmark scftc-v2 --workers 2``;
- ``v1-pd-loop``: ``pd`` flying 10 000 ``scftc-v1`` episodes for 400 steps (the fused plant's loop),
  timed inside the process.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

PD_LOOP = (
    "import time\n"
    "from scftc_cli.registry import make_controller\n"
    "from scftc_cli.sim.rollout import rollout\n"
    "from scftc_cli.sim.testbed import testbed\n"
    "bed = testbed('scftc-v1')\n"
    "rollout(make_controller('pd', 'scftc-v1'), bed.draw('test', 'sign', None, 2, 1))  # compile\n"
    "episodes = bed.draw('test', 'sign', None, 1000, 10)\n"
    "start = time.perf_counter()\n"
    "rollout(make_controller('pd', 'scftc-v1'), episodes)\n"
    "print('ELAPSED', time.perf_counter() - start)\n"
)
"""The v1 loop alone: 10 000 episodes of 400 steps, timed inside the process (it prints
``ELAPSED``), so that import and cache loading do not count."""


def commands(out: Path) -> dict[str, list[str]]:
    """Name -> argv (after the Python executable)."""
    scftc = ["-m", "scftc_cli"]
    return {
        "v2-reproduce": [*scftc, "reproduce", "--benchmark", "scftc-v2", "--workers", "2", "--out", str(out)],
        "v3-reproduce": [*scftc, "reproduce", "--benchmark", "scftc-v3", "--workers", "2", "--out", str(out)],
        "v2-verify": [*scftc, "leaderboard", "verify", "--benchmark", "scftc-v2", "--workers", "2"],
        "v1-pd-loop": ["-c", PD_LOOP],
    }


def timed(argv: list[str], tree: Path) -> float:
    """Wall seconds of ``python argv`` with ``tree``'s package first on the path (or what the
    command itself reports timing, as a line ``ELAPSED seconds``)."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *argv], cwd=tree, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed in {tree}:\n{done.stderr[-2000:]}")
    inner = [line.split()[1] for line in done.stdout.splitlines() if line.startswith("ELAPSED ")]
    return float(inner[-1]) if inner else seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("--reference", required=True, help="the commit (or ref) to compare against")
    parser.add_argument("--only", nargs="*", help="command names (default: all)")
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/against_reference.json"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        worktree = Path(scratch) / "reference"
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--detach", str(worktree), args.reference],
            check=True,
            capture_output=True,
        )
        try:
            table = commands(Path(scratch) / "results")
            names = args.only or list(table)
            results = {}
            for name in names:
                argv = table[name]
                sides = {"this": REPO, "reference": worktree}
                for tree in sides.values():
                    timed(argv, tree)  # warm-up: numba's caches
                best = {side: float("inf") for side in sides}
                for repeat in range(args.repeats):
                    order = list(sides) if repeat % 2 == 0 else list(sides)[::-1]
                    for side in order:
                        best[side] = min(best[side], timed(argv, sides[side]))
                ratio = best["this"] / best["reference"]
                results[name] = {"this_s": best["this"], "reference_s": best["reference"], "ratio": ratio}
                print(f"{name}: {best['this']:.1f} s against {best['reference']:.1f} s (ratio {ratio:.3f})")
        finally:
            subprocess.run(
                ["git", "-C", str(REPO), "worktree", "remove", "--force", str(worktree)], check=False
            )
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True)
    record = {
        "reference": args.reference,
        "this": head.stdout.strip(),
        "repeats": args.repeats,
        "machine": platform.machine(),
        "cpus": os.cpu_count(),
        "results": results,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
