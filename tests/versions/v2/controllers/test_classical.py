"""The ``scftc-v2`` classical ports that are tuned and registered: ``pid``, ``classical_adaptive``,
``icl_adaptive``, ``nussbaum``, ``rls_dob``
(``fdir`` has its own tests)."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import yaml

from scftc_cli.baselines.checker import check_controller
from scftc_cli.protocol import Progress
from scftc_cli.registry import controller_spec
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed as bed_for
from scftc_cli.training import TrainRequest, get_trainer, tuning
from scftc_cli.versions.v1.training import tuning as v1_tuning
from scftc_cli.versions.v2 import VERSION
from scftc_cli.versions.v2.controllers import estimators, law
from scftc_cli.versions.v2.controllers.adaptive import AdaptiveParams, ClassicalAdaptive
from scftc_cli.versions.v2.controllers.estimators import (
    ChangeDetector,
    WheelSample,
    informative,
    mean_coulomb_shape,
    null_direction,
)
from scftc_cli.versions.v2.controllers.icl import ICLAdaptive, ICLParams, _eig_extremes
from scftc_cli.versions.v2.controllers.nussbaum import Nussbaum, NussbaumParams
from scftc_cli.versions.v2.controllers.pid import PID, PIDParams
from scftc_cli.versions.v2.controllers.rls import RLSDob, RLSParams
from scftc_cli.versions.v2.sim.faults import WheelEpisodes, WheelFault
from scftc_cli.versions.v2.sim.testbed import TESTBED, public_context
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v2.training import tuning as v2_tuning

BED = bed_for("scftc-v2")
NAMES = ("pid", "classical_adaptive", "icl_adaptive", "nussbaum", "rls_dob")
DEFAULTS = {
    "pid": lambda: PID(PIDParams()),
    "classical_adaptive": lambda: ClassicalAdaptive(AdaptiveParams()),
    "icl_adaptive": lambda: ICLAdaptive(ICLParams(gamma_inst=1.0, offset_ratio=0.1, friction_ratio=0.1)),
    "nussbaum": lambda: Nussbaum(NussbaumParams()),
    "rls_dob": lambda: RLSDob(RLSParams()),
}


def with_fault(episodes: WheelEpisodes, **changes: np.ndarray) -> WheelEpisodes:
    """``episodes`` with fields of their fault replaced (every row alike where a 1-D row is given)."""
    fault = episodes.fault
    rows = {
        k: np.broadcast_to(np.asarray(v, float), getattr(fault, k).shape).copy() for k, v in changes.items()
    }
    if "onset_step" in rows:
        rows["onset_step"] = rows["onset_step"].astype(np.int64)
    return dataclasses.replace(episodes, fault=dataclasses.replace(fault, **rows))


class _Trace(Progress):
    def __init__(self, controller, attribute) -> None:
        self.controller, self.attribute, self.history = controller, attribute, []

    def advance(self, amount: float = 1.0) -> None:
        self.history.append(np.copy(self.attribute(self.controller)))


def trace(controller, episodes, attribute):
    """Fly ``episodes``; ``attribute(controller)`` after every step, ``(steps, ...)``."""
    recorder = _Trace(controller, attribute)
    result = rollout(controller, episodes, progress=recorder)
    return result, np.stack(recorder.history)


# --- protocol and registration ----------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_every_port_passes_the_protocol_checker(name):
    check_controller(DEFAULTS[name](), benchmark="scftc-v2")


@pytest.mark.parametrize("name", NAMES)
def test_registered_for_v2_with_its_params_file_and_trainer(name):
    entry = controller_spec(name, "scftc-v2")
    assert entry.artifacts == (f"params/v2/{name}.yaml",)
    assert entry.artifact_paths()[0] == VERSION.params_dir / f"{name}.yaml"
    assert entry.load().params_type is not None
    assert get_trainer(name, "scftc-v2").__module__ == "scftc_cli.training.tuning"
    assert name in v2_tuning.SPECS and v2_tuning.SPECS[name].benchmark == "scftc-v2"


@pytest.mark.parametrize("name", NAMES)
def test_committed_params_load_and_carry_their_provenance(name):
    path = VERSION.params_dir / f"{name}.yaml"
    if not path.exists():
        pytest.skip(f"{path} not generated yet")
    doc = yaml.safe_load(path.read_text())
    assert doc["controller"] == name
    assert doc["provenance"]["benchmark_version"] == "scftc-v2"
    assert doc["provenance"]["budget"] == "full" and doc["provenance"]["seed"] == 0
    controller = controller_spec(name, "scftc-v2").make()
    check_controller(controller, benchmark="scftc-v2", steps=10, classes=("sign",))


def test_a_v2_port_refuses_v1():
    episodes = bed_for("scftc-v1").draw("train", "sign", n_faults=1, n_seeds=1)
    with pytest.raises(Exception, match="scftc-v2"):
        rollout(PID(PIDParams()), episodes, steps=2)


# --- the wheel-torque measurement ------------------------------------------------------------------


def test_mean_coulomb_shape_is_the_exact_mean_over_a_ramp():
    wlc = 3.0
    start = np.array([[10.0, -10.0, 1.0, -2.0, 5.0]])
    end = np.array([[20.0, -4.0, 2.0, 2.0, 5.0]])
    got = mean_coulomb_shape(start, end, wlc)[0]
    assert got[0] == -1.0 and got[1] == 1.0  # outside the zone: -sign
    assert got[2] == pytest.approx(-1.5 / wlc)  # inside: -mean(Omega) / wLC
    assert got[3] == pytest.approx(0.0)  # symmetric through zero
    assert got[4] == -1.0  # no change: the shape at the start
    ramp = np.linspace(-1.0, 7.0, 200_001)
    exact = np.mean(np.where(np.abs(ramp) < wlc, -ramp / wlc, -np.sign(ramp)))
    got = mean_coulomb_shape(np.array([[-1.0]]), np.array([[7.0]]), wlc)[0, 0]
    assert got == pytest.approx(exact, abs=1e-4)


def test_the_tachometer_torque_matches_the_true_fault_to_its_noise():
    """Over a whole rollout, every linear sample equals ``clip(g a + b) + kappa s`` of the true
    fault in force during its step, to the tachometers' noise (about 9e-4 of ``u_max``)."""
    episodes = BED.draw("train", "gain_bias", n_faults=3, n_seeds=2)
    episodes = with_fault(episodes, friction_multiplier=[15.0, 1.0, 1.0, 1.0])
    controller = RLSDob(RLSParams())
    samples = []
    original = controller._adapt

    def keep(sample):
        samples.append(sample)
        original(sample)

    controller._adapt = keep  # type: ignore[method-assign]
    rollout(controller, episodes)
    wheels = controller.wheels
    residuals = []
    for k, sample in enumerate(samples):
        g, b, multiplier = episodes.fault.at(k)
        kappa = multiplier * wheels.coulomb_nm / wheels.u_max_nm
        _, linear, _ = informative(sample, g, b, kappa, wheels)
        truth = np.clip(g * sample.a + b, -1.0, 1.0) + kappa * sample.s
        residuals.append(np.where(linear, sample.z - truth, np.nan))
    residuals = np.array(residuals)
    assert np.isfinite(residuals).mean() > 0.9
    assert np.nanstd(residuals) < 1.5e-3
    assert np.nanpercentile(np.abs(residuals), 99.9) < 0.01


def test_a_clipped_sample_bounds_the_estimate_only_where_it_falls_short():
    wheels = public_context(1).wheels
    ones = np.ones((1, 4))
    sample = WheelSample(z=np.array([[1.0, 1.0, -0.3, 1.0]]), a=ones, s=-ones, speed_rad_s=100.0 * ones)
    g = np.array([[-1.0, 2.0, 1.0, 0.8]])
    target, linear, censored = informative(sample, g, 0.0 * ones, 0.0 * ones, wheels)
    assert linear.tolist() == [[False, False, True, False]]
    assert censored.tolist() == [[True, False, False, True]]  # wheel 1's estimate already reaches the clip
    assert target[0, 0] == 1.0 and target[0, 3] == 1.0 and target[0, 2] == -0.3
    at_limit = WheelSample(z=sample.z, a=ones, s=-ones, speed_rad_s=np.full((1, 4), wheels.omega_max_rad_s))
    _, linear, censored = informative(at_limit, g, 0.0 * ones, 0.0 * ones, wheels)
    assert not linear.any() and not censored.any()


def test_the_dither_direction_puts_no_torque_on_the_hub():
    wheels = public_context(1).wheels
    rng = np.random.default_rng(0)
    g = rng.uniform(0.3, 2.0, (50, 4)) * np.where(rng.random((50, 4)) < 0.5, -1.0, 1.0)
    v = null_direction(g)
    torque = np.einsum("ij,nj->ni", wheels.spin_axes.T, g * v)
    assert np.abs(torque).max() < 1e-12 and np.allclose(np.abs(v).max(axis=1), 1.0)
    g[:, 2] = 0.0  # a wheel estimated dead: only it is probed
    v = null_direction(g)
    assert np.all(v[:, 2] == 1.0) and np.all(v[:, [0, 1, 3]] == 0.0)


def test_the_change_detector_ignores_a_spike_and_catches_a_step():
    detector = ChangeDetector(2, 4, threshold=0.02, steps=2)
    ok, armed = np.ones((2, 4), bool), np.ones((2, 4), bool)
    quiet = np.zeros((2, 4))
    spike = quiet.copy()
    spike[0, 1] = 0.5
    assert not detector.update(spike, ok, armed).any()
    assert not detector.update(quiet, ok, armed).any()
    assert not detector.update(spike, ok, armed).any()
    assert detector.update(spike, ok, armed).tolist() == [True, False]
    assert not detector.update(spike, ok, ~armed).any()  # disarmed: never


# --- the estimators on known faults ------------------------------------------------------------------


def test_rls_identifies_every_wheel_and_reopens_after_a_late_fault():
    """A gain-and-offset fault with one reversed wheel starting at step 150, long after the latch
    closed on the healthy plant: the residual test re-opens it, the estimates match the fault and
    the episodes settle."""
    episodes = BED.draw("train", "gain_bias", n_faults=2, n_seeds=3)
    gain = np.array([-0.8, 1.3, 0.6, 1.1])
    bias = np.array([0.1, -0.15, 0.05, 0.0])
    episodes = with_fault(episodes, gain=gain, bias=bias, onset_step=150, inertia_scale=1.2)
    controller = RLSDob(RLSParams(dither_steps=20, p0_g=1e3, p0_b=1e2, p_max=1e4, latch_prior_ratio=0.005))
    result, latched = trace(controller, episodes, lambda c: c.rls.latched.copy())
    assert latched[140].all()  # every wheel latched on the healthy plant before the onset
    assert np.all(controller.rls.reopened >= 1)
    g_hat, b_hat, _ = controller.estimates
    assert np.abs(g_hat - gain).max() < 0.05 and np.abs(b_hat - bias).max() < 0.02
    assert np.all(result.dwell_max_error_deg <= V2.gates.settled_deg)


def test_rls_finds_a_dead_wheel_and_cancels_extra_friction():
    """Offset and friction are told apart only by a speed reversal; what the law needs, their sum
    at the wheel's present speed, is identified either way."""
    episodes = BED.draw("train", "loss", n_faults=2, n_seeds=2)
    gain = np.array([1.0, 0.0, 0.9, 1.2])
    multiplier = np.array([1.0, 1.0, 18.0, 1.0])
    episodes = with_fault(episodes, gain=gain, friction_multiplier=multiplier, onset_step=10)
    controller = RLSDob(RLSParams())
    result = rollout(controller, episodes)
    g_hat, b_hat, kappa_hat = controller.estimates
    assert np.abs(g_hat - gain).max() < 0.05
    wheels = controller.wheels
    assert controller.meter.tach is not None
    shape = estimators.coulomb_shape(controller.meter.tach, wheels.omega_linear_rad_s)
    kappa = multiplier * wheels.coulomb_nm / wheels.u_max_nm
    working = gain != 0.0
    assert np.abs((b_hat + kappa_hat * shape - kappa * shape)[:, working]).max() < 0.01
    assert np.all(result.dwell_max_error_deg <= V2.gates.settled_deg)


def test_the_fused_law_command_is_its_numpy_definition():
    """``law_command`` (numba) equals ``null_dither(estimated_command(...))`` (numpy), saturation,
    the dither and one dead-estimated wheel included. With two or more wheels estimated dead the
    regularized allocation is rank-deficient and the two forms part (measured: 1e-4 with two, 1.1
    with three): there the numba kernel, which is what flies, is the definition."""
    wheels = public_context(1).wheels
    rng = np.random.default_rng(7)
    n = 400
    g_hat = rng.uniform(0.3, 2.0, (n, 4)) * np.where(rng.random((n, 4)) < 0.3, -1.0, 1.0)
    g_hat[np.arange(n) % 3 == 0, rng.integers(0, 4, n)[np.arange(n) % 3 == 0]] = 0.02  # one estimated dead
    b_hat = rng.uniform(-0.3, 0.3, (n, 4))
    kappa_hat = rng.uniform(0.0, 0.1, (n, 4))
    tach = rng.uniform(-700.0, 700.0, (n, 4))
    demand = rng.normal(0.0, 0.3, (n, 3))
    since = rng.integers(0, 40, n)
    fused = estimators.law_command(demand, g_hat, b_hat, kappa_hat, tach, wheels, since, 0.2, 20, 2)
    command = estimators.estimated_command(demand, g_hat, b_hat, kappa_hat, tach, wheels)
    reference = estimators.null_dither(command, since, 0.2, 20, g_hat, 2)
    np.testing.assert_allclose(fused, reference, rtol=0, atol=1e-12)


def test_the_closed_form_allocation_is_laws_pseudo_inverse_to_rounding():
    """``closed_form_allocation`` (the law kernel's adjugate inverse, one compiled pass) against
    ``law.allocation`` (LAPACK): to rounding with up to one wheel dead, exactly zero with all dead."""
    wheels = public_context(1).wheels
    rng = np.random.default_rng(11)
    n = 400
    gain = rng.uniform(0.3, 2.0, (n, 4)) * np.where(rng.random((n, 4)) < 0.3, -1.0, 1.0)
    gain[np.arange(n) % 3 == 0, rng.integers(0, 4, n)[np.arange(n) % 3 == 0]] = 0.0  # one dead
    gain[-1] = 0.0
    fused, reference = estimators.closed_form_allocation(gain, wheels), law.allocation(gain, wheels)
    np.testing.assert_allclose(fused, reference, rtol=0, atol=1e-12)
    assert np.all(fused[-1] == 0.0) and np.abs(fused).max() > 0.1


def test_the_sign_vote_flips_a_reversed_wheel_and_no_dead_one():
    episodes = BED.draw("train", "loss", n_faults=2, n_seeds=2)
    gain = np.array([-1.0, 0.0, 1.0, 1.0])
    episodes = with_fault(episodes, gain=gain, onset_step=5)
    controller = ClassicalAdaptive(AdaptiveParams(dither_steps=400, dither_amp=0.2, gamma_m=1.5))
    _, signs = trace(controller, episodes, lambda c: c.sign.copy())
    assert np.all(signs[-1][:, 0] == -1.0) and np.all(signs[-1][:, [2, 3]] == 1.0)
    flips = np.abs(np.diff(signs[:, :, 1], axis=0)).sum(axis=0) / 2
    assert np.all(flips <= 1)  # the dead wheel casts no votes: at most the one it started with
    g_hat, _, _ = controller.estimates
    assert np.all(np.abs(g_hat[:, 1]) < estimators.DEAD_BELOW)


def test_the_allocation_of_all_wheels_estimated_dead_is_zero_not_an_error_in_either_form():
    wheels = public_context(1).wheels
    gains = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, -0.5, 0.8, 1.2]])
    allocation = law.allocation(gains, wheels)
    assert np.all(np.isfinite(allocation)) and np.all(allocation[0] == 0.0)
    # the fused law (rls_dob's) and its numpy definition agree there: the wheels' friction
    # feed-forward and offsets only, no hub demand allocated
    zeros, demand, since = np.zeros((3, 4)), np.full((3, 3), 0.1), np.zeros(3, np.int64)
    fused = estimators.law_command(demand, gains, zeros, zeros, zeros + 100.0, wheels, since, 0.0, 0)
    reference = estimators.estimated_command(demand, gains, zeros, zeros, zeros + 100.0, wheels)
    assert np.all(np.isfinite(fused)) and np.all(fused[0] == reference[0])


def test_icl_stack_converges_to_the_exact_parameters_with_exciting_data():
    context = public_context(3)
    controller = ICLAdaptive(ICLParams(window=2, stack_size=8, gamma_cl=1.0, gamma_inst=0.0))
    controller.reset(3, context)
    truth = np.array([[-0.7, 0.12, 0.02], [1.4, -0.05, 0.1], [0.0, 0.0, 0.005]])  # (g, b, kappa) per row
    rng = np.random.default_rng(1)
    for k in range(300):
        a = rng.uniform(-0.6, 0.6, (3, 4))
        s = np.where(rng.random((3, 4)) < 0.5, -1.0, 1.0) if k % 7 else rng.uniform(-1, 1, (3, 4))
        z = truth[:, None, 0] * a + truth[:, None, 1] + truth[:, None, 2] * s
        controller._adapt(WheelSample(z=z, a=a, s=s, speed_rad_s=np.full((3, 4), 100.0)))
    assert np.abs(controller.phi - truth[:, None, :]).max() < 1e-3


def test_icl_purges_its_stack_when_the_fault_changes():
    context = public_context(1)
    controller = ICLAdaptive(ICLParams(window=2, stack_size=6, gamma_cl=1.0, gamma_inst=0.5))
    controller.reset(1, context)
    rng = np.random.default_rng(2)

    def feed(g, steps):
        for _ in range(steps):
            a = rng.uniform(-0.5, 0.5, (1, 4))
            s = -np.ones((1, 4))
            controller._adapt(WheelSample(z=g * a + 0.005 * s, a=a, s=s, speed_rad_s=np.full((1, 4), 100.0)))

    feed(np.ones(4), 60)
    assert controller.purged[0] == 0
    feed(np.array([1.0, -1.0, 1.0, 1.0]), 200)
    assert controller.purged[0] >= 1
    assert np.abs(controller.phi[0, :, 0] - [1.0, -1.0, 1.0, 1.0]).max() < 0.02


def test_eigenvalue_extremes_match_numpy():
    rng = np.random.default_rng(3)
    for _ in range(200):
        m = rng.normal(size=(3, 3))
        m = m @ m.T
        low, high = _eig_extremes(m[0, 0], m[0, 1], m[0, 2], m[1, 1], m[1, 2], m[2, 2])
        expected = np.linalg.eigvalsh(m)
        assert low == pytest.approx(expected[0], abs=1e-9) and high == pytest.approx(expected[-1], rel=1e-9)


def test_pid_integrator_removes_a_gyro_bias_offset():
    episodes = BED.draw("train", "sign", "gyro_bias", n_faults=4, n_seeds=2)
    healthy = with_fault(episodes, gain=np.ones(4))
    pd_like = rollout(PID(PIDParams(ki_s3=1e-9)), healthy)
    pid = rollout(PID(PIDParams(ki_s3=5e-4, integrate_below=0.02)), healthy)
    assert np.median(pid.final_error_deg) < 0.5 * np.median(pd_like.final_error_deg)


def test_nussbaum_starts_as_the_nominal_law():
    """With ``N(zeta0) = 1`` and no error-driven adaptation yet, the first command is the
    nominal allocation of the analytic law (the pd calibration controller)."""
    from scftc_cli.versions.v2.controllers.analytic import PD

    episodes = BED.draw("train", "sign", n_faults=2, n_seeds=2)
    ours = rollout(Nussbaum(NussbaumParams(gamma=0.0, gamma_d=0.0, k_null=0.0)), episodes, record=True)
    pd = rollout(PD(), episodes, record=True)
    np.testing.assert_allclose(ours.commands, pd.commands, atol=1e-9)


# --- tuning -----------------------------------------------------------------------------------------


def test_v2_tuning_samples_train_episodes_only_and_is_deterministic(tmp_path, monkeypatch):
    seen: list[WheelEpisodes] = []
    original = TESTBED.draw

    def recording(split, fault_class, *args, **kwargs):
        episodes = original(split, fault_class, *args, **kwargs)
        seen.append(episodes)
        return episodes

    monkeypatch.setattr(TESTBED, "draw", recording)  # every door to the episodes: tuning and scoring
    outputs = []
    for i in range(2):
        request = TrainRequest(
            controller="pid", benchmark="scftc-v2", seed=3, budget="quick", out=tmp_path / f"p{i}.yaml"
        )
        report = tuning.tune_controller(request)
        outputs.append(yaml.safe_load(report.artifact.read_text()))

    assert seen and {e.split for e in seen} == {"train"}
    train = V2.splits["train"]
    for episodes in seen:
        fault: WheelFault = episodes.fault
        assert np.all(train.onset_s.contains(fault.onset_step * V2.dt_s))
        assert np.all(train.inertia_scale.contains(fault.inertia_scale))
    assert outputs[0]["params"] == outputs[1]["params"]
    provenance = outputs[0]["provenance"]

    def timeless(p: dict) -> dict:  # the wall time and the creation date may differ, nothing else
        return {**p, "created_utc": None, "notes": re.sub(r"; wall \d+ s", "", p["notes"])}

    assert timeless(provenance) == timeless(outputs[1]["provenance"])
    assert provenance["benchmark_version"] == "scftc-v2" and provenance["budget"] == "quick"
    assert "sign+gyro_bias" in provenance["notes"]


def test_v1_tuning_is_untouched_by_the_v2_table():
    for name, spec in v1_tuning.SPECS.items():
        assert spec.benchmark == "scftc-v1" and tuning.tune_spec(name, "scftc-v1") is spec
    assert tuning.tune_spec("rls_dob", "scftc-v2") is v2_tuning.SPECS["rls_dob"]
    v1 = tuning.tuning_episodes(2, 1, v1_tuning.TUNE_CLASSES, "scftc-v1")
    assert v1.benchmark == "scftc-v1" and v1.fault_class == "sign+gain+gain_bias"
