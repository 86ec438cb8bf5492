"""The v2 plant's numpy reference: a rigid hub with balanced reaction wheels, RK4 per step.

This is the readable truth of docs/benchmark-v2.md (the plant); the fused kernel (``v2/fast.py``) repeats its
floating-point operations in the same order, and Basilisk (``v2/basilisk.py``) is the independent
check. The state of an episode is ``(sigma, omega_rad_s, wheel_speed_rad_s)``: the hub attitude
(MRP), the hub body rate, and each wheel's speed relative to the hub. With balanced wheels
(``Js`` about the spin axis ``g_i``, ``Jt`` transverse)

    I_tot = I_hub + sum_i [Js g_i g_i' + Jt (1 - g_i g_i')],   D = I_tot - sum_i Js g_i g_i'
    D w_dot = -w x (I_tot w + sum_i Js Omega_i g_i) - sum_i g_i (u_i + fr_i)
    Omega_dot_i = (u_i + fr_i) / Js - g_i . w_dot

where ``u_i`` is the motor torque (held over a step) and ``fr_i`` the bearing friction (a function
of the wheel speed, re-evaluated at every RK4 stage). Both are internal torques: the total
angular momentum ``I_tot w + sum_i Js Omega_i g_i`` is conserved in the inertial frame.

Every sum below is written out in a fixed order (no ``@``, ``einsum`` or ``sum``, whose
summation order numpy does not promise) so the kernel can reproduce it bit for bit. Arrays are
batch-first: ``(n, 3)`` hub vectors, ``(n, m)`` per-wheel values (``m = 4`` wheels), ``(n, 3, 3)``
per-episode matrices.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Self

import numpy as np

from scftc_cli.sim.mrp import cross, dot, norm2, shadow_switch
from scftc_cli.sim.products import sum_rows
from scftc_cli.sim.scalars import lu_inverse
from scftc_cli.sim.testbed import Plant
from scftc_cli.versions.v2.spec import V2, ReactionWheelPlant

if TYPE_CHECKING:
    from scftc_cli.versions.v2.sim.faults import WheelEpisodes

RPM_TO_RAD_S = 2.0 * math.pi / 60.0
"""The same expression as Basilisk's ``macros.RPM``, so both backends get the same ``Omega_max``
(and the same ``Js = h_max / Omega_max``) to the last bit."""


@dataclass(frozen=True)
class WheelConstants:
    """The plant's numbers as the physics reads them (``WheelConstants.of(V2.plant)``: the spec's).

    Attributes:
        inertia_nominal_kgm2: Diagonal of the nominal hub inertia; an episode's hub inertia is
            ``inertia_scale * diag(inertia_nominal_kgm2)``.
        spin_axes: One unit spin axis per wheel, body frame, ``m`` rows of 3.
        h_max_nms: Wheel momentum at ``omega_max_rpm``; fixes ``Js = h_max / Omega_max``.
        omega_max_rpm: Speed above which a motor torque that would spin the wheel up is cut.
        u_max_nm: Motor torque cap per wheel.
        coulomb_nm: Nominal Coulomb friction ``fC0`` of a healthy wheel.
        viscous_nms: Viscous friction coefficient ``cV`` (N m s / rad).
        omega_linear_rad_s: Half-width ``wLC`` of the zone where friction is linear in speed
            (Basilisk's ``omegaLimitCycle``); it must be wide for RK4 at ``dt_s`` to resolve it.
        dt_s: Control step; the command is held over it.
    """

    inertia_nominal_kgm2: tuple[float, float, float]
    spin_axes: tuple[tuple[float, float, float], ...]
    h_max_nms: float
    omega_max_rpm: float
    u_max_nm: float
    coulomb_nm: float
    viscous_nms: float
    omega_linear_rad_s: float
    dt_s: float

    @classmethod
    def of(cls, plant: ReactionWheelPlant) -> WheelConstants:
        """The constants of a benchmark version's plant."""
        return cls(
            inertia_nominal_kgm2=plant.inertia_nominal_kgm2,
            spin_axes=plant.spin_axes,
            h_max_nms=plant.h_max_nms,
            omega_max_rpm=plant.omega_max_rpm,
            u_max_nm=plant.u_max_nm,
            coulomb_nm=plant.coulomb_nm,
            viscous_nms=plant.viscous_nms,
            omega_linear_rad_s=plant.omega_linear_rad_s,
            dt_s=plant.dt_s,
        )

    def __post_init__(self) -> None:
        axes = np.asarray(self.spin_axes, dtype=float)
        if axes.ndim != 2 or axes.shape[1] != 3 or len(axes) == 0:
            raise ValueError(f"spin_axes must be m rows of 3, got shape {axes.shape}")
        if np.any(np.abs(np.linalg.norm(axes, axis=1) - 1.0) > 1e-12):
            raise ValueError("spin_axes must be unit vectors")
        positive = ("h_max_nms", "omega_max_rpm", "u_max_nm", "omega_linear_rad_s", "dt_s")
        for name in positive:
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.coulomb_nm < 0.0 or self.viscous_nms < 0.0 or min(self.inertia_nominal_kgm2) <= 0.0:
            raise ValueError("friction coefficients must be >= 0 and the nominal inertia > 0")

    @property
    def n_wheels(self) -> int:
        """Number of wheels ``m``."""
        return len(self.spin_axes)

    @cached_property
    def axes(self) -> np.ndarray:
        """Spin axes as a read-only ``(m, 3)`` array (built once: the physics reads it every stage)."""
        axes = np.array(self.spin_axes, dtype=float)
        axes.setflags(write=False)
        return axes

    @property
    def omega_max_rad_s(self) -> float:
        """Speed-saturation threshold ``Omega_max`` in rad/s."""
        return self.omega_max_rpm * RPM_TO_RAD_S

    @property
    def js_kgm2(self) -> float:
        """Wheel inertia about its spin axis, ``Js = h_max / Omega_max`` (as Basilisk's rwFactory)."""
        return self.h_max_nms / self.omega_max_rad_s

    @property
    def jt_kgm2(self) -> float:
        """Transverse wheel inertia ``Jt = Jg = Js / 2`` (a thin disc)."""
        return 0.5 * self.js_kgm2

    def wheel_inertia_kgm2(self) -> np.ndarray:
        """``sum_i [Js g_i g_i' + Jt (1 - g_i g_i')]`` ``(3, 3)``: what the wheels add to the hub."""
        axes, js, jt = self.axes, self.js_kgm2, self.jt_kgm2
        out = np.zeros((3, 3))
        for g in axes:
            gg = np.outer(g, g)
            out = out + (js * gg + jt * (np.eye(3) - gg))
        return out

    def spin_inertia_kgm2(self) -> np.ndarray:
        """``sum_i Js g_i g_i'`` ``(3, 3)``: the wheels' spin-axis inertia, which ``D`` leaves out
        because each wheel's spin about ``g_i`` is a state of its own (``Omega_i``)."""
        out = np.zeros((3, 3))
        for g in self.axes:
            out = out + self.js_kgm2 * np.outer(g, g)
        return out

    def total_inertia_kgm2(self, inertia_scale: np.ndarray) -> np.ndarray:
        """``I_tot`` ``(n, 3, 3)`` for hub inertia scales ``(n,)``: hub plus every wheel."""
        scale = np.asarray(inertia_scale, dtype=float).reshape(-1, 1, 1)
        return scale * np.diag(self.inertia_nominal_kgm2) + self.wheel_inertia_kgm2()

    def coupled_inertia_kgm2(self, inertia_scale: np.ndarray) -> np.ndarray:
        """``D = I_tot - sum_i Js g_i g_i'`` ``(n, 3, 3)``: the inertia that multiplies ``w_dot``."""
        return self.total_inertia_kgm2(inertia_scale) - self.spin_inertia_kgm2()


@dataclass(frozen=True)
class MassProperties:
    """Per-episode matrices of the hub equation, computed once per batch (mass is not an event).

    Attributes:
        total_inertia_kgm2: ``I_tot`` ``(n, 3, 3)``.
        coupled_inertia_inv: ``D^-1`` ``(n, 3, 3)``; ``w_dot = D^-1 rhs`` (one inverse shared by
            every backend built on this module, so the fused kernel sees the same numbers), by
            ``sim/scalars.lu_inverse``: LU with partial pivoting in its stated order (``D`` of the
            benchmark's wheel array is diagonal, and its inverse then the reciprocal diagonal).
    """

    total_inertia_kgm2: np.ndarray
    coupled_inertia_inv: np.ndarray

    @classmethod
    def of(cls, constants: WheelConstants, inertia_scale: np.ndarray) -> MassProperties:
        """Mass properties of episodes with hub inertia scales ``inertia_scale`` ``(n,)``."""
        total = np.ascontiguousarray(constants.total_inertia_kgm2(inertia_scale))
        inv = np.ascontiguousarray(lu_inverse(constants.coupled_inertia_kgm2(inertia_scale)))
        return cls(total, inv)


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


def mrp_rate(sigma: np.ndarray, omega_rad_s: np.ndarray) -> np.ndarray:
    """``sigma_dot = 1/4 [(1 - |s|^2) w + 2 s x w + 2 s (s . w)]`` ``(n, 3)`` (as v1)."""
    s2, sw = norm2(sigma)[:, None], dot(sigma, omega_rad_s)[:, None]
    return 0.25 * ((1.0 - s2) * omega_rad_s + 2.0 * cross(sigma, omega_rad_s) + 2.0 * sigma * sw)


def motor_torque_nm(
    command: np.ndarray,
    gain: np.ndarray,
    bias: np.ndarray,
    wheel_speed_rad_s: np.ndarray,
    u_max_nm: float,
    omega_max_rad_s: float,
) -> np.ndarray:
    """The torque each motor applies over a step, ``(n, m)`` in N m.

    ``u = clip((gain a + bias) u_max, -u_max, u_max)``, then speed saturation as Basilisk's
    ``reactionWheelStateEffector`` does it, once, on the speed at the start of the step: a wheel
    at or above ``Omega_max`` gets zero torque unless the torque slows it down (``Omega u < 0``),
    so it can still be braked, and speeds can overshoot ``Omega_max`` within a step.

    Args:
        command: Normalized commands ``a`` ``(n, m)``.
        gain: Effectiveness per wheel ``(n, m)`` (1 healthy, 0 dead, negative reversed).
        bias: Offset per wheel ``(n, m)``, a fraction of ``u_max``.
        wheel_speed_rad_s: Wheel speeds at the start of the step ``(n, m)``.
        u_max_nm: Motor torque cap.
        omega_max_rad_s: Speed-saturation threshold.
    """
    u = np.clip((gain * command + bias) * u_max_nm, -u_max_nm, u_max_nm)
    cut = (np.abs(wheel_speed_rad_s) >= omega_max_rad_s) & (wheel_speed_rad_s * u >= 0.0)
    return np.where(cut, 0.0, u)


def friction_torque_nm(
    wheel_speed_rad_s: np.ndarray, coulomb_nm: np.ndarray, viscous_nms: float, omega_linear_rad_s: float
) -> np.ndarray:
    """Bearing friction on each wheel ``(n, m)`` in N m, always opposing its speed.

    ``fr = -(sign(Omega) fC + cV Omega)``; inside ``|Omega| < wLC`` the line through zero that
    meets it at ``wLC``, ``-((fC + cV wLC) / wLC) Omega`` (continuous, so RK4 can cross it).

    Args:
        wheel_speed_rad_s: Wheel speeds ``(n, m)``.
        coulomb_nm: Coulomb friction per wheel ``(n, m)`` (a fault multiplies one wheel's).
        viscous_nms: Viscous coefficient ``cV``.
        omega_linear_rad_s: ``wLC``.
    """
    slope = (coulomb_nm + viscous_nms * omega_linear_rad_s) / omega_linear_rad_s
    outside = -(np.sign(wheel_speed_rad_s) * coulomb_nm + viscous_nms * wheel_speed_rad_s)
    return np.where(np.abs(wheel_speed_rad_s) < omega_linear_rad_s, -(slope * wheel_speed_rad_s), outside)


def derivatives(
    sigma: np.ndarray,
    omega_rad_s: np.ndarray,
    wheel_speed_rad_s: np.ndarray,
    motor_nm: np.ndarray,
    coulomb_nm: np.ndarray,
    mass: MassProperties,
    constants: WheelConstants,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time derivatives ``(sigma_dot (n, 3), omega_dot (n, 3) rad/s^2, wheel_accel (n, m) rad/s^2)``.

    ``motor_nm`` ``(n, m)`` is the held motor torque; friction is evaluated here, at the state
    given, so each RK4 stage sees the friction of its own wheel speeds.
    """
    axes, js = constants.axes, constants.js_kgm2
    torque = motor_nm + friction_torque_nm(
        wheel_speed_rad_s, coulomb_nm, constants.viscous_nms, constants.omega_linear_rad_s
    )
    momentum = _matvec(mass.total_inertia_kgm2, omega_rad_s) + _along_axes(axes, js * wheel_speed_rad_s)
    rhs = -cross(omega_rad_s, momentum) - _along_axes(axes, torque)
    omega_dot = _matvec(mass.coupled_inertia_inv, rhs)
    wheel_accel = torque / js - _onto_axes(axes, omega_dot)
    return mrp_rate(sigma, omega_rad_s), omega_dot, wheel_accel


def rk4_step(
    sigma: np.ndarray,
    omega_rad_s: np.ndarray,
    wheel_speed_rad_s: np.ndarray,
    motor_nm: np.ndarray,
    coulomb_nm: np.ndarray,
    mass: MassProperties,
    constants: WheelConstants,
    dt_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One classic RK4 step on ``(sigma, omega, wheel_speed)`` together, then the shadow switch.

    The motor torque is held, friction re-evaluated at every stage (as Basilisk integrates the
    hub and the wheel states in one RK4). ``dt_s`` defaults to ``constants.dt_s``; tests pass
    others to measure the order of accuracy.
    """
    dt = constants.dt_s if dt_s is None else dt_s

    def f(s, w, o):
        return derivatives(s, w, o, motor_nm, coulomb_nm, mass, constants)

    h = 0.5 * dt
    k1s, k1w, k1o = f(sigma, omega_rad_s, wheel_speed_rad_s)
    k2s, k2w, k2o = f(sigma + h * k1s, omega_rad_s + h * k1w, wheel_speed_rad_s + h * k1o)
    k3s, k3w, k3o = f(sigma + h * k2s, omega_rad_s + h * k2w, wheel_speed_rad_s + h * k2o)
    k4s, k4w, k4o = f(sigma + dt * k3s, omega_rad_s + dt * k3w, wheel_speed_rad_s + dt * k3o)
    c = dt / 6.0
    sigma_next = sigma + c * (k1s + 2.0 * k2s + 2.0 * k3s + k4s)
    omega_next = omega_rad_s + c * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
    wheel_next = wheel_speed_rad_s + c * (k1o + 2.0 * k2o + 2.0 * k3o + k4o)
    return shadow_switch(sigma_next), omega_next, wheel_next


def body_momentum_nms(
    omega_rad_s: np.ndarray, wheel_speed_rad_s: np.ndarray, mass: MassProperties, constants: WheelConstants
) -> np.ndarray:
    """Total angular momentum of hub and wheels about the centre of mass, body frame ``(n, 3)``:
    ``I_tot w + sum_i Js Omega_i g_i``. Rotated to the inertial frame it is constant."""
    return _matvec(mass.total_inertia_kgm2, omega_rad_s) + _along_axes(
        constants.axes, constants.js_kgm2 * wheel_speed_rad_s
    )


def kinetic_energy_j(
    omega_rad_s: np.ndarray, wheel_speed_rad_s: np.ndarray, mass: MassProperties, constants: WheelConstants
) -> np.ndarray:
    """Rotational kinetic energy ``(n,)`` in J: ``w' I_tot w / 2 + sum_i Js (Omega_i^2 / 2 +
    Omega_i g_i . w)``. Its rate is the power ``sum_i Omega_i (u_i + fr_i)`` of motors and friction."""
    hub = 0.5 * dot(omega_rad_s, _matvec(mass.total_inertia_kgm2, omega_rad_s))
    spin = wheel_speed_rad_s * (0.5 * wheel_speed_rad_s + _onto_axes(constants.axes, omega_rad_s))
    return hub + constants.js_kgm2 * sum_rows(spin)


def _as_batch(name: str, x: np.ndarray, shape: tuple[int, ...], dtype: type = np.float64) -> np.ndarray:
    out: np.ndarray = np.array(x, dtype=dtype, order="C")  # a private copy: the plant owns its state
    if out.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {out.shape}")
    return out


class WheelPlantBase(Plant):
    """A batch of ``n`` v2 episodes, advanced one control step at a time (every backend).

    Args:
        sigma0: Initial hub attitudes (MRP) ``(n, 3)``.
        omega0_rad_s: Initial hub body rates ``(n, 3)``.
        wheel_speed0_rad_s: Initial wheel speeds relative to the hub ``(n, m)``.
        inertia_scale: Hub inertia scale ``f`` ``(n,)``: ``I_hub = f diag(nominal)``. A mass
            property, present from step 0 (not an event at the onset).
        gain: Faulted effectiveness per wheel ``(n, m)``.
        bias: Faulted offset per wheel ``(n, m)``, a fraction of ``u_max``.
        coulomb_nm: Each wheel's Coulomb friction once the fault is active ``(n, m)``.
        onset_step: First faulted step per episode ``(n,)`` int; before it every wheel is
            healthy (gain 1, bias 0, nominal Coulomb friction).
        constants: The plant's numbers; ``scftc-v2``'s when omitted.

    Attributes:
        sigma, omega_rad_s, wheel_speed_rad_s: The true state after the last step.
        applied_torque_nm: Motor torque each wheel applied over the last step ``(n, m)``.
    """

    def __init__(
        self,
        sigma0: np.ndarray,
        omega0_rad_s: np.ndarray,
        wheel_speed0_rad_s: np.ndarray,
        inertia_scale: np.ndarray,
        gain: np.ndarray,
        bias: np.ndarray,
        coulomb_nm: np.ndarray,
        onset_step: np.ndarray,
        constants: WheelConstants | None = None,
    ) -> None:
        self.constants = WheelConstants.of(V2.plant) if constants is None else constants
        n, m = len(sigma0), self.constants.n_wheels
        self.n = n
        self.sigma = _as_batch("sigma0", sigma0, (n, 3))
        self.omega_rad_s = _as_batch("omega0_rad_s", omega0_rad_s, (n, 3))
        self.wheel_speed_rad_s = _as_batch("wheel_speed0_rad_s", wheel_speed0_rad_s, (n, m))
        self.inertia_scale = _as_batch("inertia_scale", inertia_scale, (n,))
        if np.any(self.inertia_scale <= 0.0):
            raise ValueError("inertia_scale must be > 0")
        self.gain = _as_batch("gain", gain, (n, m))
        self.bias = _as_batch("bias", bias, (n, m))
        self.coulomb_nm = _as_batch("coulomb_nm", coulomb_nm, (n, m))
        self.onset_step = _as_batch("onset_step", onset_step, (n,), np.int64)
        self.mass = MassProperties.of(self.constants, self.inertia_scale)
        self.applied_torque_nm = np.zeros((n, m))

    @classmethod
    def of(cls, episodes: WheelEpisodes, constants: WheelConstants | None = None, **options: object) -> Self:
        """A plant holding ``episodes``' initial states and faults (the one place that maps an
        episode onto the plant's arguments), with ``constants`` (``scftc-v2``'s by default);
        ``options`` go to the backend (``parallel``)."""
        constants = WheelConstants.of(V2.plant) if constants is None else constants
        fault = episodes.fault
        return cls(
            episodes.sigma0,
            episodes.omega0_rad_s,
            episodes.wheel_speed0_rad_s,
            fault.inertia_scale,
            fault.gain,
            fault.bias,
            fault.friction_multiplier * constants.coulomb_nm,
            fault.onset_step,
            constants,
            **options,
        )

    def faults_at(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(gain, bias, coulomb_nm)`` ``(n, m)`` in force at step ``k``: healthy before onset."""
        active = (k >= self.onset_step)[:, None]
        return (
            np.where(active, self.gain, 1.0),
            np.where(active, self.bias, 0.0),
            np.where(active, self.coulomb_nm, self.constants.coulomb_nm),
        )

    def _command(self, command: np.ndarray) -> np.ndarray:
        command = np.ascontiguousarray(command, dtype=np.float64)
        shape = (self.n, self.constants.n_wheels)
        if command.shape != shape:
            raise ValueError(f"command must have shape {shape}, got {command.shape}")
        return command

    @abstractmethod
    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` (0-based) with ``command`` ``(n, m)`` held; return ``|sigma|^2``
        ``(n,)`` of the new attitude (the pointing error is ``4 atan |sigma|``)."""

    def states(self) -> dict[str, np.ndarray]:
        """``sigma`` ``(n, 3)``, ``omega_rad_s`` ``(n, 3)``, ``wheel_speed_rad_s`` ``(n, m)``."""
        return {
            "sigma": self.sigma,
            "omega_rad_s": self.omega_rad_s,
            "wheel_speed_rad_s": self.wheel_speed_rad_s,
        }


class WheelPlant(WheelPlantBase):
    """The reference backend: every episode stepped as plain numpy array operations."""

    name = "reference"

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k`` (0-based) with ``command`` ``(n, m)`` held; return ``|sigma|^2``
        ``(n,)`` of the new attitude (the pointing error is ``4 atan |sigma|``)."""
        c = self.constants
        gain, bias, coulomb = self.faults_at(k)
        motor = motor_torque_nm(
            self._command(command), gain, bias, self.wheel_speed_rad_s, c.u_max_nm, c.omega_max_rad_s
        )
        self.sigma, self.omega_rad_s, self.wheel_speed_rad_s = rk4_step(
            self.sigma, self.omega_rad_s, self.wheel_speed_rad_s, motor, coulomb, self.mass, c
        )
        self.applied_torque_nm = motor
        return norm2(self.sigma)
