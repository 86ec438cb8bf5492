"""The v3 plant's numpy reference: v2's hub and wheels in orbit, with environment and rod torques.

The readable truth of the v3 plant; the fused kernel (``fast.py``) repeats its floating-point
operations in the same order, and Basilisk (``basilisk.py``) is the independent check. The state
of an episode is ``(sigma, omega_rad_s, wheel_speed_rad_s)`` as in v2, plus the orbit time
``t = k dt`` (shared by the batch; the position is the closed form of ``environment.py``). v2's
equations gain one term, the external torque ``L`` on the hub:

    D w_dot = -w x (I_tot w + sum_i Js Omega_i g_i) - sum_i g_i (u_i + fr_i) + L
    Omega_dot_i = (u_i + fr_i) / Js - g_i . w_dot
    L = 3 mu / |r|^3 (r_hat_B x I_tot r_hat_B) + (m_rods + m_res) x B_B + c x F_srp(s_B)

When each input of ``L`` is evaluated (chosen to be Basilisk's, so the two can be compared to
rounding, and each also the natural physical choice at ``dt = 0.5`` s):

- the attitude: at every RK4 stage (``B_B = C(sigma) B_N``, ``r_hat_B``, ``s_B`` rotate with the
  stage's attitude, as Basilisk's effectors read the hub's stage state); the hub turns up to
  ~1 deg/s, 0.5 deg in a step, so holding the attitude would be a first-order error;
- the position: at every stage's time, ``t_k``, ``t_k + dt/2``, ``t_k + dt``, from the closed form
  (Basilisk's gravity gradient reads the stage position);
- the field ``B_N``: held over the step at its value at the step's start, as Basilisk's field
  module publishes it once per task step and ``MtbEffector`` reads that message at every stage.
  The field turns with the orbit, ~0.06 deg in a step: holding it is a zero-order hold like the
  commands', of the order of the field's own model error;
- the rods' dipoles and the motor torques: held (they are the step's command).

Faults (per wheel, from ``onset_step`` on; healthy before it): v2's gain, bias and Coulomb
friction multiplier, plus v3's friction ramp (the multiplier grows linearly from 1 at the onset
to ``friction_ramp_end`` at the episode's end, evaluated at each step's start), friction bursts
(during a burst, ``[start, end)`` in steps, the wheel's Coulomb friction is multiplied by
``burst_multiplier``), and the rods' gains (1 healthy, -1 reversed, 0 dead, 0.5 half). A wheel's
Coulomb friction over step ``k`` is ``fC0 ((multiplier ramp(k)) burst(k))``.

Every sum is written out in a fixed order (no ``@``, ``einsum`` or ``sum``) so the kernel can
reproduce it bit for bit. Arrays are batch-first: ``(n, 3)`` vectors, ``(n, m)`` per wheel
(``m = 4``), ``(n, 3, 3)`` per-episode matrices.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass
from typing import Any, Self

import numpy as np

from scftc_cli.sim.elementary import cosine, sine
from scftc_cli.sim.mrp import cross, norm2, shadow_switch
from scftc_cli.sim.testbed import Plant
from scftc_cli.versions.v2.sim.dynamics import (
    MassProperties,
    WheelConstants,
    friction_torque_nm,
    motor_torque_nm,
    mrp_rate,
)
from scftc_cli.versions.v2.spec import V2, ReactionWheelPlant
from scftc_cli.versions.v3.sim.environment import (
    Environment,
    EnvironmentConstants,
    advance_trig,
    dipole_field_t,
    earth_dipole_n,
    gravity_gradient_terms,
    gravity_gradient_torque_nm,
    latitude_trig,
    magnetic_torque_nm,
    mean_motion_rad_s,
    orbit_axes,
    orbit_position_m,
    rod_dipole_am2,
    srp_torque_nm,
    to_body,
)

N_RODS = 3
assert isinstance(V2.plant, ReactionWheelPlant)
V2_WHEELS = WheelConstants.of(V2.plant)
"""scftc-v2's wheel plant, which scftc-v3 flies unchanged."""


@dataclass(frozen=True)
class V3Constants:
    """The v3 plant's numbers: v2's wheel plant, the environment, and the episode's length.

    Attributes:
        wheels: v2's hub and wheel constants (``dt`` included), unchanged.
        environment: Orbit, field, solar pressure and rod constants.
        episode_steps: Steps in an episode (1200 s at 0.5 s): the friction ramp ends there.
    """

    wheels: WheelConstants = V2_WHEELS
    environment: EnvironmentConstants = EnvironmentConstants()
    episode_steps: int = 2400

    def __post_init__(self) -> None:
        if self.episode_steps < 1:
            raise ValueError("episode_steps must be >= 1")

    @property
    def dt_s(self) -> float:
        return self.wheels.dt_s

    @property
    def action_dim(self) -> int:
        """Wheel commands then rod commands: ``m + 3``."""
        return self.wheels.n_wheels + N_RODS


@dataclass(frozen=True)
class PlantFault:
    """Per-episode actuator faults of ``m`` wheels and 3 rods, in force from ``onset_step`` on.

    Attributes:
        gain: ``(n, m)`` wheel effectiveness (1 healthy, 0 dead, negative reversed; a ``double``
            fault is one wheel at 0 and another below 1).
        bias: ``(n, m)`` wheel offset, a fraction of ``u_max``.
        friction_multiplier: ``(n, m)`` constant Coulomb multiplier (v2's ``friction``; 1 healthy).
        friction_ramp_end: ``(n, m)`` multiplier the ramp reaches at the episode's end (1: none).
        burst_multiplier: ``(n, m)`` Coulomb multiplier during bursts (1: none).
        burst_start_step, burst_end_step: ``(n, b)`` int, the bursts ``[start, end)`` in steps;
            pad with empty bursts (``start == end``). They only act from the onset on.
        rod_gain: ``(n, 3)`` each rod's gain (1 healthy, -1 reversed, 0 dead, 0.5 half dipole).
        onset_step: ``(n,)`` int, the first faulted step.
        gain_creep_per_step: ``(n, m)`` how fast a wheel's effectiveness creeps down: over step
            ``k`` its gain is ``gain max(1 + rate (k - onset), floor)`` (``scftc-v4``'s
            ``incipient``; 0: none, v3's faults).
        gain_creep_floor: ``(n, m)`` where the creep stops (0: at failure; v3's faults: 0).
        burst_gain: ``(n, m)`` a wheel's gain factor during a burst (0: the wheel drops out;
            ``scftc-v4``'s ``intermittent``; 1: none, v3's faults).

    A wheel's gain over step ``k`` from the onset on is ``gain (creep(k) flicker(k))``
    (``gain_at``); with v3's faults both factors are exactly 1, so v3's numbers keep their bits.
    """

    gain: np.ndarray
    bias: np.ndarray
    friction_multiplier: np.ndarray
    friction_ramp_end: np.ndarray
    burst_multiplier: np.ndarray
    burst_start_step: np.ndarray
    burst_end_step: np.ndarray
    rod_gain: np.ndarray
    onset_step: np.ndarray
    gain_creep_per_step: np.ndarray | None = None
    gain_creep_floor: np.ndarray | None = None
    burst_gain: np.ndarray | None = None

    def __post_init__(self) -> None:
        n, m = np.shape(self.gain)
        if self.gain_creep_per_step is None:
            object.__setattr__(self, "gain_creep_per_step", np.zeros((n, m)))
        if self.gain_creep_floor is None:
            object.__setattr__(self, "gain_creep_floor", np.zeros((n, m)))
        if self.burst_gain is None:
            object.__setattr__(self, "burst_gain", np.ones((n, m)))
        b = np.shape(self.burst_start_step)[1] if np.ndim(self.burst_start_step) == 2 else -1
        shapes = {
            "gain": (n, m), "bias": (n, m), "friction_multiplier": (n, m), "friction_ramp_end": (n, m),
            "burst_multiplier": (n, m), "burst_start_step": (n, b), "burst_end_step": (n, b),
            "rod_gain": (n, N_RODS), "onset_step": (n,), "gain_creep_per_step": (n, m),
            "gain_creep_floor": (n, m), "burst_gain": (n, m),
        }  # fmt: skip
        for name, shape in shapes.items():
            dtype = np.int64 if name in ("burst_start_step", "burst_end_step", "onset_step") else np.float64
            value = np.array(getattr(self, name), dtype=dtype, order="C")
            if value.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {value.shape}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if np.any(self.burst_end_step < self.burst_start_step):
            raise ValueError("a burst must not end before it starts")

    @property
    def n(self) -> int:
        return len(self.onset_step)

    def in_burst(self, k: int) -> np.ndarray:
        """``(n, 1)`` bool: step ``k`` falls inside one of the episode's bursts."""
        return np.any((self.burst_start_step <= k) & (k < self.burst_end_step), axis=1)[:, None]

    def gain_at(self, k: int) -> np.ndarray:
        """``(n, m)`` each wheel's effectiveness over step ``k``: 1 before the onset, then ``gain
        (max(1 + creep (k - onset), floor) flicker)`` with ``flicker`` the ``burst_gain`` inside a burst
        and 1 outside (the fused kernel's order, ``fast._step_episode``)."""
        active = (k >= self.onset_step)[:, None]
        since = (k - self.onset_step)[:, None].astype(np.float64)
        rate, floor, burst = self.gain_creep_per_step, self.gain_creep_floor, self.burst_gain
        assert rate is not None and floor is not None and burst is not None  # filled in __post_init__
        creep = np.maximum(1.0 + rate * since, floor)
        flicker = np.where(self.in_burst(k), burst, 1.0)
        return np.where(active, self.gain * (creep * flicker), 1.0)

    @classmethod
    def healthy(cls, n: int, m: int = 4, bursts: int = 1) -> PlantFault:
        """``n`` episodes with nothing wrong (room for ``bursts`` empty bursts each)."""
        return cls(
            gain=np.ones((n, m)),
            bias=np.zeros((n, m)),
            friction_multiplier=np.ones((n, m)),
            friction_ramp_end=np.ones((n, m)),
            burst_multiplier=np.ones((n, m)),
            burst_start_step=np.zeros((n, bursts), dtype=np.int64),
            burst_end_step=np.zeros((n, bursts), dtype=np.int64),
            rod_gain=np.ones((n, N_RODS)),
            onset_step=np.zeros(n, dtype=np.int64),
        )


@dataclass(frozen=True)
class OrbitGeometry:
    """Per-episode constants derived once from an ``Environment`` and shared by every backend (so
    each one integrates the same doubles; their transcendental functions are numpy's, here).

    Attributes:
        mean_motion: ``n`` ``(n,)`` rad/s.
        p, q: In-plane unit vectors ``(n, 3)`` (``environment.orbit_axes``).
        half_cos, half_sin: ``cos(n dt / 2)``, ``sin(n dt / 2)`` ``(n,)``: the mid-step position
            is the step start's turned by half a step (``advance_trig``).
        dipole_n: The field's dipole vector, inertial ``(n, 3)`` tesla.
        pressure_area: ``P A`` ``(n,)`` N.
    """

    mean_motion: np.ndarray
    p: np.ndarray
    q: np.ndarray
    half_cos: np.ndarray
    half_sin: np.ndarray
    dipole_n: np.ndarray
    pressure_area: np.ndarray

    @classmethod
    def of(cls, env: Environment, constants: V3Constants) -> OrbitGeometry:
        c = constants.environment
        mean_motion = mean_motion_rad_s(env.semi_major_axis_m, c.mu_m3_s2)
        p, q = orbit_axes(env.inclination_rad, env.raan_rad)
        half = mean_motion * (0.5 * constants.dt_s)
        return cls(
            mean_motion=mean_motion,
            p=np.ascontiguousarray(p),
            q=np.ascontiguousarray(q),
            half_cos=cosine(half),
            half_sin=sine(half),
            dipole_n=np.ascontiguousarray(earth_dipole_n(env.earth_angle_rad, c)),
            pressure_area=c.srp_pressure_n_m2 * env.facet_area_m2,
        )


def external_torque_nm(
    sigma: np.ndarray,
    r_hat_n: np.ndarray,
    gg_coefficient: np.ndarray,
    field_n: np.ndarray,
    dipole_b: np.ndarray,
    env: Environment,
    geometry: OrbitGeometry,
    inertia: np.ndarray,
    constants: EnvironmentConstants,
) -> np.ndarray:
    """``L`` ``(n, 3)`` N m at attitude ``sigma`` ``(n, 3)``: gravity gradient plus magnetic (rods and
    residual dipole, ``dipole_b`` ``(n, 3)`` A m^2, in the inertial field ``field_n`` ``(n, 3)`` T)
    plus solar pressure, summed in that order. ``r_hat_n`` ``(n, 3)`` and ``gg_coefficient`` ``(n,)``
    are ``environment.gravity_gradient_terms`` of the position."""
    gravity = gravity_gradient_torque_nm(to_body(sigma, r_hat_n), gg_coefficient, inertia)
    magnetic = magnetic_torque_nm(dipole_b, to_body(sigma, field_n))
    solar = srp_torque_nm(
        to_body(sigma, env.sun_direction), env.facet_normal, env.facet_cop_m, geometry.pressure_area,
        constants.facet_specular, constants.facet_diffuse,
    )  # fmt: skip
    return (gravity + magnetic) + solar


def _matvec(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``m v`` for ``(n, 3, 3)`` by ``(n, 3)``, each row summed left to right."""
    return m[:, :, 0] * v[:, 0:1] + m[:, :, 1] * v[:, 1:2] + m[:, :, 2] * v[:, 2:3]


def _along_axes(axes: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``sum_i x_i g_i`` ``(n, 3)`` for per-wheel ``x`` ``(n, m)``, summed over wheels in order."""
    out = x[:, 0:1] * axes[0]
    for i in range(1, len(axes)):
        out = out + x[:, i : i + 1] * axes[i]
    return out


def _onto_axes(axes: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``g_i . v`` ``(n, m)`` for hub vectors ``v`` ``(n, 3)``."""
    return v[:, 0:1] * axes[:, 0] + v[:, 1:2] * axes[:, 1] + v[:, 2:3] * axes[:, 2]


def derivatives(
    sigma: np.ndarray,
    omega_rad_s: np.ndarray,
    wheel_speed_rad_s: np.ndarray,
    motor_nm: np.ndarray,
    coulomb_nm: np.ndarray,
    external_nm: np.ndarray,
    mass: MassProperties,
    constants: WheelConstants,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """v2's derivatives plus the external torque ``external_nm`` ``(n, 3)`` on the hub:
    ``(sigma_dot (n, 3), omega_dot (n, 3) rad/s^2, wheel_accel (n, m) rad/s^2)``."""
    axes, js = constants.axes, constants.js_kgm2
    torque = motor_nm + friction_torque_nm(
        wheel_speed_rad_s, coulomb_nm, constants.viscous_nms, constants.omega_linear_rad_s
    )
    momentum = _matvec(mass.total_inertia_kgm2, omega_rad_s) + _along_axes(axes, js * wheel_speed_rad_s)
    rhs = (-cross(omega_rad_s, momentum) - _along_axes(axes, torque)) + external_nm
    omega_dot = _matvec(mass.coupled_inertia_inv, rhs)
    wheel_accel = torque / js - _onto_axes(axes, omega_dot)
    return mrp_rate(sigma, omega_rad_s), omega_dot, wheel_accel


@dataclass(frozen=True)
class StepInputs:
    """What one step holds fixed or evaluates per stage, from ``V3PlantBase.step_inputs``.

    Attributes:
        motor_nm: ``(n, m)`` motor torques (held).
        coulomb_nm: ``(n, m)`` Coulomb friction per wheel (held).
        dipole_am2: ``(n, 3)`` rods' plus residual dipole, body frame (held).
        field_n: ``(n, 3)`` inertial field at the step's start (held).
        r_hat_n: Three ``(n, 3)`` unit position vectors: at ``t_k``, ``t_k + dt/2``, ``t_k + dt``.
        gg_coefficient: Three ``(n,)`` ``3 mu / |r|^3`` at the same times.
        position_end_m: ``(n, 3)`` position at ``t_k + dt`` (the next step's start).
    """

    motor_nm: np.ndarray
    coulomb_nm: np.ndarray
    dipole_am2: np.ndarray
    field_n: np.ndarray
    r_hat_n: tuple[np.ndarray, np.ndarray, np.ndarray]
    gg_coefficient: tuple[np.ndarray, np.ndarray, np.ndarray]
    position_end_m: np.ndarray


def rk4_step(
    sigma: np.ndarray,
    omega_rad_s: np.ndarray,
    wheel_speed_rad_s: np.ndarray,
    inputs: StepInputs,
    env: Environment,
    geometry: OrbitGeometry,
    mass: MassProperties,
    constants: V3Constants,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One classic RK4 step, then the shadow switch: ``(sigma, omega, wheel_speed)`` at ``t_k + dt``
    and the external torque ``L`` ``(n, 3)`` of the first stage (at the step's start state)."""
    dt = constants.dt_s
    wheels, environment = constants.wheels, constants.environment

    def f(s, w, o, stage):
        external = external_torque_nm(
            s, inputs.r_hat_n[stage], inputs.gg_coefficient[stage], inputs.field_n, inputs.dipole_am2,
            env, geometry, mass.total_inertia_kgm2, environment,
        )  # fmt: skip
        rates = derivatives(s, w, o, inputs.motor_nm, inputs.coulomb_nm, external, mass, wheels)
        return (*rates, external)

    h = 0.5 * dt
    k1s, k1w, k1o, external = f(sigma, omega_rad_s, wheel_speed_rad_s, 0)
    k2s, k2w, k2o, _ = f(sigma + h * k1s, omega_rad_s + h * k1w, wheel_speed_rad_s + h * k1o, 1)
    k3s, k3w, k3o, _ = f(sigma + h * k2s, omega_rad_s + h * k2w, wheel_speed_rad_s + h * k2o, 1)
    k4s, k4w, k4o, _ = f(sigma + dt * k3s, omega_rad_s + dt * k3w, wheel_speed_rad_s + dt * k3o, 2)
    c = dt / 6.0
    sigma_next = sigma + c * (k1s + 2.0 * k2s + 2.0 * k3s + k4s)
    omega_next = omega_rad_s + c * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
    wheel_next = wheel_speed_rad_s + c * (k1o + 2.0 * k2o + 2.0 * k3o + k4o)
    return shadow_switch(sigma_next), omega_next, wheel_next, external


def _as_batch(name: str, x: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    out: np.ndarray = np.array(x, dtype=np.float64, order="C")  # a private copy: the plant owns its state
    if out.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {out.shape}")
    return out


class V3PlantBase(Plant):
    """A batch of ``n`` v3 episodes, advanced one control step at a time (every backend).

    Args:
        sigma0: Initial hub attitudes (MRP, inertial) ``(n, 3)``.
        omega0_rad_s: Initial hub body rates ``(n, 3)``.
        wheel_speed0_rad_s: Initial wheel speeds relative to the hub ``(n, m)``.
        inertia_scale: Hub inertia scale ``f`` ``(n,)`` (v2's; a mass property, from step 0).
        fault: The actuator faults (``PlantFault``).
        environment: The orbit and disturbances (``Environment``).
        constants: The plant's numbers; scftc-v3's when omitted.

    Attributes:
        sigma, omega_rad_s, wheel_speed_rad_s: The true state after the last step.
        time_s: The orbit time of that state, ``k dt`` after ``k`` steps.
        position_m: Inertial position at ``time_s`` ``(n, 3)``.
        field_n_t, field_b_t: The field at ``position_m``, inertial and in the body frame of
            ``sigma`` ``(n, 3)`` tesla (what a perfect magnetometer reads; held over the next step).
        applied_torque_nm: Motor torque each wheel applied over the last step ``(n, m)``.
        dipole_am2: Rods' dipoles over the last step, after their faults ``(n, 3)`` (no residual).
        external_torque_nm: ``L`` at the last step's start state ``(n, 3)``: environment plus rods.
    """

    def __init__(
        self,
        sigma0: np.ndarray,
        omega0_rad_s: np.ndarray,
        wheel_speed0_rad_s: np.ndarray,
        inertia_scale: np.ndarray,
        fault: PlantFault,
        environment: Environment,
        constants: V3Constants | None = None,
    ) -> None:
        self.constants = V3Constants() if constants is None else constants
        w = self.constants.wheels
        n, m = len(sigma0), w.n_wheels
        self.n = n
        self.sigma = _as_batch("sigma0", sigma0, (n, 3))
        self.omega_rad_s = _as_batch("omega0_rad_s", omega0_rad_s, (n, 3))
        self.wheel_speed_rad_s = _as_batch("wheel_speed0_rad_s", wheel_speed0_rad_s, (n, m))
        self.inertia_scale = _as_batch("inertia_scale", inertia_scale, (n,))
        if np.any(self.inertia_scale <= 0.0):
            raise ValueError("inertia_scale must be > 0")
        if fault.n != n or fault.gain.shape[1] != m:
            raise ValueError(f"fault must hold {n} episodes of {m} wheels")
        if environment.n != n:
            raise ValueError(f"environment must hold {n} episodes, got {environment.n}")
        self.fault, self.env = fault, environment
        self.mass = MassProperties.of(w, self.inertia_scale)
        self.geometry = OrbitGeometry.of(environment, self.constants)
        steps_left = np.maximum(self.constants.episode_steps - fault.onset_step, 1).astype(np.float64)
        self.ramp_rate = np.ascontiguousarray((fault.friction_ramp_end - 1.0) / steps_left[:, None])
        # the bursts, non-empty ones first and sorted by start (so a kernel can stop at the first
        # that starts later); the reference's ``faults_at`` reads them as given
        starts, ends = fault.burst_start_step, fault.burst_end_step
        real = ends > starts
        order = np.argsort(np.where(real, starts, np.iinfo(np.int64).max), axis=1, kind="stable")
        self.burst_count = real.sum(axis=1).astype(np.int64)
        self.burst_start = np.ascontiguousarray(np.take_along_axis(starts, order, axis=1))
        self.burst_end = np.ascontiguousarray(np.take_along_axis(ends, order, axis=1))
        self._trig: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.time_s = 0.0
        self.position_m = self._position(0)
        self.field_n_t = dipole_field_t(
            self.position_m, self.geometry.dipole_n, self.constants.environment.field_radius_m
        )
        self.field_b_t = to_body(self.sigma, self.field_n_t)
        self.applied_torque_nm = np.zeros((n, m))
        self.dipole_am2 = np.zeros((n, N_RODS))
        self.external_torque_nm = np.zeros((n, 3))

    @classmethod
    def of(cls, episodes: Any, constants: V3Constants | None = None, **options: Any) -> Self:
        """A plant holding ``episodes``' initial states, faults and environments (the one place that
        maps an episode onto the plant's arguments); ``options`` go to the backend (``parallel``)."""
        return cls(
            episodes.sigma0,
            episodes.omega0_rad_s,
            episodes.wheel_speed0_rad_s,
            episodes.inertia_scale,
            episodes.fault,
            episodes.environment,
            constants,
            **options,
        )

    def trig_at(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(cos u, sin u)`` ``(n,)`` at ``t = k dt`` (cached: each is used by two steps)."""
        if k not in self._trig:
            if len(self._trig) > 2:
                self._trig.pop(min(self._trig))
            env, g = self.env, self.geometry
            self._trig[k] = latitude_trig(env.arg_latitude0_rad, g.mean_motion, k * self.constants.dt_s)
        return self._trig[k]

    def _position(self, k: int) -> np.ndarray:
        return orbit_position_m(
            self.env.semi_major_axis_m, self.geometry.p, self.geometry.q, *self.trig_at(k)
        )

    def faults_at(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(gain, bias, coulomb_nm)`` ``(n, m)`` and ``rod_gain`` ``(n, 3)`` in force over step ``k``."""
        f, fc0 = self.fault, self.constants.wheels.coulomb_nm
        active = (k >= f.onset_step)[:, None]
        ramp = 1.0 + self.ramp_rate * (k - f.onset_step)[:, None]
        burst = np.where(f.in_burst(k), f.burst_multiplier, 1.0)
        return (
            f.gain_at(k),
            np.where(active, f.bias, 0.0),
            np.where(active, fc0 * ((f.friction_multiplier * ramp) * burst), fc0),
            np.where(active, f.rod_gain, 1.0),
        )

    def step_inputs(self, k: int, command: np.ndarray) -> tuple[StepInputs, np.ndarray]:
        """Everything step ``k`` holds or evaluates per stage, for ``command`` ``(n, m + 3)``, and the
        rods' dipoles ``(n, 3)`` (after their faults, before the residual is added)."""
        c = self.constants
        w, e = c.wheels, c.environment
        m = w.n_wheels
        gain, bias, coulomb, rod_gain = self.faults_at(k)
        motor = motor_torque_nm(
            command[:, :m], gain, bias, self.wheel_speed_rad_s, w.u_max_nm, w.omega_max_rad_s
        )
        rods = rod_dipole_am2(command[:, m:], rod_gain, e.rod_dipole_max_am2)
        env, g = self.env, self.geometry
        cos0, sin0 = self.trig_at(k)
        cos1, sin1 = self.trig_at(k + 1)
        positions = (
            orbit_position_m(env.semi_major_axis_m, g.p, g.q, cos0, sin0),
            orbit_position_m(
                env.semi_major_axis_m, g.p, g.q, *advance_trig(cos0, sin0, g.half_cos, g.half_sin)
            ),
            orbit_position_m(env.semi_major_axis_m, g.p, g.q, cos1, sin1),
        )
        terms = [gravity_gradient_terms(r, e.gravity_gradient_factor) for r in positions]
        return StepInputs(
            motor_nm=motor,
            coulomb_nm=coulomb,
            dipole_am2=rods + env.residual_dipole_am2,
            field_n=self.field_n_t,
            r_hat_n=(terms[0][0], terms[1][0], terms[2][0]),
            gg_coefficient=(terms[0][1], terms[1][1], terms[2][1]),
            position_end_m=positions[2],
        ), rods

    def _command(self, command: np.ndarray) -> np.ndarray:
        command = np.ascontiguousarray(command, dtype=np.float64)
        shape = (self.n, self.constants.action_dim)
        if command.shape != shape:
            raise ValueError(f"command must have shape {shape}, got {command.shape}")
        return command

    @abstractmethod
    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` (0-based, in order) with ``command`` ``(n, m + 3)`` held (wheels, then
        rods, each in [-1, 1]); return ``|sigma|^2`` ``(n,)`` of the new attitude."""

    def states(self) -> dict[str, np.ndarray]:
        """``sigma``, ``omega_rad_s``, ``wheel_speed_rad_s`` (v2's), then ``field_b_t`` (the body
        field a perfect magnetometer reads), ``field_n_t`` and ``position_m``."""
        return {
            "sigma": self.sigma,
            "omega_rad_s": self.omega_rad_s,
            "wheel_speed_rad_s": self.wheel_speed_rad_s,
            "field_b_t": self.field_b_t,
            "field_n_t": self.field_n_t,
            "position_m": self.position_m,
        }


class V3Plant(V3PlantBase):
    """The reference backend: every episode stepped as plain numpy array operations."""

    name = "reference"

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` with ``command`` ``(n, m + 3)`` held; return ``|sigma|^2`` ``(n,)``."""
        inputs, rods = self.step_inputs(k, self._command(command))
        self.sigma, self.omega_rad_s, self.wheel_speed_rad_s, external = rk4_step(
            self.sigma, self.omega_rad_s, self.wheel_speed_rad_s, inputs, self.env, self.geometry, self.mass,
            self.constants,
        )  # fmt: skip
        self.time_s = (k + 1) * self.constants.dt_s
        self.position_m = inputs.position_end_m
        self.field_n_t = dipole_field_t(
            self.position_m, self.geometry.dipole_n, self.constants.environment.field_radius_m
        )
        self.field_b_t = to_body(self.sigma, self.field_n_t)
        self.applied_torque_nm, self.dipole_am2, self.external_torque_nm = inputs.motor_nm, rods, external
        return norm2(self.sigma)
