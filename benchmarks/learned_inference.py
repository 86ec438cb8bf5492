"""Per-step cost of the learned controllers' inference at batch 500.

Run: ``python benchmarks/learned_inference.py [--repeats 5]``

For each learned controller, flies the held-out ``gain_bias`` cell (500 episodes, 400 steps) and
times every ``act`` call (features, network, latch, observer: everything the controller does per
step) and the whole rollout. Reports the median over repeats of the per-step mean, in ms; the
first rollout (JIT compilation, caches) is not timed. Absolute figures depend on the machine and
its load; compare runs taken side by side.
"""

from __future__ import annotations

import argparse
import statistics
import time

from scftc_cli.protocol import Controller
from scftc_cli.registry import make_controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v1.sim.testbed import TESTBED
from scftc_cli.versions.v1.spec import V1

LEARNED = ("rma_student", "rma_dob", "e2e_ppo")


def timed(controller: Controller) -> tuple[Controller, list[float]]:
    """``controller`` with its ``act`` wrapped to record each call's wall time."""
    act, spent = controller.act, []

    def wrapper(obs):  # type: ignore[no-untyped-def]
        start = time.perf_counter()
        out = act(obs)
        spent.append(time.perf_counter() - start)
        return out

    controller.act = wrapper  # type: ignore[method-assign]
    return controller, spent


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--controllers", nargs="*", default=list(LEARNED) + ["pd"])
    args = parser.parse_args()
    episodes = TESTBED.draw("test", "gain_bias")
    for name in args.controllers:
        rollout(make_controller(name), episodes.subset(slice(0, 8)))  # warm-up (JIT, caches)
        act_ms, total_ms = [], []
        for _ in range(args.repeats):
            controller, spent = timed(make_controller(name))
            start = time.perf_counter()
            rollout(controller, episodes)
            total_ms.append(1e3 * (time.perf_counter() - start) / V1.steps)
            act_ms.append(1e3 * sum(spent) / len(spent))
        print(
            f"{name:12s} batch {episodes.n}: act {statistics.median(act_ms):.3f} ms/step "
            f"(min {min(act_ms):.3f}), rollout {statistics.median(total_ms):.3f} ms/step"
        )


if __name__ == "__main__":
    main()
