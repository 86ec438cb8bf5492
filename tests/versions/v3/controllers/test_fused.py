"""The compiled mission law (``controllers/fused.py``) and ``fdir``'s compiled least squares give
the same bits as their numpy definitions (``law.py``, ``tests/oracles/v3_analytic.py``,
``tests/oracles/v3_fdir.py``): piece by piece on random rows, and over whole rollouts of every v3
controller that flies the law, one episode alone (numpy's single-row sums) and a batch."""

from __future__ import annotations

import numpy as np
import pytest

from scftc_cli.sim import testbed as testbeds
from scftc_cli.sim.rollout import rollout
from scftc_cli.versions.v2.controllers.law import allocate, allocation, friction_nm
from scftc_cli.versions.v2.controllers.pid import PIDParams
from scftc_cli.versions.v2.controllers.rls import RLSParams
from scftc_cli.versions.v3.controllers import analytic, fdir, fused, law, pid, rls
from scftc_cli.versions.v3.spec import V3
from tests.oracles import v2_law, v3_analytic, v3_fdir

BED = testbeds.testbed("scftc-v3")


def _context():
    return BED.context(BED.draw("train", "gain", n_faults=1, n_seeds=1), privileged=False)


@pytest.mark.parametrize("n", [1, 7, fused.PARALLEL_MIN_BATCH + 1])  # the serial and the threaded passes
def test_each_piece_is_its_numpy_definition_bit_for_bit(n):
    rng = np.random.default_rng(n)
    context = _context()
    wheels, rods = context.wheels, context.rods
    sigma, target = rng.uniform(-0.9, 0.9, (n, 3)), rng.uniform(-0.9, 0.9, (n, 3))
    target[0] = -sigma[0] / np.dot(sigma[0], sigma[0])  # a shadow pair: the composition's 0/0
    np.testing.assert_array_equal(fused.attitude_error(sigma, target), law.attitude_error(sigma, target))
    error, gyro = rng.uniform(-0.5, 0.5, (n, 3)), rng.normal(0, 0.01, (n, 3))
    tach = rng.normal(0, 200, (n, 4))
    kp, kd = rng.uniform(0.01, 2, (n, 1)), rng.uniform(0.1, 2, (n, 1))
    for gains in ((), (0.3, 0.9), (kp, kd)):  # the defaults, scalars, one row per episode
        np.testing.assert_array_equal(
            fused.rate_limited_demand(error, gyro, tach, context, *gains),
            law.rate_limited_demand(error, gyro, tach, context, *gains),
        )
    gain = rng.uniform(-1.2, 1.2, (n, 4))
    gain[n // 2, 1] = 0.0  # a wheel believed dead
    rod_gain = rng.uniform(-1, 1, (n, 3))
    rod_gain[0, 2] = 0.05  # a rod believed dead
    field = rng.normal(0, 3e-5, (n, 3))
    unload = rng.integers(0, 2, (n, 1)).astype(float)
    demand, disturbance = rng.normal(0, 1e-3, (n, 3)), rng.normal(0, 1e-5, (n, 3))
    offset = rng.normal(0, 0.05, (n, 4))
    friction = friction_nm(tach, wheels.coulomb_nm, wheels)
    matrix = allocation(gain, wheels)
    for rate, base in ((law.NULL_RATE_PER_S, 0.0), (0.0, 0.0), (0.05, 30.0)):
        wanted = law.unloading_dipole(law.wheel_momentum(tach, context), field, rods)
        rod_cmd = law.rod_commands(wanted * unload, rod_gain, rods)
        torque = law.cross(rod_gain * rod_cmd * rods.dipole_max_am2, field)
        wheel_cmd = allocate(demand - torque - disturbance, matrix, gain, friction, offset, wheels)
        wheel_cmd = np.clip(wheel_cmd + law.null_space_commands(tach, gain, context, rate, base), -1.0, 1.0)
        got = fused.law_commands(
            demand, field, rod_gain, unload, gain, offset, friction, disturbance, tach, matrix, wheels, rods,
            rate, base,
        )  # fmt: skip
        np.testing.assert_array_equal(got, np.concatenate([wheel_cmd, rod_cmd], axis=1))


@pytest.mark.parametrize("lead", [(6, 4), (9,)])
def test_fdirs_compiled_least_squares_step_is_its_numpy_definition(lead):
    d = 2 if len(lead) == 2 else 3  # the wheels' (gain, offset) and the rods' three gains
    rng = np.random.default_rng(d)
    theta = rng.normal(size=(*lead, d))
    root = rng.normal(size=(*lead, d, d))
    p = root @ np.swapaxes(root, -1, -2) * rng.uniform(0.1, 1e3, (*lead, 1, 1))
    phi = rng.normal(size=(*lead, 3, d))[..., 1, :]  # a strided view, as fdir's regressors
    y, mask = rng.normal(size=lead), rng.random(lead) < 0.7
    for forgetting, trace_max in ((0.99, 2e4), (0.998 ** (1 / 3), 30.0), (0.9, 1.0)):
        got = fdir.rls_update(theta, p, phi, y, forgetting, mask, trace_max)
        want = v3_fdir.rls_update(theta, p, phi, y, forgetting, mask, trace_max)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
    assert not np.array_equal(got[1], p) and np.array_equal(got[1][~mask], p[~mask])


CONTROLLERS = {
    "pd": lambda: analytic.PD(),
    "teacher": lambda: analytic.Teacher(),
    "oracle": lambda: analytic.Oracle(),
    "fdir": lambda: fdir.FDIR(),
    "pid": lambda: pid.PID(PIDParams(kp_s2=0.8, kd_s=1.2, ki_s3=0.02, integral_cap=0.5, integrate_below=0.1)),
    "rls_dob": lambda: rls.RLSDob(RLSParams()),
}


def _numpy_law(monkeypatch):
    """Every controller's law back on ``law.py``'s numpy functions."""
    monkeypatch.setattr(analytic.MissionLaw, "act", v3_analytic.act)
    monkeypatch.setattr(fdir, "rls_update", v3_fdir.rls_update)
    monkeypatch.setattr(fdir.FDIR, "_wheels_and_rods", v3_fdir._wheels_and_rods)
    monkeypatch.setattr(fdir, "vote", v2_law.vote)
    for module in (fused, pid, rls):
        monkeypatch.setattr(module, "rate_limited_demand", law.rate_limited_demand)


@pytest.mark.parametrize(
    "name", [n if n == "pd" else pytest.param(n, marks=pytest.mark.slow) for n in sorted(CONTROLLERS)]
)
def test_a_rollout_through_the_compiled_law_is_the_numpy_rollout(name, monkeypatch):
    episodes = BED.draw("train", "compound", n_faults=3, n_seeds=1)
    for batch in (episodes, episodes.subset(np.array([1]))):  # a batch, and one episode alone
        compiled = rollout(CONTROLLERS[name](), batch, record=True)
        with monkeypatch.context() as patch:
            _numpy_law(patch)
            reference = rollout(CONTROLLERS[name](), batch, record=True)
        assert batch.n == 1 or not np.array_equal(reference.final_error_deg, reference.final_error_deg[::-1])
        assert compiled.commands is not None and reference.commands is not None
        np.testing.assert_array_equal(compiled.commands, reference.commands)  # every command, every step
        np.testing.assert_array_equal(compiled.error_deg, reference.error_deg)
    assert V3.steps == 2400  # whole episodes: every window, the onset and the bursts were flown


class _Reporting(fdir.FDIR):
    """``fdir`` keeping every step's health codes."""

    def reset(self, n, context):
        super().reset(n, context)
        self.reports = []

    def act(self, obs):
        command = super().act(obs)
        self.reports.append(self.health())
        return command


@pytest.mark.slow
def test_fdirs_compiled_wheel_and_rod_detectors_report_what_their_numpy_definition_reports(monkeypatch):
    from scftc_cli.versions.v3.sim.faults import AgileEpisodes

    cells = ("rod", "intermittent", "gain", "double")  # rods identified, bursts, probes, two wheels
    episodes = AgileEpisodes.concat([BED.draw("train", c, n_faults=1, n_seeds=1) for c in cells])
    for batch in (episodes, episodes.subset(np.array([1]))):
        compiled = _Reporting()
        rollout(compiled, batch)
        with monkeypatch.context() as patch:
            patch.setattr(fdir.FDIR, "_wheels_and_rods", v3_fdir._wheels_and_rods)
            reference = _Reporting()
            rollout(reference, batch)
        np.testing.assert_array_equal(np.stack(compiled.reports), np.stack(reference.reports))
        for name in ("theta", "p", "offset_fast", "rod_theta", "rod_p", "probe_until"):
            np.testing.assert_array_equal(getattr(compiled, name), getattr(reference, name))
        assert np.stack(compiled.reports).any()  # something was detected
    codes = np.stack(
        compiled.reports
    )  # the last batch: one `intermittent`... episode 2 is `intermittent`'s first
    assert codes.shape == (V3.steps, 1, len(V3.diagnosis.units))
