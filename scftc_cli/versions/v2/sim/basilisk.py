"""The Basilisk v2 backend: every episode flown on Basilisk's ``spacecraft`` with its wheels.

The numpy reference (``v2/dynamics.py``) is a vectorized copy of what this module asks Basilisk
to do; it is here so the two can be shown to agree (docs/benchmark-v2.md, Basilisk). One
Basilisk simulation holds, per episode, a rigid hub and a ``reactionWheelStateEffector`` with
four ``BalancedWheels`` made by ``rwFactory`` ("custom" wheels), all in one task stepped at
``dt`` (Basilisk's RK4 integrates the hub and wheel states together over each step, friction
evaluated at every stage, then switches to the MRP shadow set).

What it takes for Basilisk to fly scftc-v2's plant (each point checked in the tests):

- Task order: within a task Basilisk runs models by descending priority, and the hub integrates
  with the motor torque the wheel effector latched when it last ran. The effector is given a
  higher priority than the hub, so the command written before a step is applied over that step;
  with the default order every command would land one step late.
- Inertia: in bsk 2.12 balanced wheels add no inertia to the hub (only jitter models fill
  ``effProps``), so the hub's inertia is set to ``I_tot`` (hub plus wheels) here.
- Friction: ``rwFactory`` silently zeroes ``fCoulomb`` unless ``useRWfriction=True``; the
  linear zone ``omegaLimitCycle`` is set to ``wLC`` (scftc-v2's 3 rad/s, not Basilisk's 1e-4);
  ``cViscous`` as the constants; Stribeck off (``betaStatic < 0``, the factory's default). The
  fault's friction is switched by writing the wheel's ``fCoulomb`` before the onset step.
- Motor torque: the gain/bias fault and the ``u_max`` clip are applied to the command before it
  is written to ``rwMotorCmdInMsg``, so the motor receives ``u``; Basilisk's own ``u_max`` clip
  is then a no-op, and its speed saturation (on the wheel speed at the start of the step, the
  one the effector sees when it runs) is the one the reference copies. ``applied_torque_nm`` is
  read back from each wheel's ``u_current``, i.e. after Basilisk's saturation.
- Exact inputs: the spin axes and initial wheel speeds are written into each wheel's config
  after the factory made it, so both backends integrate the same doubles (the factory
  renormalizes the axes, a no-op for scftc-v2's, and takes speeds in rpm, a round trip that can
  lose the last bit).

Basilisk (``bsk`` on PyPI) is an optional extra: importing this module without it raises
``BackendUnavailable`` with the install hint.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from scftc_cli.errors import BackendUnavailable
from scftc_cli.sim.mrp import norm2
from scftc_cli.versions.v2.sim.dynamics import WheelPlantBase, motor_torque_nm

INSTALL_HINT = "Basilisk backend needs the optional extra: pip install 'scftc[basilisk]'"

try:
    from Basilisk.architecture import messaging
    from Basilisk.simulation import reactionWheelStateEffector, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW
except ImportError as err:  # the optional extra is not installed
    raise BackendUnavailable(INSTALL_HINT) from err

HUB_MASS_KG = 100.0  # arbitrary: with no gravity and no force the translation never moves
WHEEL_PRIORITY = 200  # higher than the hub's: the wheel effector latches the command first
HUB_PRIORITY = 100
_PROCESS, _TASK = "scftc_v2_process", "scftc_v2_dynamics"


class BasiliskWheelPlant(WheelPlantBase):
    """A batch of v2 episodes stepped together in one Basilisk simulation, one hub per episode.

    Same constructor and ``step`` as ``WheelPlant`` (see ``WheelPlantBase``); the state after
    each step is read from each hub's ``scStateOutMsg`` and wheel effector's ``rwSpeedOutMsg``.
    """

    name = "basilisk"

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)  # WheelPlantBase's arguments
        c = self.constants
        self.dt_ns = int(macros.sec2nano(c.dt_s))
        if self.dt_ns <= 0 or abs(self.dt_ns * 1e-9 - c.dt_s) > 1e-15:
            raise ValueError(f"dt_s = {c.dt_s} is not a whole number of nanoseconds")
        self.sim = SimulationBaseClass.SimBaseClass()
        self.sim.CreateNewProcess(_PROCESS).addTask(self.sim.CreateNewTask(_TASK, self.dt_ns))
        self.hubs, self.wheel_effectors, self.wheels, self.cmd_msgs = [], [], [], []
        for e in range(self.n):
            hub, effector, wheels = self._build_episode(e)
            cmd_msg = messaging.ArrayMotorTorqueMsg()
            effector.rwMotorCmdInMsg.subscribeTo(cmd_msg)
            self.sim.AddModelToTask(_TASK, effector, WHEEL_PRIORITY)
            self.sim.AddModelToTask(_TASK, hub, HUB_PRIORITY)
            self.hubs.append(hub)
            self.wheel_effectors.append(effector)
            self.wheels.append(wheels)
            self.cmd_msgs.append(cmd_msg)
        self._payload = messaging.ArrayMotorTorqueMsgPayload()
        self._coulomb_now = np.full((self.n, c.n_wheels), c.coulomb_nm)
        self.sim.InitializeSimulation()
        self.k = 0  # steps flown: Basilisk's clock, so step() must be called with k = 0, 1, 2...
        self._advance_to(0)  # the t = 0 pass publishes the initial states and integrates nothing
        self.sigma, self.omega_rad_s, self.wheel_speed_rad_s = self._read_states()

    def _build_episode(self, e: int):
        c = self.constants
        hub = spacecraft.Spacecraft()
        hub.ModelTag = f"scftc_v2_hub_{e}"
        hub.hub.mHub = HUB_MASS_KG
        hub.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
        hub.hub.IHubPntBc_B = self.mass.total_inertia_kgm2[e].tolist()  # I_tot: see the module doc
        hub.hub.sigma_BNInit = [[float(v)] for v in self.sigma[e]]
        hub.hub.omega_BN_BInit = [[float(v)] for v in self.omega_rad_s[e]]
        factory = simIncludeRW.rwFactory()
        wheels = []
        for i, axis in enumerate(c.axes):
            rw = factory.create(
                "custom",
                axis.tolist(),
                RWModel=messaging.BalancedWheels,
                maxMomentum=float(c.h_max_nms),
                Omega_max=float(c.omega_max_rpm),
                u_max=float(c.u_max_nm),
                useRWfriction=True,
                fCoulomb=float(c.coulomb_nm),
                cViscous=float(c.viscous_nms),
            )
            rw.omegaLimitCycle = float(c.omega_linear_rad_s)
            rw.gsHat_B = [[float(v)] for v in axis]
            rw.Omega = float(self.wheel_speed_rad_s[e, i])
            if rw.Js != c.js_kgm2 or rw.Omega_max != c.omega_max_rad_s:
                raise RuntimeError("rwFactory derived other wheel constants than WheelConstants")
            wheels.append(rw)
        effector = reactionWheelStateEffector.ReactionWheelStateEffector()
        factory.addToSpacecraft(f"scftc_v2_wheels_{e}", effector, hub)
        return hub, effector, wheels

    def _advance_to(self, k: int) -> None:
        self.sim.ConfigureStopTime(k * self.dt_ns)
        self.sim.ExecuteSimulation()

    def _read_states(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        states = [hub.scStateOutMsg.read() for hub in self.hubs]
        sigma = np.array([s.sigma_BN for s in states], dtype=float).reshape(self.n, 3)
        omega = np.array([s.omega_BN_B for s in states], dtype=float).reshape(self.n, 3)
        m = self.constants.n_wheels
        speeds = np.array(
            [eff.rwSpeedOutMsg.read().wheelSpeeds[:m] for eff in self.wheel_effectors], dtype=float
        ).reshape(self.n, m)
        return sigma, omega, speeds

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` (0-based) with ``command`` ``(n, m)`` held; return ``|sigma|^2``
        ``(n,)`` of the new attitude (the pointing error is ``4 atan |sigma|``)."""
        if k != self.k:
            raise ValueError(f"Basilisk flies steps in order: expected step {self.k}, got {k}")
        c = self.constants
        gain, bias, coulomb = self.faults_at(k)
        # The fault and the u_max clip act before the motor; infinite Omega_max leaves the speed
        # saturation to Basilisk (it sees the same step-start speeds).
        u = motor_torque_nm(self._command(command), gain, bias, self.wheel_speed_rad_s, c.u_max_nm, np.inf)
        for e in np.flatnonzero(np.any(coulomb != self._coulomb_now, axis=1)):
            for i, rw in enumerate(self.wheels[e]):
                rw.fCoulomb = float(coulomb[e, i])
            self._coulomb_now[e] = coulomb[e]
        now_ns = k * self.dt_ns
        payload = self._payload
        for cmd_msg, torque in zip(self.cmd_msgs, u.tolist(), strict=True):
            payload.motorTorque = torque
            cmd_msg.write(payload, now_ns)
        self.k = k + 1
        self._advance_to(self.k)
        self.sigma, self.omega_rad_s, self.wheel_speed_rad_s = self._read_states()
        m = c.n_wheels
        self.applied_torque_nm = np.array(
            [[eff.rwOutMsgs[i].read().u_current for i in range(m)] for eff in self.wheel_effectors]
        )
        return norm2(self.sigma)
