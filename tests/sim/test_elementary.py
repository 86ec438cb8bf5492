"""The project's own elementary functions (``scftc_cli.sim.elementary``) are correctly rounded:
checked against mpmath at 200 bits on arguments of every magnitude, the edges of their reductions and
the special values. Correct rounding is their quality; what makes a scored number the same on every
machine is that they use nothing but IEEE 754's correctly rounded operations and ``fma``."""

from __future__ import annotations

import math

import mpmath
import numba
import numpy as np
import pytest

from scftc_cli.sim.elementary import arccos, arctan, arctan2, cosine, cosine_sine, exp, log1p, sine, tangent

mpmath.mp.prec = 200
RNG = np.random.default_rng(20261128)


def _edges(values: list[float]) -> np.ndarray:
    edges = np.array(values)
    return np.concatenate([edges, np.nextafter(edges, -np.inf), np.nextafter(edges, np.inf)])


def _wrong(got: np.ndarray, reference, *args: np.ndarray) -> list[tuple[float, ...]]:
    out = []
    for i in range(got.size):
        point = tuple(float(a[i]) for a in args)
        if got[i] != float(reference(*(mpmath.mpf(p) for p in point))):
            out.append(point)
    return out


ATAN_ARGS = np.concatenate(
    [
        RNG.random(3000),  # the gates' range: |sigma| up to 1
        np.exp(RNG.uniform(-40.0, 40.0, 2000)),
        1.0 + RNG.normal(0.0, 1e-6, 300),  # either side of the inversion
        0.03125 * (1.0 + RNG.normal(0.0, 1e-9, 300)),  # either side of the last halving
        _edges([0.03125, 1.0, 2.0**-26, 2.0**26, 1e-300, 1e300]),
    ]
)
TRIG_ARGS = np.concatenate(
    [
        RNG.uniform(-8.0, 8.0, 3000),
        np.exp(RNG.uniform(-30.0, 13.0, 1000)) * RNG.choice([-1.0, 1.0], 1000),
        np.arange(-20, 21) * (math.pi / 4.0),  # near the reduction's quadrant boundaries
        _edges([1e-300, 2.0**-27, math.pi / 2.0, math.pi, 2.0 * math.pi]),
    ]
)


@pytest.mark.parametrize(
    ("function", "reference", "args"),
    [
        (arctan, mpmath.atan, ATAN_ARGS),
        (sine, mpmath.sin, TRIG_ARGS),
        (cosine, mpmath.cos, TRIG_ARGS),
        (tangent, mpmath.tan, TRIG_ARGS),
        (arccos, mpmath.acos, np.concatenate([RNG.uniform(-1.0, 1.0, 3000), _edges([-0.5, 0.0, 0.5])])),
    ],
    ids=["atan", "sin", "cos", "tan", "acos"],
)
def test_unary_functions_are_correctly_rounded(function, reference, args):
    wrong = _wrong(function(args), reference, args)
    assert not wrong, f"{len(wrong)} of {args.size} arguments not correctly rounded, e.g. {wrong[:5]}"


def test_atan2_is_correctly_rounded_in_every_quadrant():
    y = np.concatenate([RNG.uniform(-3.0, 3.0, 2000), np.exp(RNG.uniform(-20.0, 20.0, 500))])
    x = np.concatenate([RNG.uniform(-3.0, 3.0, 2000), -np.exp(RNG.uniform(-20.0, 20.0, 500))])
    wrong = _wrong(arctan2(y, x), mpmath.atan2, y, x)
    assert not wrong, f"{len(wrong)} of {y.size} points not correctly rounded, e.g. {wrong[:5]}"


def test_special_values_are_c99s():
    zero, inf, nan = 0.0, math.inf, math.nan
    ys = [0.0, -0.0, 0.0, -0.0, 1.0, -1.0, inf, -inf, inf, 1.0, 1.0, -1.0, nan, 1.0]
    xs = [0.0, 0.0, -0.0, -0.0, 0.0, -0.0, inf, -inf, 1.0, inf, -inf, inf, 1.0, nan]
    got = arctan2(np.array(ys), np.array(xs))
    for y, x, g in zip(ys, xs, got, strict=True):
        want = math.atan2(y, x)
        assert (math.isnan(g) and math.isnan(want)) or (
            g == want and math.copysign(1, g) == math.copysign(1, want)
        )
    atan = arctan(np.array([zero, -zero, inf, -inf, nan]))
    assert math.copysign(1.0, atan[0]) == 1.0 and math.copysign(1.0, atan[1]) == -1.0
    assert atan[2] == math.atan(inf) and atan[3] == -atan[2] and math.isnan(atan[4])
    assert math.copysign(1.0, sine(np.array([-0.0]))[0]) == -1.0 and tangent(np.array([0.0]))[0] == 0.0
    assert arccos(np.array([1.0]))[0] == 0.0 and arccos(np.array([-1.0]))[0] == math.acos(-1.0)
    assert np.isnan(arccos(np.array([1.5, -1.5, nan]))).all()
    assert np.isnan(sine(np.array([inf, 2.0**21])))[0] and np.isnan(cosine(np.array([nan])))[0]


def test_atan_is_odd():
    assert np.array_equal(arctan(-ATAN_ARGS), -arctan(ATAN_ARGS))


@pytest.mark.parametrize("shape", [(), (7,), (3, 4), (2, 0)])
def test_the_array_forms_keep_the_shape(shape):
    x = np.linspace(0.0, 0.9, int(np.prod(shape))).reshape(shape)
    for function, numpy_form in ((arctan, np.arctan), (sine, np.sin), (arccos, np.arccos)):
        assert function(x).shape == shape
        np.testing.assert_allclose(function(x), numpy_form(x), rtol=1e-15, atol=0.0)
    assert arctan2(x, 1.0).shape == shape


@numba.njit
def _scalar_map(function, x):  # pragma: no cover - compiled
    out = np.empty_like(x)
    for i in range(x.size):
        out[i] = function(x[i])
    return out


def _exponential(x: np.ndarray) -> np.ndarray:
    return _scalar_map(exp, x)


def _log1p(x: np.ndarray) -> np.ndarray:
    return _scalar_map(log1p, x)


LN2 = math.log(2.0)
WEDGE = RNG.uniform(0.0, 3.7, 4000)
EXP_ARGS = np.concatenate(
    [
        -0.5 * WEDGE * WEDGE,  # the ziggurat's wedges: exp(-x^2 / 2) for x up to r = 3.654
        RNG.uniform(-708.39, 709.78, 1000),  # every normal result
        np.exp(RNG.uniform(-745.0, 0.0, 300)) * RNG.choice([-1.0, 1.0], 300),
        (np.arange(-40, 41) + 0.5) * LN2,  # either side of the reduction's steps
        _edges([0.5 * LN2, -0.5 * LN2, 2.0**-54, -(2.0**-54), 2.0**-53, -(2.0**-53), 1e-300, -1e-300]),
        _edges([709.782712893384, -708.3964185322641, 1.0, -1.0]),  # the largest, the smallest normal
        [0.0, -0.0, 5e-324, -5e-324],
        np.arange(1, 64) * 2.0**-53,  # 1 + x is a tie for x an odd multiple of 2^-53 (or -2^-54)
        np.arange(1, 64) * -(2.0**-54),
    ]
)
TAIL = RNG.integers(0, 2**53, 4000) * 2.0**-53
LOG1P_ARGS = np.concatenate(
    [
        -TAIL,  # the ziggurat's tail: log1p(-u) for u in [0, 1), 53 bits
        -(RNG.random(1000) ** 8),  # small u
        np.exp(RNG.uniform(-60.0, 709.0, 1000)),
        _edges([math.sqrt(2.0) - 1.0, math.sqrt(0.5) - 1.0, 1.0, -0.5, 2.0**-54, -(2.0**-54)]),
        _edges([1e-300, -1e-300, 1e300, -1.0 + 2.0**-53]),
        [0.0, -0.0, 5e-324, -5e-324, 2.0**-1022, -(2.0**-1022), 1.7976931348623157e308],
    ]
)


@pytest.mark.parametrize(
    ("function", "reference", "args"),
    [(_exponential, mpmath.exp, EXP_ARGS), (_log1p, mpmath.log1p, LOG1P_ARGS[LOG1P_ARGS > -1.0])],
    ids=["exp", "log1p"],
)
def test_exp_and_log1p_are_correctly_rounded(function, reference, args):
    wrong = _wrong(function(args), reference, args)
    assert not wrong, f"{len(wrong)} of {args.size} arguments not correctly rounded, e.g. {wrong[:5]}"


def test_exp_and_log1p_special_values():
    inf, nan = math.inf, math.nan
    got = _exponential(np.array([inf, -inf, nan, 709.8, -745.2, 0.0, -0.0]))
    assert got[0] == inf and got[1] == 0.0 and math.isnan(got[2]) and got[3] == inf and got[4] == 0.0
    assert got[5] == got[6] == 1.0
    got = _log1p(np.array([-1.0, -1.5, -inf, nan, inf, 0.0, -0.0, -5e-324]))
    assert got[0] == -inf and np.isnan(got[1:4]).all() and got[4] == inf
    assert [math.copysign(1.0, g) for g in got[5:]] == [1.0, -1.0, -1.0] and got[7] == -5e-324


def test_exp_is_faithful_where_the_result_is_subnormal():
    x = np.concatenate([RNG.uniform(-745.13, -708.4, 2000), [-745.1332191019411, -745.1332191019412]])
    got = _exponential(x)
    exact = np.array([float(mpmath.exp(mpmath.mpf(v)) / mpmath.mpf(2) ** -1074) for v in x])
    assert np.all(np.abs(got / 5e-324 - exact) < 1.0)


def test_cosine_sine_is_cosine_and_sine_to_the_bit() -> None:
    x = np.concatenate(
        [
            RNG.uniform(-50.0, 50.0, 20_000),
            RNG.uniform(-(2.0**20), 2.0**20, 3_992),  # every quadrant, far from zero
            [0.0, -0.0, 1e-300, -5e-324, 2.0**20, 2.0**21, np.nan, np.inf],
        ]
    ).reshape(4, -1)
    c, s = cosine_sine(x)
    assert c.shape == s.shape == x.shape
    np.testing.assert_array_equal(c.view(np.int64), cosine(x).view(np.int64))
    np.testing.assert_array_equal(s.view(np.int64), sine(x).view(np.int64))


def test_the_short_forms_are_within_a_few_ulp() -> None:
    """``acos_short`` within 2 ulp of the exact arccosine on [-1, 1]; ``cos_short`` within 4 ulp of
    1 (absolute) of the exact cosine on [0, pi], its argument taken as the float it is given."""
    from scftc_cli.sim.elementary import short_rows

    x = np.concatenate([RNG.uniform(-1.0, 1.0, 4000), [-1.0, -0.5, -0.0, 0.0, 0.5, 1.0, 1e-300]])
    got_acos, got_cos = np.empty_like(x), np.empty_like(x)
    short_rows(x, got_acos, got_cos)
    arg = (x + 1.0) * (math.pi / 2.0)
    for xi, a, c, t in zip(x, got_acos, got_cos, arg, strict=True):
        exact = float(mpmath.acos(mpmath.mpf(float(xi))))
        assert abs(a - exact) <= 2 * math.ulp(exact)
        assert abs(c - float(mpmath.cos(mpmath.mpf(float(t))))) <= 4 * math.ulp(1.0) / 2
