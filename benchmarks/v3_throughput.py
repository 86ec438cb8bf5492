"""Wall-clock speed of ``scftc-v3``'s plant: ``python benchmarks/v3_throughput.py [--n 10000] [--steps 200]``.

Times env-steps per second (episodes x steps / wall seconds) of the fused kernel alone
(``MissionFastPlant.step``, the target error included), of the kernel plus the sensors
(``observe`` then ``step``, as a rollout calls them), and of the whole loop with ``pd`` flying:
its compiled law (``controllers/fused.py``) and, in the same run, its numpy definition
(``tests/oracles/v3_analytic.py``), with their ratio. Pinned ``train`` episodes of every class tiled
to ``--n``, after a warm-up step (numba compiles or loads its cache first). The load average is
printed beside each figure: on a shared machine other processes move the numbers.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from functools import partial
from pathlib import Path

import numpy as np

from scftc_cli.sim.testbed import testbed
from scftc_cli.versions.v3.controllers import fused
from scftc_cli.versions.v3.controllers import law as numpy_law
from scftc_cli.versions.v3.controllers.analytic import PD
from scftc_cli.versions.v3.sim.faults import AgileEpisodes

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: tests.oracles
from tests.oracles import v3_analytic as oracle


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def episodes(n: int) -> AgileEpisodes:
    """``n`` episodes: a pinned ``train`` draw of 8 x 2 per class, tiled."""
    bed = testbed("scftc-v3")
    parts = [bed.draw("train", c, n_faults=8, n_seeds=2) for c in bed.spec.fault_classes]
    batch = AgileEpisodes.concat(parts)
    return batch.subset(np.arange(n) % batch.n)


compiled_demand = fused.rate_limited_demand


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args()
    bed = testbed("scftc-v3")
    batch = episodes(args.n)
    command = np.random.default_rng(0).uniform(-1.0, 1.0, (batch.n, bed.spec.action_dim))

    plant = bed.plant(batch)
    plant.step(0, command)
    wall = time.perf_counter()
    for k in range(1, args.steps + 1):
        plant.step(k, command)
    wall = time.perf_counter() - wall
    print(f"kernel:           {batch.n * args.steps / wall / 1e6:.2f} M env-steps/s (load {_load()})")

    plant, sensors = bed.plant(batch), bed.sensors(batch)
    sensors.observe(0, plant)
    plant.step(0, command)
    wall = time.perf_counter()
    for k in range(1, args.steps + 1):
        sensors.observe(k, plant)
        plant.step(k, command)
    wall = time.perf_counter() - wall
    print(f"kernel + sensors: {batch.n * args.steps / wall / 1e6:.2f} M env-steps/s (load {_load()})")

    rates = {}
    for law in ("compiled", "numpy"):
        plant, sensors, controller = bed.plant(batch), bed.sensors(batch), PD()
        controller.reset(batch.n, bed.context(batch, privileged=False))
        act = controller.act if law == "compiled" else partial(oracle.act, controller)
        # the numpy run's demand hook on law.py's numpy function too
        fused.rate_limited_demand = compiled_demand if law == "compiled" else numpy_law.rate_limited_demand
        plant.step(0, act(sensors.observe(0, plant)))
        wall = time.perf_counter()
        for k in range(1, args.steps + 1):
            plant.step(k, act(sensors.observe(k, plant)))
        rates[law] = batch.n * args.steps / (time.perf_counter() - wall)
        print(f"loop, pd {law + ' law:':14} {rates[law] / 1e6:.2f} M env-steps/s (load {_load()})")
    fused.rate_limited_demand = compiled_demand
    print(f"compiled / numpy law: x{rates['compiled'] / rates['numpy']:.2f}")


if __name__ == "__main__":
    main()
