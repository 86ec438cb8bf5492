"""``scftc-v1``'s simulator: a rigid body with body-axis torques and perfect sensors."""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context, TrueFault
from scftc_cli.sim.testbed import Sensors, Testbed
from scftc_cli.versions.v1.sim.faults import RigidEpisodes, pinned_episodes
from scftc_cli.versions.v1.sim.sensors import StarTrackerAndGyro
from scftc_cli.versions.v1.spec import V1


class RigidBodyTestbed(Testbed):
    """``scftc-v1`` (docs/benchmark.md): backends ``numpy`` (fused), ``reference``, ``basilisk``."""

    spec = V1

    plants = {
        "numpy": "scftc_cli.versions.v1.sim.fast:FastPlant",
        "reference": "scftc_cli.versions.v1.sim.dynamics:ReferencePlant",
        "basilisk": "scftc_cli.versions.v1.sim.basilisk:BasiliskPlant",  # BackendUnavailable without bsk
    }
    pinned = staticmethod(pinned_episodes)
    sensor_fault_per_episode = False  # StarTrackerAndGyro holds the cell's one sensor fault

    def sensors(self, episodes: RigidEpisodes) -> Sensors:  # type: ignore[override]
        return StarTrackerAndGyro(episodes)

    def context(self, episodes: RigidEpisodes, privileged: bool) -> Context:  # type: ignore[override]
        return public_context(
            episodes.n, TrueFault(episodes.fault.theta, episodes.fault.beta) if privileged else None
        )


def public_context(n: int, fault: TrueFault | None = None) -> Context:
    """The context of ``n`` ``scftc-v1`` episodes: ``dt``, ``tau_max`` and the nominal inertia."""
    plant = V1.plant
    return Context(
        n=n,
        benchmark_version=V1.version,
        dt_s=plant.dt_s,
        obs_dim=V1.obs_dim,
        action_dim=V1.action_dim,
        inertia_nominal_kgm2=np.array(plant.inertia_nominal_kgm2),
        tau_max_nm=plant.tau_max_nm,
        fault=fault,
    )


TESTBED = RigidBodyTestbed()
