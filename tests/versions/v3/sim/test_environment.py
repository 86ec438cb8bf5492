"""The environment's functions against first principles (Basilisk's are in test_basilisk.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scftc_cli.sim.mrp import to_dcm
from scftc_cli.versions.v3.sim.environment import (
    EARTH_RADIUS_M,
    FIELD_RADIUS_M,
    MU_EARTH_M3_S2,
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
    orbit_velocity_m_s,
    rod_dipole_am2,
    srp_torque_nm,
    to_body,
)
from tests.versions.v3.sim.demo import unit_vectors

C = EnvironmentConstants()
RNG = np.random.default_rng(1)


def _orbits(n: int):
    a = EARTH_RADIUS_M + RNG.uniform(500e3, 700e3, n)
    inc, raan, u0 = (
        np.radians(RNG.uniform(40, 98, n)),
        RNG.uniform(0, 2 * np.pi, n),
        RNG.uniform(0, 2 * np.pi, n),
    )
    p, q = orbit_axes(inc, raan)
    return a, inc, raan, u0, p, q, mean_motion_rad_s(a, MU_EARTH_M3_S2)


def test_the_orbit_is_a_circular_kepler_orbit_with_the_drawn_elements():
    a, inc, raan, u0, p, q, n = _orbits(50)
    for t in (0.0, 333.5, 1200.0):
        cu, su = latitude_trig(u0, n, t)
        r, v = orbit_position_m(a, p, q, cu, su), orbit_velocity_m_s(a, n, p, q, cu, su)
        np.testing.assert_allclose(np.linalg.norm(r, axis=1), a, rtol=1e-15)
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), np.sqrt(MU_EARTH_M3_S2 / a), rtol=1e-15)
        cos_rv = np.einsum("ni,ni->n", r, v) / (np.linalg.norm(r, axis=1) * np.linalg.norm(v, axis=1))
        np.testing.assert_allclose(cos_rv, 0.0, atol=1e-15)
        h = np.cross(r, v)
        h /= np.linalg.norm(h, axis=1)[:, None]
        np.testing.assert_allclose(np.arccos(h[:, 2]), inc, atol=1e-12)  # inclination
        np.testing.assert_allclose(
            np.arctan2(h[:, 0], -h[:, 1]) % (2 * np.pi), raan % (2 * np.pi), atol=1e-12
        )
    # one period later it is back; the velocity is the derivative of the position
    period = 2 * np.pi / n
    cu, su = latitude_trig(u0, n, 0.0)
    cp, sp = np.cos(u0 + n * period), np.sin(u0 + n * period)
    np.testing.assert_allclose(
        orbit_position_m(a, p, q, cp, sp), orbit_position_m(a, p, q, cu, su), atol=1e-6
    )
    dt = 1e-3
    r1 = orbit_position_m(a, p, q, *latitude_trig(u0, n, 100.0 + dt))
    r0 = orbit_position_m(a, p, q, *latitude_trig(u0, n, 100.0 - dt))
    v = orbit_velocity_m_s(a, n, p, q, *latitude_trig(u0, n, 100.0))
    np.testing.assert_allclose((r1 - r0) / (2 * dt), v, rtol=1e-7, atol=1e-4)


def test_the_half_step_turn_is_the_closed_form_to_rounding():
    a, _, _, u0, p, q, n = _orbits(50)
    h = 0.25
    turned = advance_trig(*latitude_trig(u0, n, 500.0), np.cos(n * h), np.sin(n * h))
    direct = latitude_trig(u0, n, 500.0 + h)
    np.testing.assert_allclose(turned, direct, rtol=0, atol=2e-15)


def test_the_dipole_is_igrf_2020s_first_degree_field():
    m = np.array(C.earth_dipole_t)
    b0 = np.linalg.norm(m)
    assert b0 == pytest.approx(29806.0e-9, rel=1e-4)  # |(g11, h11, g10)|
    assert math.degrees(math.acos(-m[2] / b0)) == pytest.approx(
        9.41, abs=0.01
    )  # dipole tilt (pole at 80.6 N)
    # the Earth angle turns the Earth-fixed dipole about z, nothing else
    theta = RNG.uniform(0, 2 * np.pi, 20)
    m_n = earth_dipole_n(theta, C)
    np.testing.assert_allclose(np.linalg.norm(m_n, axis=1), b0, rtol=1e-15)
    np.testing.assert_array_equal(m_n[:, 2], C.g10_t)
    back = np.stack([np.cos(theta) * m_n[:, 0] + np.sin(theta) * m_n[:, 1],
                     -np.sin(theta) * m_n[:, 0] + np.cos(theta) * m_n[:, 1]], axis=1)  # fmt: skip
    np.testing.assert_allclose(back, np.tile(m[:2], (20, 1)), rtol=1e-14)


def test_the_field_is_minus_the_gradient_of_the_dipole_potential():
    r = (EARTH_RADIUS_M + 600e3) * unit_vectors(RNG, 30)
    m = earth_dipole_n(RNG.uniform(0, 2 * np.pi, 30), C)

    def potential(x):  # V = a^3 (m . x) / |x|^3: B = -grad V
        return FIELD_RADIUS_M**3 * np.einsum("ni,ni->n", m, x) / np.linalg.norm(x, axis=1) ** 3

    grad = np.empty((30, 3))
    step = 1.0
    for i in range(3):
        d = np.zeros(3)
        d[i] = step
        grad[:, i] = (potential(r + d) - potential(r - d)) / (2 * step)
    field = dipole_field_t(r, m, FIELD_RADIUS_M)
    np.testing.assert_allclose(field, -grad, rtol=0, atol=1e-13)
    # on the dipole's axis the field is twice its size on the dipole's equator, at the same radius
    axis = m[0] / np.linalg.norm(m[0])
    equator = np.cross(axis, [1.0, 0.0, 0.0])
    equator /= np.linalg.norm(equator)
    rr = 7.0e6 * np.stack([axis, equator])
    b = np.linalg.norm(dipole_field_t(rr, np.tile(m[0], (2, 1)), FIELD_RADIUS_M), axis=1)
    assert b[0] / b[1] == pytest.approx(2.0, rel=1e-14)


def test_to_body_is_the_mrp_direction_cosine_matrix_for_any_mrp():
    sigma = RNG.uniform(-1.5, 1.5, (40, 3))  # shadow sets and |sigma| > 1 stage values too
    v = RNG.standard_normal((40, 3))
    np.testing.assert_allclose(
        to_body(sigma, v), np.einsum("nij,nj->ni", to_dcm(sigma), v), rtol=0, atol=1e-14
    )
    shadow = -sigma / np.einsum("ni,ni->n", sigma, sigma)[:, None]
    np.testing.assert_allclose(to_body(shadow, v), to_body(sigma, v), rtol=0, atol=1e-14)


def test_gravity_gradient_torque():
    r = (EARTH_RADIUS_M + 500e3) * unit_vectors(RNG, 20)
    inertia = np.einsum("ij,n->nij", np.diag([10.0, 8.0, 6.0]), RNG.uniform(0.7, 2.3, 20))
    r_hat, coefficient = gravity_gradient_terms(r, C.gravity_gradient_factor)
    torque = gravity_gradient_torque_nm(r_hat, coefficient, inertia)
    ir = np.einsum("nij,nj->ni", inertia, r)
    expected = 3 * MU_EARTH_M3_S2 / np.linalg.norm(r, axis=1)[:, None] ** 5 * np.cross(r, ir)
    np.testing.assert_allclose(torque, expected, rtol=1e-13, atol=1e-22)
    # none for an isotropic body or along a principal axis; at most 3 mu / r^3 (I_max - I_min) / 2
    assert (
        np.abs(gravity_gradient_torque_nm(r_hat, coefficient, np.tile(3.0 * np.eye(3), (20, 1, 1)))).max()
        < 1e-20
    )
    axis = np.tile([0.0, 0.0, 1.0], (20, 1))
    np.testing.assert_array_equal(gravity_gradient_torque_nm(axis, coefficient, inertia), 0.0)
    bound = coefficient * (inertia[:, 0, 0] - inertia[:, 2, 2]) / 2
    assert np.all(np.linalg.norm(torque, axis=1) <= bound * (1 + 1e-12))


def test_rods_make_their_fraction_of_the_cap_and_the_torque_is_m_cross_b():
    cmd = np.array([[0.5, -2.0, 1.0], [0.5, -2.0, 1.0], [0.3, 0.3, 0.3]])
    gain = np.array([[1.0, 1.0, 1.0], [-1.0, 0.0, 0.5], [1.0, 1.0, 1.0]])
    dipole = rod_dipole_am2(cmd, gain, 10.0)
    np.testing.assert_array_equal(dipole, [[5.0, -10.0, 10.0], [-5.0, -0.0, 5.0], [3.0, 3.0, 3.0]])
    field = RNG.standard_normal((3, 3)) * 3e-5
    np.testing.assert_array_equal(magnetic_torque_nm(dipole, field), np.cross(dipole, field))


def test_solar_pressure_on_a_facet():
    n = 6
    normal = unit_vectors(RNG, n)
    cop = RNG.uniform(-0.3, 0.3, (n, 3))
    pa = np.full(n, C.srp_pressure_n_m2 * 2.0)
    sun = normal.copy()  # face on
    # all absorbed: F = -P A s; all specular: F = -2 P A cos^2 n
    absorbed = srp_torque_nm(sun, normal, cop, pa, 0.0, 0.0)
    # to some 50 ulps of the torque's size: a component near zero after the cross product's
    # cancellation has no relative precision to compare (the draws depend on the test order)
    expected = np.cross(cop, -pa[:, None] * sun)
    np.testing.assert_allclose(absorbed, expected, rtol=0, atol=1e-14 * np.abs(expected).max())
    tilted = unit_vectors(RNG, n)
    tilted = np.where((np.einsum("ni,ni->n", tilted, normal) > 0)[:, None], tilted, -tilted)
    cos = np.einsum("ni,ni->n", tilted, normal)[:, None]
    mirror = srp_torque_nm(tilted, normal, cop, pa, 1.0, 0.0)
    np.testing.assert_allclose(
        mirror, np.cross(cop, -2 * pa[:, None] * cos**2 * normal), rtol=1e-13, atol=1e-22
    )
    # a facet facing away from the Sun feels nothing
    np.testing.assert_array_equal(srp_torque_nm(-tilted, normal, cop, pa, 0.1, 0.1), 0.0)
    assert C.srp_pressure_n_m2 == pytest.approx(4.563e-6, rel=1e-3)
