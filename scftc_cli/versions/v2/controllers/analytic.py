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
from scftc_cli.versions.v2.controllers.law import AnalyticLaw, allocation, wheels_of


class _Analytic(Controller):
    """A controller that flies one ``AnalyticLaw`` (built by ``reset``)."""

    law: AnalyticLaw

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self.law.command(obs)


class PD(_Analytic):
    """Fault-unaware: the analytic law through the nominal allocation ``pinv(G)``, friction
    feed-forward at the nominal ``fC0``."""

    def reset(self, n: int, context: Context) -> None:
        wheels = wheels_of(context)
        m = len(wheels.spin_axes)
        gain = np.ones((n, m))
        nominal = (allocation(gain, wheels), gain, np.full((n, m), wheels.coulomb_nm), np.zeros((n, m)))
        self.law = AnalyticLaw(n, context, nominal, nominal, np.zeros(n, dtype=np.int64))


class Teacher(_Analytic):
    """Privileged: the analytic law through the true effectiveness ``g(t)`` (healthy before the
    onset), no offset or fault-friction compensation (an upper bound for gain identification)."""

    privileged = True
    knows_offsets_and_friction = False

    def reset(self, n: int, context: Context) -> None:
        if context.fault is None:
            raise ValueError("a privileged controller needs the true fault in its context")
        wheels, fault = wheels_of(context), context.fault
        m = len(wheels.spin_axes)
        healthy, gain_after = np.ones((n, m)), np.asarray(fault.gain)
        nominal, no_bias = np.full((n, m), wheels.coulomb_nm), np.zeros((n, m))
        if self.knows_offsets_and_friction:
            coulomb_after = wheels.coulomb_nm * np.asarray(fault.friction_multiplier)
            bias_after = np.asarray(fault.bias)
        else:
            coulomb_after, bias_after = nominal, no_bias
        before = (allocation(healthy, wheels), healthy, nominal, no_bias)
        after = (allocation(gain_after, wheels), gain_after, coulomb_after, bias_after)
        self.law = AnalyticLaw(n, context, before, after, np.asarray(fault.onset_step))


class BiasOracle(Teacher):
    """Privileged: the teacher plus the true offsets and the true friction (from the tachometer
    speed and the true Coulomb level)."""

    knows_offsets_and_friction = True
