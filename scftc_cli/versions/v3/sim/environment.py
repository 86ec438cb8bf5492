"""scftc-v3's orbit and space environment: pure vectorized functions of batch-first arrays.

A v3 episode flies a circular low Earth orbit; four environment terms act on the hub, and the
magnetorquer rods act through the same magnetic field. Everything here is a plain function of
``(n, ...)`` arrays (``n`` episodes), written with every sum in a fixed order (no ``@``,
``einsum`` or ``sum``) so the fused kernel (``fast.py``) can repeat it bit for bit. Frames: ``N``
inertial (Earth-centred, the equator of the epoch), ``B`` the hub's body frame; ``C(sigma)`` maps
``N`` components to ``B`` components (``to_body``).

- Orbit: circular, radius ``a``, inclination ``i``, right ascension of the ascending node
  ``Omega``, argument of latitude ``u(t) = u0 + n t`` with ``n = sqrt(mu / a^3)``. The position is
  the closed form ``r_N(t) = a (cos u P + sin u Q)`` (``P`` towards the node, ``Q`` 90 deg ahead in
  the orbit plane), exact for a point-mass Earth: nothing is integrated, so nothing drifts.
- Magnetic field: a centred dipole with IGRF-2020's first-degree Gauss coefficients. Its potential
  ``V = a_ref^3 (m . r) / |r|^3`` with the Earth-fixed vector ``m_E = (g11, h11, g10)`` gives
  ``B(r) = (a_ref / |r|)^3 (3 r_hat (r_hat . m) - m)`` (Basilisk's ``magneticFieldCenteredDipole``).
  The Earth turns ~5 deg in a 1200 s episode; that is neglected, so ``m`` is fixed in ``N`` per
  episode at the Earth rotation angle ``theta`` of the episode's epoch: ``m_N = R3(theta)' m_E``.
- Gravity gradient: ``3 mu / |r|^3 (r_hat_B x I r_hat_B)`` about the centre of mass (Basilisk's
  ``GravityGradientEffector``), with the spacecraft inertia ``I`` (hub plus wheels; the tetrahedral
  wheels add an isotropic part, which puts no torque, so this equals the hub's own).
- Magnetic torques: ``m x B_B`` for the commanded rod dipoles plus the constant residual dipole
  (Basilisk's ``MtbEffector``: ``-[B_B~] G_t mu_cmd``).
- Solar radiation pressure on one flat facet (Basilisk's ``facetSRPDynamicEffector``): with ``s``
  the unit vector to the Sun and ``n`` the facet's normal, both in ``B``, and ``cos = n . s > 0``,
  ``F = -P A cos ((1 - rho_s) s + 2 (rho_d / 3 + rho_s cos) n)`` acts at the centre of pressure
  ``c``: torque ``c x F``. The Sun's direction is fixed in ``N`` per episode, at 1 AU (pressure
  ``P = 1368 W/m^2 / c``), and never eclipsed.

Units are SI throughout: metres, seconds, radians, tesla, A m^2, N m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scftc_cli.sim.elementary import cosine_sine
from scftc_cli.sim.mrp import cross, dot

MU_EARTH_M3_S2 = 398600.4418e9
"""Earth's gravitational parameter (398600.4418 km^3/s^2)."""
EARTH_RADIUS_M = 6378136.6
"""Equatorial radius the altitude is measured from (Basilisk's ``orbitalMotion.REQ_EARTH``)."""
FIELD_RADIUS_M = 6371200.0
"""IGRF's reference radius ``a_ref``: the Gauss coefficients are the field's size there."""
IGRF2020_G10_T = -29404.8e-9
IGRF2020_G11_T = -1450.9e-9
IGRF2020_H11_T = 4652.5e-9
SOLAR_FLUX_W_M2 = 1368.0
"""Solar flux at 1 AU, Basilisk's ``solarRadFlux``."""
SPEED_OF_LIGHT_M_S = 299792458.0
EARTH_ROTATION_RAD_S = 7.2921159e-5
"""Only to state what is neglected: 1200 s of it is 5.0 deg."""


@dataclass(frozen=True)
class EnvironmentConstants:
    """The environment's numbers as the physics reads them (shared by every episode).

    Attributes:
        mu_m3_s2: Gravitational parameter; fixes the mean motion and the gravity gradient.
        earth_radius_m: Radius the altitudes are measured from.
        field_radius_m: The dipole's reference radius ``a_ref``.
        g10_t, g11_t, h11_t: First-degree Gauss coefficients (tesla), Earth-fixed.
        srp_pressure_n_m2: Solar radiation pressure at 1 AU, ``flux / c``.
        facet_specular, facet_diffuse: The facet's optical coefficients ``rho_s``, ``rho_d`` (the
            rest is absorbed): a solar array's front, which absorbs most of the light.
        rod_dipole_max_am2: Dipole cap ``m_max`` of each rod (a command of 1 is ``m_max``).
        gravity_gradient: False switches the gravity-gradient torque off (exactly zero): tests only.
    """

    mu_m3_s2: float = MU_EARTH_M3_S2
    earth_radius_m: float = EARTH_RADIUS_M
    field_radius_m: float = FIELD_RADIUS_M
    g10_t: float = IGRF2020_G10_T
    g11_t: float = IGRF2020_G11_T
    h11_t: float = IGRF2020_H11_T
    srp_pressure_n_m2: float = SOLAR_FLUX_W_M2 / SPEED_OF_LIGHT_M_S
    facet_specular: float = 0.1
    facet_diffuse: float = 0.1
    rod_dipole_max_am2: float = 10.0
    gravity_gradient: bool = True

    def __post_init__(self) -> None:
        for name in ("mu_m3_s2", "earth_radius_m", "field_radius_m", "rod_dipole_max_am2"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.srp_pressure_n_m2 < 0.0:
            raise ValueError("srp_pressure_n_m2 must be >= 0")
        if not (0.0 <= self.facet_specular and 0.0 <= self.facet_diffuse
                and self.facet_specular + self.facet_diffuse <= 1.0):  # fmt: skip
            raise ValueError("optical coefficients must be >= 0 and sum to at most 1")

    @property
    def gravity_gradient_factor(self) -> float:
        """``3 mu`` (0 with the gravity gradient off): the torque is this over ``|r|^3``."""
        return 3.0 * self.mu_m3_s2 if self.gravity_gradient else 0.0

    @property
    def earth_dipole_t(self) -> tuple[float, float, float]:
        """The dipole vector ``m_E = (g11, h11, g10)`` in Earth-fixed axes, tesla."""
        return (self.g11_t, self.h11_t, self.g10_t)


@dataclass(frozen=True)
class Environment:
    """Per-episode orbit and disturbance parameters (what an episode generator draws).

    Attributes:
        semi_major_axis_m: Orbit radius ``a`` ``(n,)`` (Earth radius plus altitude).
        inclination_rad: ``(n,)``.
        raan_rad: Right ascension of the ascending node ``(n,)``.
        arg_latitude0_rad: Argument of latitude at ``t = 0`` ``(n,)``.
        earth_angle_rad: Earth rotation angle at the epoch ``(n,)``: the Earth-fixed frame is the
            inertial one turned by it about ``z`` (Basilisk's ``J20002Pfix = R3(theta)``); it sets
            where the tilted dipole points, fixed over the episode.
        residual_dipole_am2: Constant residual dipole of the spacecraft, body frame ``(n, 3)``.
        sun_direction: Unit vector to the Sun, inertial ``(n, 3)``.
        facet_area_m2: Area of the sunlit facet ``(n,)`` (0: no solar pressure).
        facet_normal: The facet's unit normal, body frame ``(n, 3)``; lit when it faces the Sun.
        facet_cop_m: Centre of pressure relative to the centre of mass, body frame ``(n, 3)``.
    """

    semi_major_axis_m: np.ndarray
    inclination_rad: np.ndarray
    raan_rad: np.ndarray
    arg_latitude0_rad: np.ndarray
    earth_angle_rad: np.ndarray
    residual_dipole_am2: np.ndarray
    sun_direction: np.ndarray
    facet_area_m2: np.ndarray
    facet_normal: np.ndarray
    facet_cop_m: np.ndarray

    @property
    def n(self) -> int:
        return len(self.semi_major_axis_m)

    def __post_init__(self) -> None:
        n = len(np.asarray(self.semi_major_axis_m))
        shapes = {
            "semi_major_axis_m": (n,), "inclination_rad": (n,), "raan_rad": (n,),
            "arg_latitude0_rad": (n,), "earth_angle_rad": (n,), "residual_dipole_am2": (n, 3),
            "sun_direction": (n, 3), "facet_area_m2": (n,), "facet_normal": (n, 3), "facet_cop_m": (n, 3),
        }  # fmt: skip
        for name, shape in shapes.items():
            value = np.array(getattr(self, name), dtype=np.float64, order="C")  # a private copy
            if value.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {value.shape}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if np.any(self.semi_major_axis_m <= 0.0) or np.any(self.facet_area_m2 < 0.0):
            raise ValueError("semi_major_axis_m must be > 0 and facet_area_m2 >= 0")
        for name in ("sun_direction", "facet_normal"):
            if np.any(np.abs(np.sqrt(dot(getattr(self, name), getattr(self, name))) - 1.0) > 1e-12):
                raise ValueError(f"{name} must hold unit vectors")

    @classmethod
    def quiet(cls, n: int, altitude_m: float = 600e3, inclination_deg: float = 60.0) -> Environment:
        """``n`` episodes on one orbit with no residual dipole and no solar pressure (area 0)."""
        return cls(
            semi_major_axis_m=np.full(n, EARTH_RADIUS_M + altitude_m),
            inclination_rad=np.full(n, math.radians(inclination_deg)),
            raan_rad=np.zeros(n),
            arg_latitude0_rad=np.zeros(n),
            earth_angle_rad=np.zeros(n),
            residual_dipole_am2=np.zeros((n, 3)),
            sun_direction=np.tile([1.0, 0.0, 0.0], (n, 1)),
            facet_area_m2=np.zeros(n),
            facet_normal=np.tile([1.0, 0.0, 0.0], (n, 1)),
            facet_cop_m=np.zeros((n, 3)),
        )


# ---------------------------------------------------------------------------------------------
# Orbit


def mean_motion_rad_s(semi_major_axis_m: np.ndarray, mu_m3_s2: float) -> np.ndarray:
    """``n = sqrt(mu / a^3)`` ``(n,)`` rad/s: the circular orbit's angular rate."""
    a = np.asarray(semi_major_axis_m, dtype=np.float64)
    return np.sqrt(mu_m3_s2 / ((a * a) * a))


def orbit_axes(inclination_rad: np.ndarray, raan_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(P, Q)`` ``(n, 3)`` each, inertial: the unit vector to the ascending node and the one 90 deg
    ahead of it in the orbit plane (the perifocal axes of a circular orbit measured from the node).

    ``P = (cos Omega, sin Omega, 0)``, ``Q = (-sin Omega cos i, cos Omega cos i, sin i)``.
    """
    ci, si = cosine_sine(inclination_rad)
    co, so = cosine_sine(raan_rad)
    p = np.stack((co, so, np.zeros_like(co)), axis=1)
    q = np.stack((-(so * ci), co * ci, si), axis=1)
    return p, q


def latitude_trig(
    arg_latitude0_rad: np.ndarray, mean_motion: np.ndarray, time_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """``(cos u, sin u)`` ``(n,)`` of the argument of latitude ``u = u0 + n t`` at time ``time_s``.

    The only transcendental functions of a step: every backend takes these same arrays (the
    project's correctly rounded ``cos``/``sin``, ``sim/elementary``), so none of them depends on
    how numpy, libm or another library rounds a cosine.
    """
    u = arg_latitude0_rad + mean_motion * time_s
    return cosine_sine(u)


def advance_trig(
    cos_u: np.ndarray, sin_u: np.ndarray, cos_d: np.ndarray, sin_d: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(cos(u + d), sin(u + d))`` by the angle-sum identities (used for the half step, whose
    ``cos d``, ``sin d`` are per-episode constants)."""
    return cos_u * cos_d - sin_u * sin_d, sin_u * cos_d + cos_u * sin_d


def orbit_position_m(
    semi_major_axis_m: np.ndarray, p: np.ndarray, q: np.ndarray, cos_u: np.ndarray, sin_u: np.ndarray
) -> np.ndarray:
    """``r_N = a (cos u P + sin u Q)`` ``(n, 3)`` in metres."""
    a, c, s = semi_major_axis_m[:, None], cos_u[:, None], sin_u[:, None]
    return a * (c * p + s * q)


def orbit_velocity_m_s(
    semi_major_axis_m: np.ndarray,
    mean_motion: np.ndarray,
    p: np.ndarray,
    q: np.ndarray,
    cos_u: np.ndarray,
    sin_u: np.ndarray,
) -> np.ndarray:
    """``v_N = a n (-sin u P + cos u Q)`` ``(n, 3)`` in m/s (to start an integrator on the orbit)."""
    an, c, s = (semi_major_axis_m * mean_motion)[:, None], cos_u[:, None], sin_u[:, None]
    return an * (c * q - s * p)


# ---------------------------------------------------------------------------------------------
# Frames


def to_body(sigma: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``C(sigma) v`` ``(n, 3)``: inertial components ``v`` ``(n, 3)`` in the body frame of ``sigma``.

    ``C = I + (8 [s~]^2 - 4 (1 - |s|^2) [s~]) / (1 + |s|^2)^2`` applied as two cross products
    (``a = s x v``, ``b = s x a``) instead of a matrix: fewer operations, one division (the kernel
    rotates three vectors per RK4 stage), and any MRP (a shadow set or a stage value with
    ``|s| > 1``) gives the same rotation.
    """
    s2 = dot(sigma, sigma)[:, None]
    a = cross(sigma, v)
    b = cross(sigma, a)
    d = 1.0 + s2
    return v + (8.0 * b - (4.0 * (1.0 - s2)) * a) * (1.0 / (d * d))


# ---------------------------------------------------------------------------------------------
# Fields and torques


def earth_dipole_n(earth_angle_rad: np.ndarray, constants: EnvironmentConstants) -> np.ndarray:
    """The dipole vector ``m_N = R3(theta)' (g11, h11, g10)`` ``(n, 3)`` in tesla, inertial."""
    g11, h11, g10 = constants.earth_dipole_t
    c, s = cosine_sine(earth_angle_rad)
    return np.stack((c * g11 - s * h11, s * g11 + c * h11, np.full_like(c, g10)), axis=1)


def dipole_field_t(r_n: np.ndarray, dipole_n: np.ndarray, field_radius_m: float) -> np.ndarray:
    """Centred-dipole field ``B = (a_ref / |r|)^3 (3 r_hat (r_hat . m) - m)`` ``(n, 3)`` in tesla, in
    the frame of ``r_n`` and ``dipole_n`` ``(n, 3)`` (inertial here)."""
    inv_r = 1.0 / np.sqrt(dot(r_n, r_n))[:, None]
    r_hat = r_n * inv_r
    ratio = field_radius_m * inv_r
    scale = (ratio * ratio) * ratio
    along = dot(r_hat, dipole_n)[:, None]
    return scale * ((3.0 * r_hat) * along - dipole_n)


def gravity_gradient_terms(r_n: np.ndarray, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """``(r_hat_N (n, 3), 3 mu / |r|^3 (n,))``: what the gravity gradient needs of a position."""
    inv_r = 1.0 / np.sqrt(dot(r_n, r_n))
    return r_n * inv_r[:, None], factor * ((inv_r * inv_r) * inv_r)


def gravity_gradient_torque_nm(
    r_hat_b: np.ndarray, coefficient: np.ndarray, inertia: np.ndarray
) -> np.ndarray:
    """``3 mu / |r|^3 (r_hat_B x I r_hat_B)`` ``(n, 3)`` in N m, for ``r_hat_b`` ``(n, 3)``, the
    coefficient ``(n,)`` and the inertia about the centre of mass ``(n, 3, 3)``."""
    i_r = (
        inertia[:, :, 0] * r_hat_b[:, 0:1]
        + inertia[:, :, 1] * r_hat_b[:, 1:2]
        + inertia[:, :, 2] * r_hat_b[:, 2:3]
    )
    return coefficient[:, None] * cross(r_hat_b, i_r)


def rod_dipole_am2(command: np.ndarray, rod_gain: np.ndarray, dipole_max_am2: float) -> np.ndarray:
    """Dipoles the three rods (along the body axes) produce ``(n, 3)`` in A m^2.

    ``m_j = g_j (clip(a_j, -1, 1) m_max)``: the command is a fraction of the cap, the rod's health
    ``g_j`` (1 healthy, -1 reversed, 0 dead, 0.5 half) scales what the rod makes of it.
    """
    return rod_gain * (np.clip(command, -1.0, 1.0) * dipole_max_am2)


def magnetic_torque_nm(dipole_b: np.ndarray, field_b: np.ndarray) -> np.ndarray:
    """``m x B`` ``(n, 3)`` in N m for a body dipole (A m^2) in a body field (T)."""
    return cross(dipole_b, field_b)


def srp_torque_nm(
    sun_b: np.ndarray,
    normal_b: np.ndarray,
    cop_m: np.ndarray,
    pressure_area: np.ndarray,
    specular: float,
    diffuse: float,
) -> np.ndarray:
    """Solar-pressure torque of one flat facet ``(n, 3)`` in N m (zero when it faces away).

    ``F = -(P A cos) ((1 - rho_s) s + 2 (rho_d / 3 + rho_s cos) n)``, ``cos = n . s``, torque
    ``c x F``; ``pressure_area`` is ``P A`` ``(n,)``.
    """
    cos = dot(normal_b, sun_b)[:, None]
    scale = -(pressure_area[:, None] * cos)
    force = scale * ((1.0 - specular) * sun_b + (2.0 * (diffuse / 3.0 + specular * cos)) * normal_b)
    return np.where(cos > 0.0, cross(cop_m, force), 0.0)
