"""``scftc-v2``'s simulator: a hub with four reaction wheels, noisy redundant sensors, mid-flight faults."""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context, WheelKnowledge
from scftc_cli.sim.testbed import Sensors, Testbed
from scftc_cli.versions.v2.sim.dynamics import WheelConstants
from scftc_cli.versions.v2.sim.faults import WheelEpisodes, WheelFault, pinned_episodes
from scftc_cli.versions.v2.sim.sensors import HeadsGyroTachometers, sensor_knowledge
from scftc_cli.versions.v2.spec import V2, ReactionWheelPlant


class ReactionWheelTestbed(Testbed):
    """``scftc-v2`` (docs/benchmark-v2.md): backends ``numpy`` (fused), ``reference``, ``basilisk``."""

    spec = V2

    plants = {
        "numpy": "scftc_cli.versions.v2.sim.fast:FastWheelPlant",
        "reference": "scftc_cli.versions.v2.sim.dynamics:WheelPlant",
        "basilisk": "scftc_cli.versions.v2.sim.basilisk:BasiliskWheelPlant",  # BackendUnavailable without bsk
    }
    pinned = staticmethod(pinned_episodes)

    def sensors(self, episodes: WheelEpisodes) -> Sensors:  # type: ignore[override]
        return HeadsGyroTachometers(episodes, self.spec)

    def context(self, episodes: WheelEpisodes, privileged: bool) -> Context:  # type: ignore[override]
        return public_context(episodes.n, episodes.fault if privileged else None)


def wheel_knowledge(plant: ReactionWheelPlant) -> WheelKnowledge:
    """The wheel constants a controller may know."""
    constants = WheelConstants.of(plant)
    return WheelKnowledge(
        spin_axes=np.array(plant.spin_axes),
        u_max_nm=plant.u_max_nm,
        omega_max_rad_s=constants.omega_max_rad_s,
        spin_inertia_kgm2=constants.js_kgm2,
        transverse_inertia_kgm2=constants.jt_kgm2,
        coulomb_nm=plant.coulomb_nm,
        viscous_nms=plant.viscous_nms,
        omega_linear_rad_s=plant.omega_linear_rad_s,
    )


def public_context(n: int, fault: WheelFault | None = None) -> Context:
    """The context of ``n`` ``scftc-v2`` episodes: ``dt``, the nominal inertia, the wheels'
    constants and the sensors' noise figures; the true fault only for a privileged controller."""
    plant = V2.plant
    assert isinstance(plant, ReactionWheelPlant) and V2.sensors is not None
    return Context(
        n=n,
        benchmark_version=V2.version,
        dt_s=plant.dt_s,
        obs_dim=V2.obs_dim,
        action_dim=V2.action_dim,
        inertia_nominal_kgm2=np.array(plant.inertia_nominal_kgm2),
        wheels=wheel_knowledge(plant),
        sensors=sensor_knowledge(V2.sensors, plant.dt_s),
        fault=fault,
    )


assert isinstance(V2.plant, ReactionWheelPlant)
CONSTANTS = WheelConstants.of(V2.plant)
TESTBED = ReactionWheelTestbed()
