"""``MissionLaw.act`` (``scftc_cli/versions/v3/controllers/analytic.py``) through ``law.py``'s numpy
functions: the readable form of the compiled mission law (``controllers/fused.py``), which a
rollout on it is tested against, bit for bit. It takes the controller as ``self``: a test sets it
as ``MissionLaw.act`` to fly every controller built on the law on numpy."""

from __future__ import annotations

import numpy as np

from scftc_cli.sim.mrp import cross
from scftc_cli.versions.v2.controllers.law import allocate
from scftc_cli.versions.v3.controllers.analytic import MissionLaw
from scftc_cli.versions.v3.controllers.law import (
    attitude_error,
    null_space_commands,
    rod_commands,
    split_observation,
    unloading_dipole,
    wheel_momentum,
)


def act(self: MissionLaw, obs: np.ndarray) -> np.ndarray:
    """``MissionLaw.act`` through ``law.py``'s numpy functions (the same bits).
    The ``demand`` hook is the subclass's: the compiled ``fused.rate_limited_demand`` unless
    put back on ``law.rate_limited_demand``, as the tests and the benchmark do."""
    heads, valid, gyro, tach, magnetometer, target, time_left = split_observation(self.corrected(obs))
    sigma = self.fuser.update(heads, valid, gyro, self.context.dt_s)
    error = attitude_error(sigma, target)
    demand = self.demand(error, gyro, tach)
    field = self.field_body(magnetometer, sigma)
    rod_gain = self.rod_gain()
    wanted = unloading_dipole(wheel_momentum(tach, self.context), field, self.rods)
    rods = rod_commands(wanted * self.unloading(time_left), rod_gain, self.rods)
    rod_torque = cross(rod_gain * rods * self.rods.dipole_max_am2, field)
    gain, offset, friction = self.wheel_model(tach)
    matrix = self.nominal if np.all(gain == 1.0) else self.allocation(gain)
    wheels = allocate(
        demand - rod_torque - self.disturbance_nm(sigma), matrix, gain, friction, offset, self.wheels
    )
    drain = null_space_commands(tach, gain, self.context, self.null_rate_per_s, self.null_target_rad_s)
    wheels = np.clip(wheels + drain, -1.0, 1.0)
    self.commanded(error, wheels)
    self.k += 1
    return np.concatenate([wheels, rods], axis=1)
