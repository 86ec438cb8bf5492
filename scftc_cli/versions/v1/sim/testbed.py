"""``scftc-v1``'s simulator: a rigid body with body-axis torques and perfect sensors."""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context, TrueFault
from scftc_cli.sim.testbed import Plant, Sensors, Testbed, check_backend
from scftc_cli.versions.v1.sim.dynamics import ReferencePlant, RigidPlant
from scftc_cli.versions.v1.sim.faults import RigidEpisodes, pinned_episodes
from scftc_cli.versions.v1.sim.sensors import StarTrackerAndGyro
from scftc_cli.versions.v1.spec import V1


class RigidBodyTestbed(Testbed):
    """``scftc-v1`` (docs/benchmark.md): backends ``numpy`` (fused), ``reference``, ``basilisk``."""

    spec = V1

    def pinned(
        self,
        split: str,
        fault_class: str,
        sensor: str | None,
        n_faults: int,
        n_seeds: int,
        salt: bytes,
        start: int,
        stop: int,
    ) -> RigidEpisodes:
        return pinned_episodes(split, fault_class, sensor, n_faults, n_seeds, salt, start, stop)

    def plant(self, episodes: RigidEpisodes, backend: str = "numpy") -> Plant:  # type: ignore[override]
        check_backend(backend)
        cls: type[RigidPlant]
        if backend == "numpy":
            from scftc_cli.versions.v1.sim.fast import FastPlant

            cls = FastPlant
        elif backend == "reference":
            cls = ReferencePlant
        else:
            from scftc_cli.versions.v1.sim.basilisk import BasiliskPlant  # BackendUnavailable without bsk

            cls = BasiliskPlant
        plant = self.spec.plant
        fault = episodes.fault
        inertia = fault.inertia_scale[:, None] * np.asarray(plant.inertia_nominal_kgm2)
        return cls(
            episodes.sigma0,
            episodes.omega0_rad_s,
            inertia,
            fault.gain,
            fault.bias,
            plant.tau_max_nm,
            plant.dt_s,
        )

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
