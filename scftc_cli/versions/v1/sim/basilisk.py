"""The Basilisk backend: every episode flown on Basilisk's own ``spacecraft`` hub.

The numpy backend (``sim/dynamics.py``) is a vectorized copy of what Basilisk does; this module is
the original, so that ``scftc crosscheck`` can *show* the two agree and users who trust Basilisk
can run any cell on it. One Basilisk simulation holds one rigid hub per episode, each driven by
its own ``extForceTorque`` effector, all in one task stepped at ``dt`` (so Basilisk's default RK4
integrates each hub with one ``dt`` step and then switches to the MRP shadow set when
``|sigma| > 1``, exactly as docs/benchmark.md says).

Task order matters: within a task Basilisk runs models by descending priority,
and the hub integrates from the previous task time to the current one using the torque its
effectors hold *at that moment*. The effector is therefore given a higher priority than the hub,
so it reads the command written before the step and the hub applies it over that same step; with
the default order every command would land one step late.

Basilisk (``bsk`` on PyPI) is an optional extra: importing this module without it raises
``BackendUnavailable`` with the install hint, and nothing else in the product imports it.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.errors import BackendUnavailable
from scftc_cli.sim.mrp import norm2
from scftc_cli.versions.v1.sim.dynamics import RigidPlant

INSTALL_HINT = "Basilisk backend needs the optional extra: pip install 'scftc[basilisk]'"

try:
    from Basilisk.architecture import messaging
    from Basilisk.simulation import extForceTorque, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros
except ImportError as err:  # the optional extra is not installed
    raise BackendUnavailable(INSTALL_HINT) from err

HUB_MASS_KG = 100.0  # arbitrary: with no gravity and no force the translation never moves
EFFECTOR_PRIORITY = 200  # higher than the hub's: the effector runs first in each task pass
HUB_PRIORITY = 100
_PROCESS, _TASK = "scftc_process", "scftc_dynamics"


def basilisk_version() -> str:
    """The installed ``bsk`` version (recorded with cross-checks and benchmarks)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("bsk")
    except PackageNotFoundError:
        return "unknown"


class BasiliskPlant(RigidPlant):
    """A batch of episodes stepped together in one Basilisk simulation, one hub per episode.

    Same interface as ``ReferencePlant`` (same constructor, same actuator fault); the true state
    after each step is read from each hub's ``scStateOutMsg``.
    """

    name = "basilisk"

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.n = len(self.sigma)
        self.dt_ns = int(macros.sec2nano(self.dt_s))
        if self.dt_ns <= 0 or abs(self.dt_ns * 1e-9 - self.dt_s) > 1e-15:
            raise ValueError(f"dt_s = {self.dt_s} is not a whole number of nanoseconds")
        self.sim = SimulationBaseClass.SimBaseClass()
        self.sim.CreateNewProcess(_PROCESS).addTask(self.sim.CreateNewTask(_TASK, self.dt_ns))
        self.hubs, self.effectors, self.cmd_msgs = [], [], []
        for i in range(self.n):
            hub = spacecraft.Spacecraft()
            hub.ModelTag = f"scftc_hub_{i}"
            hub.hub.mHub = HUB_MASS_KG
            hub.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
            hub.hub.IHubPntBc_B = np.diag(self.inertia_kgm2[i]).tolist()
            hub.hub.sigma_BNInit = [[float(v)] for v in self.sigma[i]]
            hub.hub.omega_BN_BInit = [[float(v)] for v in self.omega_rad_s[i]]
            effector = extForceTorque.ExtForceTorque()
            effector.ModelTag = f"scftc_torque_{i}"
            hub.addDynamicEffector(effector)
            cmd_msg = messaging.CmdTorqueBodyMsg()
            effector.cmdTorqueInMsg.subscribeTo(cmd_msg)
            self.sim.AddModelToTask(_TASK, effector, EFFECTOR_PRIORITY)
            self.sim.AddModelToTask(_TASK, hub, HUB_PRIORITY)
            self.hubs.append(hub)
            self.effectors.append(effector)
            self.cmd_msgs.append(cmd_msg)
        self._payload = messaging.CmdTorqueBodyMsgPayload()
        self.sim.InitializeSimulation()
        self.k = 0
        self._advance_to(0)  # the t = 0 pass publishes the initial states and integrates nothing
        self.sigma, self.omega_rad_s = self._read_states()

    def _advance_to(self, k: int) -> None:
        self.sim.ConfigureStopTime(k * self.dt_ns)
        self.sim.ExecuteSimulation()

    def _read_states(self) -> tuple[np.ndarray, np.ndarray]:
        states = [hub.scStateOutMsg.read() for hub in self.hubs]
        sigma = np.array([s.sigma_BN for s in states], dtype=float).reshape(self.n, 3)
        omega = np.array([s.omega_BN_B for s in states], dtype=float).reshape(self.n, 3)
        return sigma, omega

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Hold the faulty actuators' torque for ``command`` ``(n, 3)`` over one step; return
        ``|sigma|^2`` ``(n,)`` of the new state."""
        torque_nm = self.torque_nm(np.asarray(command, dtype=float))
        now_ns = self.k * self.dt_ns
        payload = self._payload
        for cmd_msg, torque in zip(self.cmd_msgs, torque_nm.tolist(), strict=True):
            payload.torqueRequestBody = torque
            cmd_msg.write(payload, now_ns)
        self.k += 1
        self._advance_to(self.k)
        self.sigma, self.omega_rad_s = self._read_states()
        return norm2(self.sigma)
