"""Where a step of scftc-v2's closed loop goes: CPU time per episode-step of each part, in one run.

Run: ``python benchmarks/v2_loop_parts.py [--batch 10000] [--steps 100] [--repeats 3]
[--out benchmarks/results/v2_loop_parts.json]``

Flies ``pd`` through ``--steps`` steps of ``--batch`` held-out episodes (as
``benchmarks/v2_throughput.py``) with every kernel on one thread, and times each part of every step with the
process's CPU clock (``time.process_time``), which, unlike the wall clock, a busy second core does
not stretch much: this 2-core machine is shared with other jobs. Parts: the sensors (``observe``:
one numba pass that also draws the noise; and ``observe_reference``, its numpy form drawing from
numpy's generators, ``tests/oracles/v2_sensors.py``, on a second sensors object fed the same
plant), the controller's ``act``, the fused plant step and the numpy reference plant (a second
plant given the same commands).
Reported as nanoseconds per episode-step, best of ``--repeats`` runs, with the ratios fused /
reference; ``loop_serial`` is what one core would give the fused loop (sensors + controller + plant),
in env-steps per CPU-second.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from scftc_cli.registry import make_controller
from scftc_cli.sim.testbed import testbed
from scftc_cli.versions.v2.controllers import law
from scftc_cli.versions.v2.sim import fast, sensors
from scftc_cli.versions.v2.spec import V2

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: tests.oracles
from v2_throughput import tiled_episodes  # the same episodes

from tests.oracles import v2_sensors as oracle

PARTS = ("observe", "observe_reference", "act", "plant", "plant_reference")


def one_run(n: int, steps: int) -> dict[str, float]:
    """CPU seconds of each part over ``steps`` steps of ``n`` episodes."""
    episodes = tiled_episodes(n)
    bed = testbed(episodes.benchmark)
    plant, plant_ref = bed.plant(episodes, "numpy"), bed.plant(episodes, "reference")
    fused, reference = bed.sensors(episodes), bed.sensors(episodes)
    controller = make_controller("pd", V2.version)
    controller.reset(n, bed.context(episodes, controller.privileged))
    spent = dict.fromkeys(PARTS, 0.0)

    def timed(part: str, fn, *args):  # type: ignore[no-untyped-def]
        start = time.process_time()
        out = fn(*args)
        spent[part] += time.process_time() - start
        return out

    for k in range(steps):
        obs = timed("observe", fused.observe, k, plant)
        timed("observe_reference", oracle.observe, reference, k, plant)
        command = np.clip(timed("act", controller.act, obs), -1.0, 1.0)
        timed("plant_reference", plant_ref.step, k, command)
        timed("plant", plant.step, k, command)
    return spent


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--batch", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/v2_loop_parts.json"))
    args = parser.parse_args()
    # every kernel on one thread: CPU time is work
    fast.PARALLEL_MIN_BATCH = sensors.PARALLEL_MIN_BATCH = law.PARALLEL_MIN_BATCH = sys.maxsize
    one_run(8, 3)  # compile or load the kernels
    load_before = os.getloadavg()[0]
    runs = [one_run(args.batch, args.steps) for _ in range(max(1, args.repeats))]
    per = {part: min(r[part] for r in runs) / (args.batch * args.steps) * 1e9 for part in PARTS}
    loop = per["observe"] + per["act"] + per["plant"]
    doc = {
        "benchmark": "scftc-v2 closed loop with pd, CPU time per part (kernels on one thread)",
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "cpus": os.cpu_count(),
        "batch": args.batch,
        "steps": args.steps,
        "repeats": args.repeats,
        "ns_per_episode_step": per,
        "observe_reference_over_observe": per["observe_reference"] / per["observe"],
        "plant_reference_over_plant": per["plant_reference"] / per["plant"],
        "act_share_of_fused_loop": per["act"] / loop,
        "loop_serial_env_steps_per_cpu_s": 1e9 / loop,
        "loadavg_1min": [round(load_before, 2), round(os.getloadavg()[0], 2)],
    }
    for part in PARTS:
        print(f"{part:18s} {per[part]:8.1f} ns per episode-step")
    print(f"fused loop on one core: {doc['loop_serial_env_steps_per_cpu_s'] / 1e6:.2f} M env-steps per CPU-s")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
