"""``scftc-v3``'s draws, mission and diagnosis truth: pinned and deterministic, held-out ranges
disjoint from the train ones, three windows with the target and time left in the observation,
the truth read off the faults, and the two plant backends equal to the bit in the closed loop."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from scftc_cli.sim import testbed as testbeds
from scftc_cli.versions.v3.controllers.analytic import PD
from scftc_cli.versions.v3.sim.faults import MAX_MISSION_DRAWS, feasible, pinned_episodes, sample_fault
from scftc_cli.versions.v3.sim.mission import MissionFastPlant, MissionReferencePlant, target_error
from scftc_cli.versions.v3.sim.testbed import diagnosis_truth
from scftc_cli.versions.v3.spec import UNITS, V3, AgileFaultClass

BED = testbeds.testbed("scftc-v3")
PLANT = V3.plant
TRAIN, TEST = V3.splits["train"], V3.splits["test"]


def _draw(split: str, cls: str, sensor: str | None = None, n_faults: int = 6, n_seeds: int = 2):
    return BED.draw(split, cls, sensor, n_faults=n_faults, n_seeds=n_seeds)


def _arrays(e) -> list[np.ndarray]:
    out = []

    def walk(v):
        if isinstance(v, np.ndarray):
            out.append(v)
        elif dataclasses.is_dataclass(v) and not isinstance(v, type):
            for f in dataclasses.fields(v):
                walk(getattr(v, f.name))

    walk(e)
    return out


def test_draws_are_pinned_sliceable_and_independent_of_the_cell_size():
    pinned_episodes.cache_clear()
    a = _draw("train", "intermittent", n_faults=4, n_seeds=3)
    pinned_episodes.cache_clear()
    b = _draw("train", "intermittent", n_faults=4, n_seeds=3)
    for x, y in zip(_arrays(a), _arrays(b), strict=True):
        np.testing.assert_array_equal(x, y)
    part = BED.draw("train", "intermittent", None, n_faults=4, n_seeds=3, start=5, stop=9)
    for x, y in zip(_arrays(a.subset(slice(5, 9))), _arrays(part), strict=True):
        np.testing.assert_array_equal(x, y)
    bigger = _draw("train", "intermittent", n_faults=8, n_seeds=3)
    np.testing.assert_array_equal(bigger.fault.gain[:12], a.fault.gain)
    np.testing.assert_array_equal(bigger.targets[:12], a.targets)
    sealed = BED.draw("train", "intermittent", None, n_faults=4, n_seeds=3, salt=b"round")
    assert not np.array_equal(sealed.sigma0, a.sigma0)


def test_held_out_ranges_are_disjoint_from_the_train_ones():
    for name in ("onset_s", "stored_momentum_nms", "residual_dipole_am2", "double_gain_magnitude",
                 "burst_multiplier", "burst_duration_s", "friction_ramp_end", "mag_bias_t",
                 "inertia_scale", "gain_magnitude", "friction_multiplier"):  # fmt: skip
        test_values = getattr(TEST, name).sample(np.random.default_rng(0), 2000)
        assert not np.any(getattr(TRAIN, name).contains(test_values)), name
    assert TRAIN.rod_fault != TEST.rod_fault and TRAIN.compound_sensor != TEST.compound_sensor
    assert not set(TRAIN.reversed_wheels) & set(TEST.reversed_wheels)


@pytest.mark.parametrize("split", ["train", "test"])
def test_drawn_episodes_lie_in_their_split(split):
    ranges = V3.splits[split]
    loss, double = _draw(split, "loss"), _draw(split, "double")
    env = loss.environment
    dipole = np.sqrt((np.asarray(env.residual_dipole_am2) ** 2).sum(axis=1))
    assert np.all(ranges.residual_dipole_am2.contains(dipole))
    onset_s = np.asarray(loss.fault.onset_step) * V3.dt_s
    assert np.all(ranges.onset_s.contains(onset_s) | ranges.onset_s.contains(onset_s - V3.dt_s))
    degraded = np.asarray(double.fault.gain)[
        (np.asarray(double.fault.gain) != 0) & (np.asarray(double.fault.gain) != 1)
    ]
    assert len(degraded) == double.n and np.all(ranges.double_gain_magnitude.contains(degraded))
    assert np.all((np.asarray(double.fault.gain) == 0).sum(axis=1) == 1)
    ramp = _draw(split, "incipient").fault.friction_ramp_end
    assert np.all(ranges.friction_ramp_end.contains(np.asarray(ramp).max(axis=1)))
    rod = _draw(split, "rod")
    rods = np.sort(np.asarray(rod.fault.rod_gain), axis=1)
    expected = [-1.0, 1.0, 1.0] if ranges.rod_fault == "reversed" else [0.0, 0.5, 1.0]
    assert np.all(rods == expected)
    assert np.all(np.sort(np.asarray(rod.fault.gain), axis=1) == [0.0, 1.0, 1.0, 1.0])  # and one dead wheel


def test_bursts_start_at_the_onset_and_stay_inside_the_episode():
    e = _draw("train", "intermittent")
    starts, ends = np.asarray(e.fault.burst_start_step), np.asarray(e.fault.burst_end_step)
    real = ends > starts
    assert np.all(starts[:, 0] == e.fault.onset_step) and np.all(real[:, 0])
    assert np.all(starts[real] >= np.repeat(e.fault.onset_step, real.sum(axis=1))) and ends.max() <= V3.steps
    assert np.all((np.asarray(e.fault.burst_multiplier) != 1.0).sum(axis=1) == 1)


def test_the_stored_momentum_is_the_drawn_size_and_dead_wheel_missions_are_feasible():
    from scftc_cli.versions.v2.sim.dynamics import MassProperties
    from scftc_cli.versions.v3.sim.dynamics import V2_WHEELS

    e = _draw("test", "loss", n_faults=8, n_seeds=2)
    total = MassProperties.of(V2_WHEELS, np.asarray(e.inertia_scale)).total_inertia_kgm2
    h = (
        np.einsum("nij,nj->ni", total, e.omega0_rad_s)
        + (V2_WHEELS.js_kgm2 * e.wheel_speed0_rad_s) @ V2_WHEELS.axes
    )
    size = np.sqrt((h * h).sum(axis=1))
    assert np.all(TEST.stored_momentum_nms.contains(np.round(size, 12)) | (np.abs(size - 1.9) < 1e-12))
    assert np.all(np.abs(e.wheel_speed0_rad_s) < V2_WHEELS.omega_max_rad_s)
    rng = np.random.default_rng(0)
    kind = V3.fault_class("loss")
    assert isinstance(kind, AgileFaultClass)
    for row in range(e.n):
        if e.mission_draws[row] < MAX_MISSION_DRAWS:
            fault = sample_fault(TEST, kind, PLANT, rng)
            fault = dataclasses.replace(
                fault, gain=np.asarray(e.fault.gain[row]), onset_step=int(e.fault.onset_step[row])
            )
            assert feasible(PLANT, fault, np.asarray(e.sigma0[row]), h[row], np.asarray(e.targets[row]))


def test_sensor_cells_pair_with_their_sign_cell_and_nominal_has_no_fault():
    sign, mag = _draw("test", "sign"), _draw("test", "sign", "mag_bias")
    for name in ("sigma0", "wheel_speed0_rad_s", "targets", "noise_seed"):
        np.testing.assert_array_equal(getattr(sign, name), getattr(mag, name))
    np.testing.assert_array_equal(sign.fault.gain, mag.fault.gain)
    size = np.sqrt((np.asarray(mag.magnetometer.bias_t) ** 2).sum(axis=1))
    assert np.all(TEST.mag_bias_t.contains(size))
    nominal = _draw("test", "nominal")
    assert np.all(nominal.fault.onset_step == V3.steps) and np.all(nominal.fault.gain == 1.0)


def test_the_targets_are_slews_within_range_and_the_first_is_the_origin():
    e = _draw("train", "nominal")
    targets = np.asarray(e.targets)
    assert targets.shape == (e.n, PLANT.windows, 3) and np.all(targets[:, 0] == 0.0)
    for w in range(1, PLANT.windows):
        error = target_error(targets[:, w], targets[:, w - 1])
        angle = np.degrees(4.0 * np.arctan(np.sqrt((error * error).sum(axis=1))))
        assert np.all((angle >= 20.0 - 1e-9) & (angle <= 120.0 + 1e-9))


def test_three_windows_and_the_observation_carries_the_target_and_the_time_left():
    assert BED.windows() == (800, 1600, 2400) and V3.obs_dim == 26 and V3.action_dim == 7
    e = _draw("train", "nominal", n_faults=1, n_seeds=2)
    plant, sensors = BED.plant(e), BED.sensors(e)
    for k in range(3):
        obs = sensors.observe(k, plant)
        plant.step(k, np.zeros((e.n, 7)))
    np.testing.assert_array_equal(obs[:, 22:25], e.targets[:, 0])
    assert obs[0, 25] == (800 - 2) * V3.dt_s
    from scftc_cli.versions.v3.sim.testbed import MissionSensors

    assert isinstance(sensors, MissionSensors)
    np.testing.assert_array_equal(sensors.targets[:, 1], e.targets[:, 1])


@pytest.mark.parametrize("split", ["train", "test"])
def test_an_outage_blanks_every_head_for_its_drawn_duration_then_they_report_again(split):
    ranges = V3.splits[split]
    sign, outage = (
        _draw(split, "sign", n_faults=10, n_seeds=1),
        _draw(split, "sign", "st_outage", n_faults=10, n_seeds=1),
    )
    onset, end = np.asarray(outage.fault.onset_step), np.asarray(outage.outage_end_step)
    duration_s = (end - onset) * V3.dt_s
    assert np.all(
        ranges.outage_duration_s.contains(duration_s)
        | ranges.outage_duration_s.contains(duration_s - V3.dt_s)
    )
    assert np.all(np.asarray(sign.outage_end_step) == 0)  # no outage, nothing drawn
    # the same episodes with and without the outage: equal outside it, blank heads inside
    first = int(onset.min())
    rows = np.flatnonzero(onset == first)
    sub_sign, sub_out = sign.subset(rows), outage.subset(rows)
    last = int(min(end[rows].max() + 3, V3.steps))
    plant_a, plant_b = BED.plant(sub_sign), BED.plant(sub_out)
    sens_a, sens_b = BED.sensors(sub_sign), BED.sensors(sub_out)
    command = np.zeros((len(rows), 7))
    stop = end[rows]
    for k in range(last):
        a, b = sens_a.observe(k, plant_a), sens_b.observe(k, plant_b)
        out = (k >= first) & (k < stop)
        np.testing.assert_array_equal(b[~out], a[~out])
        assert np.all(b[out, :12] == 0.0)
        np.testing.assert_array_equal(b[out, 12:], a[out, 12:])
        plant_a.step(k, command)
        plant_b.step(k, command)


CODES = {  # class -> the set of unit codes a faulted episode may have (beside healthy units)
    "loss": {"wheel": {1, 2}},  # the dead wheel; the others keep their drawn magnitudes
    "double": {"wheel": {1, 2}},
    "intermittent": {"wheel": {1}},
    "incipient": {"wheel": {1}},
    "rod": {"rod": {2}, "wheel": {2}},  # a rod fault and a dead wheel
}


@pytest.mark.parametrize("split", ["train", "test"])
def test_the_diagnosis_truth_is_read_off_the_faults(split):
    assert len(UNITS) == 12 and V3.diagnosis is not None and V3.diagnosis.units == UNITS
    for cls, expected in CODES.items():
        truth = diagnosis_truth(_draw(split, cls))
        touched = []
        for kind, codes in expected.items():
            columns = [i for i, u in enumerate(UNITS) if u.startswith(kind)]
            touched += columns
            faulted = truth.codes[:, columns]
            assert set(np.unique(faulted[faulted > 0])) <= codes | (
                {1} if split == "test" and kind == "rod" else set()
            )
            assert np.all(faulted.max(axis=1) > 0), cls
        others = np.delete(truth.codes, touched, axis=1)
        assert np.all(others == 0), cls
    nominal = diagnosis_truth(_draw(split, "nominal"))
    assert np.all(nominal.codes == 0) and np.all(nominal.onset_step == V3.steps)
    outages = _draw(split, "sign", "st_outage", n_faults=20)
    outage = diagnosis_truth(outages)
    heads = [UNITS.index(h) for h in ("head_1", "head_2", "head_3")]
    lasting = np.asarray(outages.outage_end_step) >= V3.steps  # failed to the end, else intermittent
    np.testing.assert_array_equal(outage.codes[:, heads], np.where(lasting, 2, 1)[:, None] * np.ones(3))
    spikes = diagnosis_truth(_draw(split, "sign", "mag_spike"))
    assert np.all(spikes.codes[:, UNITS.index("magnetometer")] == 1)
    compound = diagnosis_truth(_draw(split, "compound"))
    sensor_unit = "gyro" if split == "test" else None
    if sensor_unit:
        assert np.all(compound.codes[:, UNITS.index("gyro")] == 1)
    else:
        assert np.all(compound.codes[:, heads].max(axis=1) == 1)


def test_fused_and_reference_plants_agree_to_the_bit_in_the_closed_loop_across_a_window_change():
    e = _draw("train", "intermittent", n_faults=2, n_seeds=1)
    fast, reference = MissionFastPlant.of(e), MissionReferencePlant.of(e)
    controller = PD()
    controller.reset(e.n, BED.context(e, False))
    sensors = BED.sensors(e)
    for k in range(805):
        command = controller.act(sensors.observe(k, reference))
        np.testing.assert_array_equal(fast.step(k, command), reference.step(k, command), err_msg=f"step {k}")
    for name in ("sigma", "omega_rad_s", "wheel_speed_rad_s", "field_b_t"):
        np.testing.assert_array_equal(fast.states()[name], reference.states()[name])


def test_the_context_tells_the_rods_the_orbit_and_the_units_and_crosses_the_wire():
    from scftc_cli.protocol import Context

    e = _draw("test", "rod", n_faults=2, n_seeds=1)
    context = BED.context(e, False)
    assert context.fault is None and context.rods is not None and context.orbit is not None
    assert context.health_units == UNITS and context.rods.dipole_max_am2 == PLANT.rod_dipole_max_am2
    assert np.all((context.orbit.altitude_m > 499e3) & (context.orbit.altitude_m < 701e3))
    back = Context.from_public(context.public())
    np.testing.assert_array_equal(back.rods.axes, context.rods.axes)
    np.testing.assert_array_equal(back.orbit.inclination_rad, context.orbit.inclination_rad)
    assert back.sensors.magnetometer_noise_t == V3.sensors.magnetometer_noise_t
    assert BED.context(e, True).fault.truth.codes.shape == (2, 12)
