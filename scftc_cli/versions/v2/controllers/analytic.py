"""``scftc-v2``'s calibration controllers: ``pd``, ``teacher``, ``bias_oracle``
(docs/benchmark-v2.md, "Calibration").

All three fly the analytic law of ``law.py`` on the fused attitude and the gyro rate, with the
gyroscopic and the nominal friction feed-forwards; they differ only in what they know of the fault:
``pd`` nothing (nominal allocation), ``teacher`` the true effectiveness ``g(t)`` (healthy before
the onset), ``bias_oracle`` also the true offsets and friction.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v2.controllers.law import (
    AttitudeFuser,
    allocate,
    allocation,
    friction_nm,
    split_observation,
    torque_demand,
    wheels_of,
)


class PD(Controller):
    """Fault-unaware: the analytic law through the nominal allocation ``pinv(G)``, friction
    feed-forward at the nominal ``fC0``."""

    def reset(self, n: int, context: Context) -> None:
        self.context, self.wheels = context, wheels_of(context)
        self.fuser = AttitudeFuser(n)
        self.gain = np.ones((n, len(self.wheels.spin_axes)))
        self.allocation = allocation(self.gain, self.wheels)

    def act(self, obs: np.ndarray) -> np.ndarray:
        heads, valid, gyro, tach = split_observation(obs)
        sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
        demand = torque_demand(sigma, gyro, tach, self.context)
        friction = friction_nm(tach, self.wheels.coulomb_nm, self.wheels)
        return allocate(demand, self.allocation, self.gain, friction, 0.0, self.wheels)


class Teacher(Controller):
    """Privileged: the analytic law through the true effectiveness ``g(t)`` (healthy before the
    onset), no offset or fault-friction compensation (an upper bound for gain identification)."""

    privileged = True
    knows_offsets_and_friction = False

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("a privileged controller needs the true fault in its context")
        self.context, self.wheels = context, wheels_of(context)
        fault = context.fault
        m = len(self.wheels.spin_axes)
        self.fuser = AttitudeFuser(n)
        self.onset = np.asarray(fault.onset_step)
        self.gain_before, self.gain_after = np.ones((n, m)), np.asarray(fault.gain)
        self.healthy = allocation(self.gain_before, self.wheels)  # constant: computed once
        self.faulted = allocation(self.gain_after, self.wheels)
        nominal = np.full((n, m), self.wheels.coulomb_nm)
        if self.knows_offsets_and_friction:
            self.coulomb_after = self.wheels.coulomb_nm * np.asarray(fault.friction_multiplier)
            self.bias_after = np.asarray(fault.bias)
        else:
            self.coulomb_after, self.bias_after = nominal, np.zeros((n, m))
        self.coulomb_before, self.bias_before = nominal, np.zeros((n, m))
        self.k = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        heads, valid, gyro, tach = split_observation(obs)
        sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
        demand = torque_demand(sigma, gyro, tach, self.context)
        after = (self.k >= self.onset)[:, None]
        matrix = np.where(after[:, :, None], self.faulted, self.healthy)
        coulomb = np.where(after, self.coulomb_after, self.coulomb_before)
        bias = np.where(after, self.bias_after, self.bias_before)
        gain = np.where(after, self.gain_after, self.gain_before)
        self.k += 1
        return allocate(demand, matrix, gain, friction_nm(tach, coulomb, self.wheels), bias, self.wheels)


class BiasOracle(Teacher):
    """Privileged: the teacher plus the true offsets and the true friction (from the tachometer
    speed and the true Coulomb level)."""

    knows_offsets_and_friction = True
