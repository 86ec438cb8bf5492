"""``scftc-v3``'s draws: the only code that draws its faults, missions, orbits and noise seeds.

A cell's episode ``e = i n_seeds + j`` pairs fault ``i`` with seed ``j``. Every random number comes
from a ``SeedSequence`` keyed by the version, the split, the class and the index
(``sim/episodes.py``), one stream per purpose, so no draw moves another:

| stream key | index | draws |
|---|---|---|
| ``(split, class)`` | ``(0, i)`` | the fault (``sample_fault``) |
| ``(split, class)`` | ``(1, i, j)`` | initial attitude, rate, wheel-speed spread |
| ``(split, class)`` | ``(2, i, j)`` | the orbit and environment (``sample_environment``) |
| ``(split, class)`` | ``(3, i, j)`` | stored momentum, slews (``sample_mission``); redrawn until feasible |
| ``(split, class, "sensor", name)`` | ``(i, j)`` | a sensor fault (a sensor cell's or a ``compound``'s) |
| ``(split, class, "noise")`` | ``(i, j)`` | the entropy of the episode's sensor-noise streams |

Sensor cells sit on the split's ``sign`` faults and use the ``sign`` cell's keys (faults, initial
states, missions, orbits, noise), so the two cells pair episode by episode, as in v2. A sealed draw
mixes a ``salt`` into every key. The order of the draws below is part of the benchmark.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from scftc_cli.sim.elementary import tangent
from scftc_cli.sim.episodes import Episodes, generator, seed_sequence, unit_norm
from scftc_cli.sim.mrp import compose, to_dcm
from scftc_cli.sim.products import matmul
from scftc_cli.versions.v2.sim.dynamics import RPM_TO_RAD_S, MassProperties
from scftc_cli.versions.v2.sim.faults import SensorFault, onset_step, sample_sensor_fault
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v3.sim.dynamics import N_RODS, V2_WHEELS, PlantFault
from scftc_cli.versions.v3.sim.environment import EARTH_RADIUS_M, Environment
from scftc_cli.versions.v3.sim.sensors import MAG_BIAS, MAG_SPIKE, MagnetometerFault
from scftc_cli.versions.v3.spec import V3, AgileFaultClass, AgilePlant, AgileSensors, AgileSplit

V2_SENSOR_FAULTS = V2.sensor_faults
"""The sensor faults v2's sensor code knows (their codes are v2's); v3 adds the magnetometer's."""
MAX_MISSION_DRAWS = 100
"""A dead-wheel episode whose mission is still infeasible after this many draws keeps the last."""


@dataclass(frozen=True)
class AgileEpisodes(Episodes):
    """Everything that defines a batch of ``scftc-v3`` episodes; held by the simulator, never by a
    deployable controller.

    Attributes:
        fault: the actuator faults, wheels and rods (``onset_step`` ``(n,)``: the first faulted
            step; ``steps`` for a ``nominal`` episode).
        inertia_scale: ``(n,)`` hub inertia scale ``f`` (a mass property, from step 0).
        environment: the orbit, field epoch, residual dipole, Sun and facet of each episode.
        sigma0, omega0_rad_s: ``(n, 3)`` initial true attitude (MRP, inertial) and body rate.
        wheel_speed0_rad_s: ``(n, 4)`` initial wheel speeds.
        targets: ``(n, windows, 3)`` each window's target attitude (inertial MRP); the first is 0.
        sensor_fault: v2's star-tracker and gyro faults (kinds coded as v2's ``sensor_code``).
        magnetometer: the magnetometer's fault.
        outage_end_step: ``(n,)`` the first step at which an ``st_outage``'s heads are back (0 where
            the episode has no outage; past ``steps`` where it lasts to the end).
        noise_seed: ``(n, 4)`` ``uint32``: the entropy of each episode's sensor-noise streams.
        mission_draws: ``(n,)`` how many missions were drawn until a feasible one (1 almost always).
    """

    fault: PlantFault
    inertia_scale: np.ndarray
    environment: Environment
    sigma0: np.ndarray
    omega0_rad_s: np.ndarray
    wheel_speed0_rad_s: np.ndarray
    targets: np.ndarray
    sensor_fault: SensorFault
    magnetometer: MagnetometerFault
    outage_end_step: np.ndarray
    noise_seed: np.ndarray
    mission_draws: np.ndarray


@dataclass(frozen=True)
class DrawnFault:
    """One episode's actuator fault as drawn (``sample_fault``): per wheel ``(4,)`` arrays, per rod
    ``(3,)``, bursts as ``[start, end)`` step pairs."""

    gain: np.ndarray
    bias: np.ndarray
    friction_multiplier: np.ndarray
    friction_ramp_end: np.ndarray
    burst_multiplier: np.ndarray
    bursts: tuple[tuple[int, int], ...]
    rod_gain: np.ndarray
    inertia_scale: float
    onset_step: int
    gain_creep_per_step: np.ndarray | None = None
    gain_creep_floor: np.ndarray | None = None
    burst_gain: np.ndarray | None = None

    @property
    def dead_wheels(self) -> tuple[int, ...]:
        return tuple(int(w) for w in np.flatnonzero(self.gain == 0.0))


def unit_vector(rng: np.random.Generator) -> np.ndarray:
    """A uniform random unit vector ``(3,)``."""
    v = rng.standard_normal(3)
    return v / unit_norm(v)


def rotation_mrp(axis: np.ndarray, angle_deg: float) -> np.ndarray:
    """MRP ``tan(angle/4) axis`` ``(3,)`` of a rotation about unit ``axis`` (``elementary.tangent``
    of the angle in radians, ``angle_deg * (pi / 180)``, over four)."""
    return float(tangent(angle_deg * (math.pi / 180.0) / 4.0)) * axis


def sample_fault(
    split: AgileSplit, kind: AgileFaultClass, plant: AgilePlant, rng: np.random.Generator
) -> DrawnFault:
    """Draw one fault of class ``kind``.

    The order of the draws is part of the benchmark: ``f``, ``t_f``; with ``reversals`` the number of
    reversed wheels and which; magnitudes (``magnitude``); offsets (``bias``); the friction wheel and
    its multiplier (``friction``); the dead wheel (``dead``); for ``double`` the dead wheel, the
    degraded one among the others, its magnitude; for ``intermittent`` the wheel, the factor, then
    the bursts (a duration, then the gap to the next start, until the episode's end); for
    ``incipient`` the wheel and the ramp's end; for ``rod`` the rod (reversed) or the dead rod and
    the half one among the others. A ``nominal`` fault is healthy with its onset past the end.
    """
    m, dt, steps = plant.n_wheels, plant.dt_s, plant.steps
    f = float(split.inertia_scale.sample(rng, 1)[0])
    t_f = float(split.onset_s.sample(rng, 1)[0])
    onset = steps if kind.healthy else int(onset_step(np.array([t_f]), dt)[0])
    sign = np.ones(m)
    if kind.reversals:
        n_reversed = int(rng.choice(split.reversed_wheels))
        sign[rng.choice(m, size=n_reversed, replace=False)] = -1.0
    gain = sign * split.gain_magnitude.sample(rng, m) if kind.magnitude else sign
    bias = split.bias.sample(rng, m) if kind.bias else np.zeros(m)
    friction, ramp, burst = np.ones(m), np.ones(m), np.ones(m)
    bursts: list[tuple[int, int]] = []
    rods = np.ones(N_RODS)
    if kind.friction:
        wheel = int(rng.integers(m))
        friction[wheel] = float(split.friction_multiplier.sample(rng, 1)[0])
    if kind.dead:
        gain[rng.integers(m)] = 0.0
    if kind.double:
        dead = int(rng.integers(m))
        degraded = (dead + 1 + int(rng.integers(m - 1))) % m
        gain[dead] = 0.0
        gain[degraded] = float(split.double_gain_magnitude.sample(rng, 1)[0])
    if kind.intermittent:
        wheel = int(rng.integers(m))
        burst[wheel] = float(split.burst_multiplier.sample(rng, 1)[0])
        start_s = t_f
        while start_s < steps * dt:
            duration = float(split.burst_duration_s.sample(rng, 1)[0])
            start, end = onset_step(np.array([start_s, start_s + duration]), dt)
            if len(bursts) < plant.max_bursts:
                bursts.append((int(start), int(min(end, steps))))
            start_s += float(rng.exponential(split.burst_interval_s))
    if kind.incipient:
        wheel = int(rng.integers(m))
        ramp[wheel] = float(split.friction_ramp_end.sample(rng, 1)[0])
    if kind.rod:
        if split.rod_fault == "reversed":
            rods[rng.integers(N_RODS)] = -1.0
        else:
            dead = int(rng.integers(N_RODS))
            rods[dead] = 0.0
            rods[(dead + 1 + int(rng.integers(N_RODS - 1))) % N_RODS] = 0.5
    return DrawnFault(gain, bias, friction, ramp, burst, tuple(bursts), rods, f, onset)


def sample_initial_state(
    plant: AgilePlant, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(sigma0 (3,), omega0 (3,) rad/s, spread (4,) rad/s)``: v2's attitude, rate and per-wheel
    speed draws; the speeds' part along the wheels' null space (``(1, 1, 1, 1) / 2`` for the
    tetrahedral axes) is kept as a spread that stores no momentum."""
    sigma0 = rng.uniform(-plant.sigma0_half_width, plant.sigma0_half_width, 3)
    omega0 = rng.uniform(-plant.omega0_half_width_rad_s, plant.omega0_half_width_rad_s, 3)
    half = plant.wheel_speed0_half_width_rpm * RPM_TO_RAD_S
    speeds = rng.uniform(-half, half, plant.n_wheels)
    null = null_vector(plant)
    along = speeds[0] * null[0] + speeds[1] * null[1] + speeds[2] * null[2] + speeds[3] * null[3]
    return sigma0, omega0, along * null


def null_vector(plant: AgilePlant) -> np.ndarray:
    """The unit vector ``(4,)`` of wheel speeds that put no momentum on the hub (``G' n = 0``):
    ``(1, 1, 1, 1) / 2`` for the tetrahedral axes (checked)."""
    null = np.full(plant.n_wheels, 0.5)
    if np.max(np.abs(matmul(np.array(plant.spin_axes).T, null))) > 1e-12:
        raise ValueError("the wheels' spin axes are not tetrahedral")
    return null


def sample_environment(split: AgileSplit, plant: AgilePlant, rng: np.random.Generator) -> dict:
    """One episode's orbit and environment, in order: altitude, inclination, node, argument of
    latitude, Earth angle; the residual dipole's size and direction; the Sun's direction; the
    facet's normal; its centre of pressure's distance and direction."""
    altitude = float(plant.altitude_km.sample(rng, 1)[0]) * 1e3
    inclination = math.radians(float(plant.inclination_deg.sample(rng, 1)[0]))
    raan, u0, theta = (float(rng.uniform(0.0, 2.0 * math.pi)) for _ in range(3))
    residual = float(split.residual_dipole_am2.sample(rng, 1)[0]) * unit_vector(rng)
    sun, normal = unit_vector(rng), unit_vector(rng)
    cop = float(plant.facet_cop_m.sample(rng, 1)[0]) * unit_vector(rng)
    return {
        "semi_major_axis_m": EARTH_RADIUS_M + altitude,
        "inclination_rad": inclination,
        "raan_rad": raan,
        "arg_latitude0_rad": u0,
        "earth_angle_rad": theta,
        "residual_dipole_am2": residual,
        "sun_direction": sun,
        "facet_area_m2": plant.facet_area_m2,
        "facet_normal": normal,
        "facet_cop_m": cop,
    }


def sample_mission(split: AgileSplit, plant: AgilePlant, rng: np.random.Generator) -> tuple:
    """``(stored momentum (3,) N m s body frame at the start, targets (windows, 3) MRP)``: the
    momentum's size and direction, then each later target's slew axis and angle from the previous."""
    h = float(split.stored_momentum_nms.sample(rng, 1)[0]) * unit_vector(rng)
    targets = np.zeros((plant.windows, 3))
    for w in range(1, plant.windows):
        axis = unit_vector(rng)
        slew = rotation_mrp(axis, float(plant.slew_deg.sample(rng, 1)[0]))
        targets[w] = compose(targets[w - 1 : w], slew[None])[0]
    return h, targets


def dcm(sigma: np.ndarray) -> np.ndarray:
    """``C(sigma)`` ``(3, 3)``: inertial components to body components (``sim/mrp.to_dcm``)."""
    return to_dcm(np.asarray(sigma, dtype=np.float64)[None])[0]


def three_wheel_load(plant: AgilePlant, dead: int, momentum_b: np.ndarray) -> float:
    """The largest fraction of ``h_max`` the three wheels other than ``dead`` must hold to store
    ``momentum_b`` ``(3,)`` N m s between them (the unique split along their three axes): the
    adjugate inverse of the three axes (``adjugate_inverse``) times the momentum, each entry a
    ``products`` multiply-add chain."""
    working = np.delete(np.array(plant.spin_axes), dead, axis=0).T
    per_wheel = matmul(adjugate_inverse(working), np.asarray(momentum_b, dtype=np.float64))
    return float(np.max(np.abs(per_wheel))) / plant.h_max_nms


def adjugate_inverse(m: np.ndarray) -> np.ndarray:
    """The inverse ``(3, 3)`` of one 3x3 matrix in Python floats (IEEE float64), in
    ``sim/scalars.inverse3``'s order: the cofactors ``e i - f h, ...``, ``det = (a c00 + b c10) +
    c c20``, each entry a cofactor over ``det``. Plain Python, so that drawing an episode compiles
    nothing."""
    (a, b, c), (d, e, f), (g, h, i) = np.asarray(m, dtype=np.float64).tolist()
    cofactors = (
        (e * i - f * h, c * h - b * i, b * f - c * e),
        (f * g - d * i, a * i - c * g, c * d - a * f),
        (d * h - e * g, b * g - a * h, a * e - b * d),
    )
    det = (a * cofactors[0][0] + b * cofactors[1][0]) + c * cofactors[2][0]
    return np.array([[x / det for x in row] for row in cofactors])


def feasible(plant: AgilePlant, fault: DrawnFault, sigma0: np.ndarray, h_b: np.ndarray, targets) -> bool:
    """Whether the working wheels can hold the stored momentum at every target from the onset's
    window on: the system momentum ``H_N = C(sigma0)' h`` seen at each target, less the rods'
    ``unload_allowance_nms``, split among the three wheels other than each dead one (the dead wheel
    counted as fully spun down, its momentum handed to the others), must stay within
    ``feasibility_margin`` of ``h_max``. Faults without a dead wheel always pass."""
    if not fault.dead_wheels:
        return True
    h_n = matmul(dcm(sigma0).T, h_b)
    size = math.sqrt(float(matmul(h_n, h_n)))
    scale = max(size - plant.unload_allowance_nms, 0.0) / size if size > 0.0 else 0.0
    first = min(fault.onset_step // plant.window_steps, plant.windows - 1)
    for target in targets[first:]:
        load = scale * matmul(dcm(target), h_n)
        for dead in fault.dead_wheels:
            if three_wheel_load(plant, dead, load) > plant.feasibility_margin:
                return False
    return True


def wheel_speeds(
    plant: AgilePlant, inertia_scale: float, omega0: np.ndarray, h_b: np.ndarray, spread: np.ndarray
) -> np.ndarray:
    """Initial wheel speeds ``(4,)`` rad/s whose system momentum (hub ``I_tot omega0`` plus wheels)
    is ``h_b`` ``(3,)``: the minimum-norm speeds for ``h_b - I_tot omega0`` (``G G' = 4/3 I`` for
    the tetrahedral axes, so ``Omega = (3/4) G (h_b - I_tot omega0) / Js``), plus ``spread``.
    Every sum is written out (no BLAS): a draw must give the same bits on every CPU."""
    total = MassProperties.of(V2_WHEELS, np.array([inertia_scale])).total_inertia_kgm2[0]
    rest = [
        h_b[r] - ((total[r, 0] * omega0[0] + total[r, 1] * omega0[1]) + total[r, 2] * omega0[2])
        for r in range(3)
    ]
    out = np.empty(plant.n_wheels)
    for i, g in enumerate(plant.spin_axes):
        along = (g[0] * rest[0] + g[1] * rest[1]) + g[2] * rest[2]
        out[i] = 0.75 * along / V2_WHEELS.js_kgm2 + spread[i]
    return out


def sample_sensor(
    split: AgileSplit, sensors: AgileSensors, name: str | None, rng: np.random.Generator | None
) -> tuple[int, int, np.ndarray, np.ndarray, int, np.ndarray, np.ndarray, float]:
    """One episode's sensor fault: ``(v2 kind, head, head bias MRP, gyro step, magnetometer kind,
    magnetometer bias (3,) T, spike probability (3,), outage duration s)``. v2's faults as v2 draws
    them, then, for ``st_outage``, its duration; ``mag_bias``: the size, then the direction;
    ``mag_spike`` draws nothing (its spikes come from the noise)."""
    none = (0, 0, np.zeros(3), np.zeros(3), 0, np.zeros(3), np.zeros(3), 0.0)
    if name is None or rng is None:
        return none
    if name in V2_SENSOR_FAULTS:
        head, bias, step = sample_sensor_fault(split, name, sensors.star_tracker_heads, rng)
        outage = float(split.outage_duration_s.sample(rng, 1)[0]) if name == "st_outage" else 0.0
        return (1 + V2_SENSOR_FAULTS.index(name), head, bias, step, 0, np.zeros(3), np.zeros(3), outage)
    if name == "mag_bias":
        size = float(split.mag_bias_t.sample(rng, 1)[0])
        return (0, 0, np.zeros(3), np.zeros(3), MAG_BIAS, size * unit_vector(rng), np.zeros(3), 0.0)
    if name == "mag_spike":
        p = np.full(3, sensors.mag_spike_probability)
        return (0, 0, np.zeros(3), np.zeros(3), MAG_SPIKE, np.zeros(3), p, 0.0)
    raise ValueError(f"unknown sensor fault {name}")


@functools.lru_cache(maxsize=64)
def pinned_episodes(
    split: str,
    fault_class: str,
    sensor: str | None,
    n_faults: int,
    n_seeds: int,
    salt: bytes,
    start: int,
    stop: int,
) -> AgileEpisodes:
    """Episodes ``start..stop-1`` of the pinned (or, with ``salt``, sealed) cell, fault-major, drawn
    without drawing the others (equal to that slice of the whole cell). Cached; read-only."""
    return draw_cell(V3, sample_fault, split, fault_class, sensor, n_seeds, salt, start, stop)


def draw_cell(
    spec,
    sample,
    split: str,
    fault_class: str,
    sensor: str | None,
    n_seeds: int,
    salt: bytes,
    start: int,
    stop: int,
) -> AgileEpisodes:
    """Episodes ``start..stop-1`` of a cell of ``spec`` (v3 or a version built on its mission), the
    faults drawn by ``sample(split ranges, class, plant, rng) -> DrawnFault`` and everything else as
    the table above says; a class's split ranges are ``class_ranges(spec, split, class)``."""
    plant, sensors = spec.plant, spec.sensors
    assert isinstance(plant, AgilePlant) and isinstance(sensors, AgileSensors)
    key = (split, fault_class)
    kind = spec.fault_class(fault_class)
    assert isinstance(kind, AgileFaultClass)
    ranges = class_ranges(spec, split, kind)
    companion = sensor if sensor is not None else (ranges.compound_sensor if kind.compound else None)
    first, last = start // n_seeds, (stop - 1) // n_seeds
    faults = {
        i: sample(ranges, kind, plant, generator(spec.version, *key, index=(0, i), salt=salt))
        for i in range(first, last + 1)
    }
    rows = []
    for e in range(start, stop):
        i, j = divmod(e, n_seeds)
        fault = faults[i]
        sigma0, omega0, spread = sample_initial_state(
            plant, generator(spec.version, *key, index=(1, i, j), salt=salt)
        )
        env = sample_environment(ranges, plant, generator(spec.version, *key, index=(2, i, j), salt=salt))
        rng = generator(spec.version, *key, index=(3, i, j), salt=salt)
        draws = 0
        while True:
            h_b, targets = sample_mission(ranges, plant, rng)
            draws += 1
            if draws == MAX_MISSION_DRAWS or feasible(plant, fault, sigma0, h_b, targets):
                break
        speeds = wheel_speeds(plant, fault.inertia_scale, omega0, h_b, spread)
        sensor_rng = (
            generator(spec.version, *key, "sensor", companion, index=(i, j), salt=salt)
            if companion is not None
            else None
        )
        drawn = sample_sensor(ranges, sensors, companion, sensor_rng)
        noise = seed_sequence(spec.version, *key, "noise", index=(i, j), salt=salt).generate_state(
            4, np.uint32
        )
        rows.append((i, j, fault, sigma0, omega0, speeds, env, targets, drawn, noise, draws))
    return assemble(spec.version, split, fault_class, sensor, rows, plant, sensors.mag_spike_amount)


def class_ranges(spec, split: str, kind: AgileFaultClass) -> AgileSplit:
    """The ranges class ``kind`` draws from on ``split``: the split's own, unless the split says
    otherwise for that class (``AgileSplit.for_class``; v3's never do)."""
    ranges = spec.splits[split]
    assert isinstance(ranges, AgileSplit)
    return ranges.for_class(kind.name)


def assemble(
    version: str,
    split: str,
    fault_class: str,
    sensor: str | None,
    rows: list,
    plant: AgilePlant,
    spike_amount: float,
) -> AgileEpisodes:
    """Stack per-episode draws (``pinned_episodes``' rows: fault and seed index, ``DrawnFault``,
    ``sigma0``, ``omega0``, wheel speeds, environment dict, targets, sensor draw, noise seed, mission
    draws) into an ``AgileEpisodes`` batch of ``len(rows)`` episodes (read-only)."""
    n, width = len(rows), plant.max_bursts
    faults = [r[2] for r in rows]
    starts = np.zeros((n, width), dtype=np.int64)
    ends = np.zeros((n, width), dtype=np.int64)
    for row, f in enumerate(faults):
        for b, (s, t) in enumerate(f.bursts):
            starts[row, b], ends[row, b] = s, t
    stack = lambda name: np.array([getattr(f, name) for f in faults])  # noqa: E731
    onset = np.array([f.onset_step for f in faults], dtype=np.int64)
    envs = [r[6] for r in rows]
    drawn = [r[8] for r in rows]
    part = lambda k: np.array([d[k] for d in drawn])  # noqa: E731
    return AgileEpisodes(
        benchmark=version,
        split=split,
        fault_class=fault_class,
        sensor=sensor,
        fault_index=np.array([r[0] for r in rows], dtype=np.int64),
        seed_index=np.array([r[1] for r in rows], dtype=np.int64),
        fault=PlantFault(
            gain=stack("gain"),
            bias=stack("bias"),
            friction_multiplier=stack("friction_multiplier"),
            friction_ramp_end=stack("friction_ramp_end"),
            burst_multiplier=stack("burst_multiplier"),
            burst_start_step=starts,
            burst_end_step=ends,
            rod_gain=stack("rod_gain"),
            onset_step=onset,
            gain_creep_per_step=np.array(
                [
                    np.zeros(plant.n_wheels) if f.gain_creep_per_step is None else f.gain_creep_per_step
                    for f in faults
                ]
            ),
            gain_creep_floor=np.array(
                [
                    np.zeros(plant.n_wheels) if f.gain_creep_floor is None else f.gain_creep_floor
                    for f in faults
                ]
            ),
            burst_gain=np.array(
                [np.ones(plant.n_wheels) if f.burst_gain is None else f.burst_gain for f in faults]
            ),
        ),
        inertia_scale=stack("inertia_scale").astype(np.float64),
        environment=Environment(**{k: np.array([e[k] for e in envs]) for k in envs[0]}),
        sigma0=np.array([r[3] for r in rows]),
        omega0_rad_s=np.array([r[4] for r in rows]),
        wheel_speed0_rad_s=np.array([r[5] for r in rows]),
        targets=np.array([r[7] for r in rows]),
        sensor_fault=SensorFault(
            part(0).astype(np.int64), part(1).astype(np.int64), part(2).reshape(n, 3), part(3).reshape(n, 3)
        ),
        magnetometer=MagnetometerFault(
            kind=part(4).astype(np.int64),
            bias_t=part(5).reshape(n, 3),
            spike_probability=part(6).reshape(n, 3),
            spike_amount=np.full((n, 3), spike_amount),
        ),
        outage_end_step=np.where(
            part(7) > 0.0, onset + onset_step(part(7).astype(np.float64), plant.dt_s), 0
        ).astype(np.int64),
        noise_seed=np.array([r[9] for r in rows], dtype=np.uint32),
        mission_draws=np.array([r[10] for r in rows], dtype=np.int64),
    ).readonly()
