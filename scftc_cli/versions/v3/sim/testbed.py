"""``scftc-v3``'s simulator: the plant in orbit on three backends, v2's sensors plus a magnetometer,
the mission's target and time left appended to the observation, three pointing windows, and the
diagnosis truth the health reports are scored against."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scftc_cli.protocol import Context, OrbitKnowledge, RodKnowledge
from scftc_cli.sim.testbed import DiagnosisTruth, Plant, Sensors, Testbed
from scftc_cli.versions.v2.sim.faults import sensor_code
from scftc_cli.versions.v2.sim.sensors import sensor_knowledge
from scftc_cli.versions.v2.sim.testbed import wheel_knowledge
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v3.sim.environment import EARTH_RADIUS_M
from scftc_cli.versions.v3.sim.faults import AgileEpisodes, pinned_episodes
from scftc_cli.versions.v3.sim.mission import PLANT, time_left_s, window_ends, window_of
from scftc_cli.versions.v3.sim.sensors import MAG_NONE, SensorEpisodes, V3Sensors
from scftc_cli.versions.v3.spec import HEAD_UNITS, ROD_UNITS, UNITS, V3, WHEEL_UNITS, AgileSensors

HEALTHY, DEGRADED, FAILED = 0, 1, 2


class MissionSensors(Sensors):
    """Observation ``(n, 26)``: v2's 19 values and the magnetometer (``V3Sensors``), then the
    current window's target MRP (3) and the time left in the window (1, s)."""

    def __init__(self, episodes: AgileEpisodes, suite: AgileSensors | None = None) -> None:
        suite = V3.sensors if suite is None else suite
        assert isinstance(suite, AgileSensors)
        self.inner = V3Sensors(
            SensorEpisodes(
                np.asarray(episodes.fault.onset_step),
                episodes.sensor_fault,
                episodes.magnetometer,
                np.asarray(episodes.noise_seed),
                np.asarray(episodes.outage_end_step),
            ),
            noise_t=suite.magnetometer_noise_t,
        )
        self.targets = np.asarray(episodes.targets)

    def observe(self, k: int, plant: Plant) -> np.ndarray:
        base = self.inner.observe(k, plant)
        n = base.shape[0]
        out = np.empty((n, base.shape[1] + 4))
        out[:, : base.shape[1]] = base
        out[:, base.shape[1] : base.shape[1] + 3] = self.targets[:, window_of(k)]
        out[:, -1] = time_left_s(k)
        return out


class AgileTestbed(Testbed):
    """``scftc-v3`` (docs/benchmark-v3.md): backends ``numpy`` (fused), ``reference``, ``basilisk``."""

    spec = V3
    plants = {
        "numpy": "scftc_cli.versions.v3.sim.mission:MissionFastPlant",
        "reference": "scftc_cli.versions.v3.sim.mission:MissionReferencePlant",
        "basilisk": "scftc_cli.versions.v3.sim.basilisk:MissionBasiliskPlant",
    }
    pinned = staticmethod(pinned_episodes)

    def sensors(self, episodes: AgileEpisodes) -> Sensors:  # type: ignore[override]
        return MissionSensors(episodes, self.spec.sensors)

    def windows(self) -> tuple[int, ...]:
        return window_ends()

    def diagnosis_truth(self, episodes: AgileEpisodes) -> DiagnosisTruth:  # type: ignore[override]
        return diagnosis_truth(episodes)

    def context(self, episodes: AgileEpisodes, privileged: bool) -> Context:  # type: ignore[override]
        return public_context(episodes, privileged, self.spec)


def diagnosis_truth(episodes: AgileEpisodes) -> DiagnosisTruth:
    """What a perfect detector reports from the onset on, per unit (``spec.UNITS``), read off the
    faults themselves (so a mixed batch works too):

    - a wheel: failed if its gain is 0 or negative (dead or reversed), or creeps to 0 before the
      episode's end (a creep with floor 0); degraded if its magnitude, offset or friction (constant, ramp
      end or bursts) is off nominal by more than the plant's ``health_*_tolerance`` (within it the
      wheel counts healthy), if its gain creeps but has not reached 0 at the end, or if it drops
      out during bursts (``burst_gain`` below 1: an intermittent unit);
    - a rod: failed if its gain is 0 or negative; degraded if it is off 1 (half dipole);
    - a head: failed if stuck, or in an outage (all three) that lasts to the end; degraded if
      biased, or in an outage that ends (an intermittent unit: what it did once it may do again);
    - the gyro: degraded by a bias step; the magnetometer: degraded by a bias or spikes.

    An episode whose faults leave every unit healthy (a ``nominal`` one, or a ``sign`` fault that
    reversed no wheel) has its onset at ``steps``: any alarm in it is false.
    """
    f = episodes.fault
    n = episodes.n
    codes = np.zeros((n, len(UNITS)), dtype=np.int64)
    gain = np.asarray(f.gain)
    has_bursts = np.any(np.asarray(f.burst_end_step) > np.asarray(f.burst_start_step), axis=1)[:, None]
    plant = PLANT
    friction = np.maximum(np.asarray(f.friction_multiplier), np.asarray(f.friction_ramp_end))
    friction = np.maximum(friction, np.where(has_bursts, np.asarray(f.burst_multiplier), 1.0))
    off = (
        (np.abs(np.abs(gain) - 1.0) > plant.health_gain_tolerance)
        | (np.abs(np.asarray(f.bias)) > plant.health_offset_tolerance)
        | (friction > plant.health_friction_tolerance)
    )
    creep = np.asarray(f.gain_creep_per_step)
    creeping = creep < 0.0
    zero_step = np.asarray(f.onset_step)[:, None] + 1.0 / np.where(creeping, -creep, 1.0)  # gain reaches 0
    crept_out = creeping & (np.asarray(f.gain_creep_floor) <= 0.0) & (zero_step <= plant.steps)
    off = off | creeping | (has_bursts & (np.asarray(f.burst_gain) < 1.0))
    wheels = slice(UNITS.index(WHEEL_UNITS[0]), UNITS.index(WHEEL_UNITS[-1]) + 1)
    codes[:, wheels] = np.where((gain <= 0.0) | crept_out, FAILED, np.where(off, DEGRADED, HEALTHY))
    rod = np.asarray(f.rod_gain)
    rods = slice(UNITS.index(ROD_UNITS[0]), UNITS.index(ROD_UNITS[-1]) + 1)
    codes[:, rods] = np.where(rod <= 0.0, FAILED, np.where(rod != 1.0, DEGRADED, HEALTHY))
    kind = np.asarray(episodes.sensor_fault.kind)
    head = np.asarray(episodes.sensor_fault.head)
    first_head = UNITS.index(HEAD_UNITS[0])
    rows = np.arange(n)
    for name, code in (("st_bias", DEGRADED), ("st_stuck", FAILED)):
        hit = kind == sensor_code(V2, name)
        codes[rows[hit], first_head + head[hit]] = code
    outage = kind == sensor_code(V2, "st_outage")
    lasting = np.asarray(episodes.outage_end_step) >= V3.steps
    codes[outage, first_head : first_head + len(HEAD_UNITS)] = np.where(lasting[outage], FAILED, DEGRADED)[
        :, None
    ]
    codes[kind == sensor_code(V2, "gyro_bias"), UNITS.index("gyro")] = DEGRADED
    codes[np.asarray(episodes.magnetometer.kind) != MAG_NONE, UNITS.index("magnetometer")] = DEGRADED
    onset = np.where(codes.any(axis=1), np.asarray(f.onset_step), V3.steps)
    return DiagnosisTruth(onset_step=onset, codes=codes)


@dataclass(frozen=True)
class TrueAgileFault:
    """What a privileged controller is handed: the episodes (faults, environment, mission) and the
    diagnosis truth."""

    episodes: AgileEpisodes
    truth: DiagnosisTruth


def public_context(episodes: AgileEpisodes, privileged: bool = False, spec=V3) -> Context:
    """The context of ``scftc-v3`` episodes (or of a version built on its mission, ``spec``): v2's
    (``dt``, nominal inertia, wheels, sensor noise), plus the magnetometer's noise, the rods, each
    episode's orbit altitude and inclination, and the health units; the true fault
    (``TrueAgileFault``) only for a privileged controller."""
    plant, suite = PLANT, spec.sensors
    assert isinstance(suite, AgileSensors)
    knowledge = sensor_knowledge(suite, plant.dt_s)
    env = episodes.environment
    return Context(
        n=episodes.n,
        benchmark_version=spec.version,
        dt_s=plant.dt_s,
        obs_dim=spec.obs_dim,
        action_dim=spec.action_dim,
        inertia_nominal_kgm2=np.array(plant.inertia_nominal_kgm2),
        wheels=wheel_knowledge(plant),
        sensors=type(knowledge)(**{**knowledge.__dict__, "magnetometer_noise_t": suite.magnetometer_noise_t}),
        rods=RodKnowledge(
            axes=np.eye(3),
            dipole_max_am2=plant.rod_dipole_max_am2,
            residual_dipole_nominal_am2=np.zeros(3),
        ),
        orbit=OrbitKnowledge(
            altitude_m=np.asarray(env.semi_major_axis_m) - EARTH_RADIUS_M,
            inclination_rad=np.asarray(env.inclination_rad),
        ),
        health_units=UNITS,
        fault=TrueAgileFault(episodes, diagnosis_truth(episodes)) if privileged else None,
    )


TESTBED = AgileTestbed()
