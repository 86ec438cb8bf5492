"""``scftc-v3``'s calibration controllers: ``pd``, ``teacher``, ``oracle`` (docs/benchmark-v3.md).

All three fly one law (``MissionLaw``): the fused attitude's error to the current target, v2's PD
as a rate loop with a 1 deg/s slew cap and the gyroscopic feed-forward, cross-product momentum
unloading by the rods, the rods' torque fed forward through the wheels, and v2's allocation with
friction feed-forward. They differ only in what they know of the fault and the environment:

- ``pd``: nothing (nominal wheels and rods, nominal friction; its own magnetometer);
- ``teacher`` (privileged): the true wheel effectiveness ``g(t)`` and rod gains (healthy before
  the onset), and a perfect diagnosis;
- ``oracle`` (privileged): the teacher plus the true offsets and friction (bursts and ramps
  included), the environment's torques fed forward, and the true field for the rods.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v2.controllers.law import (
    AttitudeFuser,
    HeldAllocation,
    allocation,
    friction_nm,
)
from scftc_cli.versions.v2.sim.faults import sensor_code
from scftc_cli.versions.v2.spec import V2
from scftc_cli.versions.v3.controllers import fused
from scftc_cli.versions.v3.controllers.law import (
    NULL_RATE_PER_S,
    NULL_TARGET_RAD_S,
    rods_of,
    split_observation,
)
from scftc_cli.versions.v3.sim.dynamics import MassProperties, OrbitGeometry, external_torque_nm
from scftc_cli.versions.v3.sim.environment import (
    dipole_field_t,
    gravity_gradient_terms,
    latitude_trig,
    orbit_position_m,
    to_body,
)
from scftc_cli.versions.v3.sim.mission import CONSTANTS
from scftc_cli.versions.v3.spec import V3


class MissionLaw(Controller):
    """The law every v3 calibration controller flies; subclasses say what it knows (the hooks
    below return the nominal model)."""

    null_rate_per_s: float = NULL_RATE_PER_S
    null_target_rad_s: float = NULL_TARGET_RAD_S

    def reset(self, n: int, context: Context) -> None:
        self.context, self.rods = context, rods_of(context)
        assert context.wheels is not None
        self.wheels = context.wheels
        self.n, self.k = n, 0
        self.m = len(self.wheels.spin_axes)
        self.fuser = AttitudeFuser(n)
        self.nominal = allocation(np.ones((n, self.m)), self.wheels)
        self.held_allocation = HeldAllocation(self.wheels)

    # what the controller believes of the plant at the current step (nominal by default)
    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(gain (n, m), offset (n, m), friction (n, m) N m)``."""
        ones = np.ones((self.n, self.m))
        return ones, np.zeros((self.n, self.m)), friction_nm(tach, self.wheels.coulomb_nm, self.wheels)

    def allocation(self, gain: np.ndarray) -> np.ndarray:
        """``pinv(G diag(gain))`` ``(n, m, 3)`` for believed gains ``(n, m)`` (``law.allocation``,
        recomputed only on the rows whose gains changed: ``HeldAllocation``)."""
        return self.held_allocation(gain)

    def rod_gain(self) -> np.ndarray:
        return np.ones((self.n, 3))

    def field_body(self, magnetometer: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        return magnetometer

    def disturbance_nm(self, sigma: np.ndarray) -> np.ndarray:
        return np.zeros((self.n, 3))

    def unloading(self, time_left_s: np.ndarray) -> np.ndarray:
        """``(n, 1)`` 1 where the rods unload this step, 0 where they stay off."""
        return np.ones((self.n, 1))

    def corrected(self, obs: np.ndarray) -> np.ndarray:
        """The observation the law flies on (the raw one unless a subclass knows better)."""
        return obs

    def demand(self, error: np.ndarray, gyro: np.ndarray, tach: np.ndarray) -> np.ndarray:
        """The body torque demand ``(n, 3)`` N m for the error to the target ``(n, 3)`` MRP (the rate-
        limited PD with its gyroscopic feed-forward unless a subclass adds to it)."""
        return fused.rate_limited_demand(error, gyro, tach, self.context)

    def commanded(self, error: np.ndarray, wheels: np.ndarray) -> None:
        """Told the step's clipped wheel commands ``(n, m)`` and the error they answered (nothing to
        do unless a subclass keeps state on them)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Wheel and rod commands ``(n, m + 3)`` for a step's observations (``split_observation``):
        the fused attitude's error to the target, the demand, the rods' unloading and the wheels'
        allocation in one compiled law
        (``fused.law_commands``; tests/oracles/v3_analytic.py holds the readable form through
        ``law.py``'s numpy functions, the same bits)."""
        heads, valid, gyro, tach, magnetometer, target, time_left = split_observation(self.corrected(obs))
        sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
        error = fused.attitude_error(sigma, target)
        demand = self.demand(error, gyro, tach)
        field = self.field_body(magnetometer, sigma)
        rod_gain = self.rod_gain()
        unload = self.unloading(time_left)
        gain, offset, friction = self.wheel_model(tach)
        matrix = self.nominal if np.all(gain == 1.0) else self.allocation(gain)
        command = fused.law_commands(
            demand, field, rod_gain, unload, gain, offset, friction, self.disturbance_nm(sigma), tach, matrix,
            self.wheels, self.rods, self.null_rate_per_s, self.null_target_rad_s,
        )  # fmt: skip
        self.commanded(error, command[:, : self.m])
        self.k += 1
        return command


class PD(MissionLaw):
    """Fault-unaware: the law on the nominal model."""


class Teacher(MissionLaw):
    """Privileged: the true wheel effectiveness ``g(t)`` and rod gains, a perfect diagnosis."""

    privileged = True

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("a privileged controller needs the true fault in its context")
        super().reset(n, context)
        self.truth = context.fault.truth
        self.episodes = context.fault.episodes
        fault = self.episodes.fault
        self.fault = fault
        self.onset = np.asarray(fault.onset_step)
        steps_left = np.maximum(V3.steps - self.onset, 1)  # the plant's ramp: 1 at the onset, k at the end
        self.ramp_rate = (np.asarray(fault.friction_ramp_end) - 1.0) / steps_left[:, None]

    def active(self) -> np.ndarray:
        return (self.k >= self.onset)[:, None]

    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        gain, offset, friction = super().wheel_model(tach)
        return self.fault.gain_at(self.k), offset, friction

    def rod_gain(self) -> np.ndarray:
        return np.where(self.active(), self.fault.rod_gain, 1.0)

    def health(self) -> np.ndarray:
        return np.where((self.k - 1 >= self.truth.onset_step)[:, None], self.truth.codes, 0)


class Oracle(Teacher):
    """Privileged: the teacher plus the true offsets and friction (bursts and ramps), the
    environment's torques fed forward, the true field for the rods, and the sensor faults: the
    gyro-bias step removed, a biased or stuck head ignored (marked invalid)."""

    def corrected(self, obs: np.ndarray) -> np.ndarray:

        fault = self.episodes.sensor_fault
        kind, active = np.asarray(fault.kind), self.k >= np.asarray(self.episodes.fault.onset_step)
        out = obs.copy()
        step = np.where(
            (active & (kind == sensor_code(V2, "gyro_bias")))[:, None], fault.gyro_bias_step_rad_s, 0.0
        )
        out[:, 12:15] = obs[:, 12:15] - step
        bad = active & ((kind == sensor_code(V2, "st_bias")) | (kind == sensor_code(V2, "st_stuck")))
        rows = np.flatnonzero(bad)
        heads = np.asarray(fault.head)[rows]
        out[rows, 9 + heads] = 0.0
        for axis in range(3):
            out[rows, 3 * heads + axis] = 0.0
        return out

    def reset(self, n: int, context: Context) -> None:
        super().reset(n, context)

        self.constants = CONSTANTS
        env = self.episodes.environment
        self.geometry = OrbitGeometry.of(env, CONSTANTS)
        self.inertia = MassProperties.of(
            CONSTANTS.wheels, np.asarray(self.episodes.inertia_scale)
        ).total_inertia_kgm2
        self._field_n = np.zeros((n, 3))

    def wheel_model(self, tach: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f, k = self.fault, self.k
        active = self.active()
        gain = f.gain_at(k)
        offset = np.where(active, f.bias, 0.0)
        ramp = 1.0 + self.ramp_rate * (k - self.onset)[:, None]
        burst = np.where(f.in_burst(k), f.burst_multiplier, 1.0)
        coulomb = self.wheels.coulomb_nm * np.where(active, (f.friction_multiplier * ramp) * burst, 1.0)
        return gain, offset, friction_nm(tach, coulomb, self.wheels)

    def _position(self) -> np.ndarray:

        env, g = self.episodes.environment, self.geometry
        cos_u, sin_u = latitude_trig(env.arg_latitude0_rad, g.mean_motion, self.k * self.context.dt_s)
        return orbit_position_m(env.semi_major_axis_m, g.p, g.q, cos_u, sin_u)

    def field_body(self, magnetometer: np.ndarray, sigma: np.ndarray) -> np.ndarray:

        self._field_n = dipole_field_t(
            self._position(), self.geometry.dipole_n, self.constants.environment.field_radius_m
        )
        return to_body(sigma, self._field_n)

    def disturbance_nm(self, sigma: np.ndarray) -> np.ndarray:

        env = self.episodes.environment
        r_hat, coefficient = gravity_gradient_terms(
            self._position(), self.constants.environment.gravity_gradient_factor
        )
        return external_torque_nm(
            sigma, r_hat, coefficient, self._field_n, np.asarray(env.residual_dipole_am2), env,
            self.geometry, self.inertia, self.constants.environment,
        )  # fmt: skip
