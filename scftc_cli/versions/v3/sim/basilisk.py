"""The v3 plant flown on Basilisk: the independent check of ``dynamics.py``, effector by effector.

One Basilisk simulation holds, per episode, v2's hub and wheels (built as v2's Basilisk backend
builds them) on a translating ``spacecraft`` with a point-mass Earth, plus one Basilisk module per
environment term:

- ``GravityGradientEffector`` (planet ``earth``, ``mu`` set to ours: the factory's is 398600.436);
- ``magneticFieldCenteredDipole`` with IGRF-2020's ``g10, g11, h11`` set explicitly and a constant
  planet message whose ``J20002Pfix`` is ``R3(theta)``: the Earth-fixed frame frozen at the episode's
  Earth angle (Basilisk's ``simSetPlanetEnvironment.centeredDipoleMagField`` writes other numbers,
  -30926 / -2318 / 5817 nT, under an "IGRF 2020" comment: not IGRF-2020's first-degree terms);
- ``MtbEffector`` for the rods: three rods, ``GtMatrix_B`` row-major (3 x numMTB), here
  ``diag(rod gains)`` so a fault is a column of ``G_t`` (changed at the onset), commands
  ``clip(a, -1, 1) m_max`` with ``maxMtbDipoles = m_max`` (its own clip is then a no-op);
- a second ``MtbEffector`` holding the residual dipole as a constant command (``G_t = I``);
- ``facetSRPDynamicEffector`` with one facet (area, normal, centre of pressure, ``rho_d``,
  ``rho_s``) and a Sun message rewritten each step at 1 AU along the episode's Sun direction from
  the spacecraft's position at the step's start, so the Sun's direction is fixed as in the
  reference (within a step the spacecraft moves < 4 km: 2.5e-8 rad of parallax).

Task order (descending priority): the wheel effector (latches the command, as v2), the hub
(integrates ``[t_k, t_k + dt]``, its dynamic effectors evaluated at every RK4 stage), then the
field module, which publishes the field at the new position: the field over a step is the one at
its start, held, as in the reference. The hub's orbit is integrated by Basilisk's RK4 (the
reference uses the closed form): measured, the two orbits stay within ~1e-9 relative over an
episode.

Basilisk (``bsk``) is an optional extra: importing this module without it raises
``BackendUnavailable`` with the install hint.
"""

from __future__ import annotations

import math

import numpy as np

from scftc_cli.errors import BackendUnavailable
from scftc_cli.sim.mrp import norm2
from scftc_cli.versions.v2.sim.dynamics import motor_torque_nm
from scftc_cli.versions.v3.sim.dynamics import V3PlantBase
from scftc_cli.versions.v3.sim.environment import latitude_trig, orbit_velocity_m_s, to_body
from scftc_cli.versions.v3.sim.mission import MissionMixin

INSTALL_HINT = "Basilisk backend needs the optional extra: pip install 'scftc[basilisk]'"

try:
    from Basilisk.architecture import messaging
    from Basilisk.simulation import (
        GravityGradientEffector,
        MtbEffector,
        facetSRPDynamicEffector,
        magneticFieldCenteredDipole,
        reactionWheelStateEffector,
        spacecraft,
    )
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeGravBody, simIncludeRW
except ImportError as err:  # the optional extra is not installed
    raise BackendUnavailable(INSTALL_HINT) from err

ASTRONOMICAL_UNIT_M = 149597870700.0  # Basilisk's AstU: at this distance its pressure is flux / c
HUB_MASS_KG = 1e12
"""The translation only carries the orbit: so heavy a hub makes the solar pressure's force on the
orbit, which the reference's Kepler orbit leaves out (~7 cm over an episode for 100 kg), vanish.
The mass enters nothing rotational here (the centre of mass is at B)."""
WHEEL_PRIORITY, HUB_PRIORITY, FIELD_PRIORITY = 200, 100, 50
RESIDUAL_DIPOLE_CAP_AM2 = 1e6  # the residual's MtbEffector must never clip it
_PROCESS, _TASK = "scftc_v3_process", "scftc_v3_dynamics"


def _column(v) -> list[list[float]]:
    return [[float(x)] for x in v]


class BasiliskV3Plant(V3PlantBase):
    """A batch of v3 episodes stepped together in one Basilisk simulation, one spacecraft each.

    Same constructor and ``step`` as ``V3Plant`` (see ``V3PlantBase``). After each step the state
    is read back from Basilisk (``sigma``, ``omega_rad_s``, ``wheel_speed_rad_s``, ``position_m``,
    ``field_n_t`` from the field module; ``field_b_t`` rotates it with ``sigma``), and
    ``external_torque_nm`` is the sum of Basilisk's effectors evaluated at the step's start state.
    """

    name = "basilisk"

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        c = self.constants
        self.dt_ns = int(macros.sec2nano(c.dt_s))
        if self.dt_ns <= 0 or abs(self.dt_ns * 1e-9 - c.dt_s) > 1e-15:
            raise ValueError(f"dt_s = {c.dt_s} is not a whole number of nanoseconds")
        self.sim = SimulationBaseClass.SimBaseClass()
        self.sim.CreateNewProcess(_PROCESS).addTask(self.sim.CreateNewTask(_TASK, self.dt_ns))
        self.gravity = simIncludeGravBody.gravBodyFactory()
        earth = self.gravity.createEarth()
        earth.isCentralBody = True
        earth.mu = c.environment.mu_m3_s2
        self.earth_name = earth.planetName
        self.episodes = [self._build_episode(e) for e in range(self.n)]
        self._payload = messaging.ArrayMotorTorqueMsgPayload()
        self._coulomb_now = np.full((self.n, c.wheels.n_wheels), c.wheels.coulomb_nm)
        self._rod_gain_now = np.ones((self.n, 3))
        self.sim.InitializeSimulation()
        self.k = 0
        self._advance_to(0)  # publishes the initial states and the field at the initial position
        self._read_states()

    def _build_episode(self, e: int) -> dict:
        c = self.constants
        w, env_c, env = c.wheels, c.environment, self.env
        sc = spacecraft.Spacecraft()
        sc.ModelTag = f"scftc_v3_hub_{e}"
        sc.hub.mHub = HUB_MASS_KG
        sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
        sc.hub.IHubPntBc_B = self.mass.total_inertia_kgm2[e].tolist()  # I_tot, as v2's backend
        sc.hub.sigma_BNInit = _column(self.sigma[e])
        sc.hub.omega_BN_BInit = _column(self.omega_rad_s[e])
        cos_u, sin_u = latitude_trig(
            env.arg_latitude0_rad[e : e + 1], self.geometry.mean_motion[e : e + 1], 0.0
        )
        velocity = orbit_velocity_m_s(
            env.semi_major_axis_m[e : e + 1], self.geometry.mean_motion[e : e + 1],
            self.geometry.p[e : e + 1], self.geometry.q[e : e + 1], cos_u, sin_u,
        )[0]  # fmt: skip
        sc.hub.r_CN_NInit = _column(self.position_m[e])
        sc.hub.v_CN_NInit = _column(velocity)
        self.gravity.addBodiesTo(sc)

        factory = simIncludeRW.rwFactory()
        wheels = []
        for i, axis in enumerate(w.axes):
            rw = factory.create(
                "custom", axis.tolist(), RWModel=messaging.BalancedWheels, maxMomentum=float(w.h_max_nms),
                Omega_max=float(w.omega_max_rpm), u_max=float(w.u_max_nm), useRWfriction=True,
                fCoulomb=float(w.coulomb_nm), cViscous=float(w.viscous_nms),
            )  # fmt: skip
            rw.omegaLimitCycle = float(w.omega_linear_rad_s)
            rw.gsHat_B = _column(axis)
            rw.Omega = float(self.wheel_speed_rad_s[e, i])
            wheels.append(rw)
        rw_effector = reactionWheelStateEffector.ReactionWheelStateEffector()
        factory.addToSpacecraft(f"scftc_v3_wheels_{e}", rw_effector, sc)
        rw_cmd = messaging.ArrayMotorTorqueMsg()
        rw_effector.rwMotorCmdInMsg.subscribeTo(rw_cmd)

        gg = GravityGradientEffector.GravityGradientEffector()
        gg.ModelTag = f"scftc_v3_gg_{e}"
        gg.addPlanetName(self.earth_name)
        sc.addDynamicEffector(gg)

        field = magneticFieldCenteredDipole.MagneticFieldCenteredDipole()
        field.ModelTag = f"scftc_v3_field_{e}"
        field.g10, field.g11, field.h11 = env_c.g10_t, env_c.g11_t, env_c.h11_t
        field.planetRadius = env_c.field_radius_m
        field.addSpacecraftToModel(sc.scStateOutMsg)
        planet = messaging.SpicePlanetStateMsgPayload()
        theta = float(env.earth_angle_rad[e])
        cos, sin = math.cos(theta), math.sin(theta)
        planet.J20002Pfix = [[cos, sin, 0.0], [-sin, cos, 0.0], [0.0, 0.0, 1.0]]
        planet_msg = messaging.SpicePlanetStateMsg().write(planet)
        field.planetPosInMsg.subscribeTo(planet_msg)

        rods = MtbEffector.MtbEffector()
        rods.ModelTag = f"scftc_v3_rods_{e}"
        rod_params = messaging.MTBArrayConfigMsg().write(
            self._rod_params(np.ones(3), env_c.rod_dipole_max_am2)
        )
        rods.mtbParamsInMsg.subscribeTo(rod_params)
        rod_cmd = messaging.MTBCmdMsg().write(self._dipole_cmd(np.zeros(3)))
        rods.mtbCmdInMsg.subscribeTo(rod_cmd)
        rods.magInMsg.subscribeTo(field.envOutMsgs[0])
        sc.addDynamicEffector(rods)

        residual = MtbEffector.MtbEffector()
        residual.ModelTag = f"scftc_v3_residual_{e}"
        residual_params = messaging.MTBArrayConfigMsg().write(
            self._rod_params(np.ones(3), RESIDUAL_DIPOLE_CAP_AM2)
        )
        residual.mtbParamsInMsg.subscribeTo(residual_params)
        residual_cmd = messaging.MTBCmdMsg().write(self._dipole_cmd(env.residual_dipole_am2[e]))
        residual.mtbCmdInMsg.subscribeTo(residual_cmd)
        residual.magInMsg.subscribeTo(field.envOutMsgs[0])
        sc.addDynamicEffector(residual)

        srp = facetSRPDynamicEffector.FacetSRPDynamicEffector()
        srp.ModelTag = f"scftc_v3_srp_{e}"
        srp.setNumFacets(1)
        srp.setNumArticulatedFacets(0)
        srp.addFacet(
            float(env.facet_area_m2[e]), np.eye(3), np.array(env.facet_normal[e]), np.array([0.0, 0.0, 1.0]),
            np.array(env.facet_cop_m[e]), float(env_c.facet_diffuse), float(env_c.facet_specular),
        )  # fmt: skip
        sun_msg = messaging.SpicePlanetStateMsg().write(self._sun(e, self.position_m[e]))
        srp.sunInMsg.subscribeTo(sun_msg)
        sc.addDynamicEffector(srp)

        self.sim.AddModelToTask(_TASK, rw_effector, WHEEL_PRIORITY)
        self.sim.AddModelToTask(_TASK, sc, HUB_PRIORITY)
        self.sim.AddModelToTask(_TASK, field, FIELD_PRIORITY)
        return {
            "hub": sc, "rw": rw_effector, "wheels": wheels, "rw_cmd": rw_cmd, "gg": gg, "field": field,
            "planet_msg": planet_msg, "rods": rods, "rod_params": rod_params, "rod_cmd": rod_cmd,
            "residual": residual, "residual_params": residual_params, "residual_cmd": residual_cmd,
            "srp": srp, "sun_msg": sun_msg,
        }  # fmt: skip

    @staticmethod
    def _rod_params(gain: np.ndarray, cap: float):
        params = messaging.MTBArrayConfigMsgPayload()
        params.numMTB = 3
        gt = np.diag(np.asarray(gain, dtype=float))
        params.GtMatrix_B = gt.reshape(-1).tolist()  # row-major 3 x numMTB
        params.maxMtbDipoles = [float(cap)] * 3
        return params

    @staticmethod
    def _dipole_cmd(dipole: np.ndarray):
        cmd = messaging.MTBCmdMsgPayload()
        cmd.mtbDipoleCmds = [float(x) for x in dipole]
        return cmd

    def _sun(self, e: int, position: np.ndarray):
        sun = messaging.SpicePlanetStateMsgPayload()
        sun.PositionVector = (np.asarray(position) + ASTRONOMICAL_UNIT_M * self.env.sun_direction[e]).tolist()
        return sun

    def _advance_to(self, k: int) -> None:
        self.sim.ConfigureStopTime(k * self.dt_ns)
        self.sim.ExecuteSimulation()

    def _read_states(self) -> None:
        states = [ep["hub"].scStateOutMsg.read() for ep in self.episodes]
        n, m = self.n, self.constants.wheels.n_wheels
        self.sigma = np.array([s.sigma_BN for s in states], dtype=float).reshape(n, 3)
        self.omega_rad_s = np.array([s.omega_BN_B for s in states], dtype=float).reshape(n, 3)
        self.position_m = np.array([s.r_BN_N for s in states], dtype=float).reshape(n, 3)
        self.wheel_speed_rad_s = np.array(
            [ep["rw"].rwSpeedOutMsg.read().wheelSpeeds[:m] for ep in self.episodes], dtype=float
        ).reshape(n, m)
        self.field_n_t = np.array(
            [ep["field"].envOutMsgs[0].read().magField_N for ep in self.episodes], dtype=float
        ).reshape(n, 3)
        self.field_b_t = to_body(self.sigma, self.field_n_t)

    def effector_torques(self) -> dict[str, np.ndarray]:
        """Each environment effector's torque ``(n, 3)`` N m at the current state, as Basilisk
        computes it (``computeForceTorque`` called now, on the hub's current states and messages;
        the Sun message is first rewritten from the current position)."""
        for e, ep in enumerate(self.episodes):
            ep["sun_msg"].write(self._sun(e, self.position_m[e]), self.k * self.dt_ns)
        out = {}
        for name in ("gg", "rods", "residual", "srp"):
            rows = []
            for ep in self.episodes:
                ep[name].computeForceTorque(self.time_s, self.constants.dt_s)
                rows.append(np.asarray(ep[name].torqueExternalPntB_B, dtype=float).reshape(3))
            out[name] = np.array(rows)
        return out

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` with ``command`` ``(n, m + 3)`` held; return ``|sigma|^2`` ``(n,)``."""
        if k != self.k:
            raise ValueError(f"Basilisk flies steps in order: expected step {self.k}, got {k}")
        c = self.constants
        w, m = c.wheels, c.wheels.n_wheels
        command = self._command(command)
        gain, bias, coulomb, rod_gain = self.faults_at(k)
        u = motor_torque_nm(command[:, :m], gain, bias, self.wheel_speed_rad_s, w.u_max_nm, np.inf)
        rod_cmd = np.clip(command[:, m:], -1.0, 1.0) * c.environment.rod_dipole_max_am2
        now_ns = k * self.dt_ns
        for e, ep in enumerate(self.episodes):
            if np.any(coulomb[e] != self._coulomb_now[e]):
                for i, rw in enumerate(ep["wheels"]):
                    rw.fCoulomb = float(coulomb[e, i])
                self._coulomb_now[e] = coulomb[e]
            if np.any(rod_gain[e] != self._rod_gain_now[e]):
                ep["rod_params"].write(
                    self._rod_params(rod_gain[e], c.environment.rod_dipole_max_am2), now_ns
                )
                self._rod_gain_now[e] = rod_gain[e]
            self._payload.motorTorque = u[e].tolist()
            ep["rw_cmd"].write(self._payload, now_ns)
            ep["rod_cmd"].write(self._dipole_cmd(rod_cmd[e]), now_ns)
        torques = self.effector_torques()
        self.external_torque_nm = ((torques["gg"] + torques["rods"]) + torques["residual"]) + torques["srp"]
        self.dipole_am2 = rod_gain * rod_cmd
        self.k = k + 1
        self._advance_to(self.k)
        self._read_states()
        self.time_s = self.k * c.dt_s
        self.applied_torque_nm = np.array(
            [[ep["rw"].rwOutMsgs[i].read().u_current for i in range(m)] for ep in self.episodes]
        )
        return norm2(self.sigma)


class MissionBasiliskPlant(MissionMixin, BasiliskV3Plant):
    """The Basilisk backend with the mission's episode mapping and target error (``mission.py``)."""
