"""The benchmark's own elementary functions: the same bits on every machine, whatever libm or numpy
loop the process would otherwise call.

numpy picks a loop for ``arctan`` by CPU (with AVX-512 it calls Intel's SVML, which differs from
libm in the last bit on about one value in a thousand), and libm itself differs between C libraries
and, in glibc on x86-64, between CPUs with and without FMA (it selects a variant at load). A scored
number that goes through such a function is then a property of the machine. The functions here are
computed from ``+ - * /``, ``sqrt`` and explicit ``fma`` only, all correctly rounded by IEEE 754, in a
stated order (docs/numerics.md).

``atan`` is *correctly rounded*: the result is the float64 nearest the exact arctangent. It is
evaluated in double-double arithmetic (an unevaluated sum ``hi + lo`` carrying about 106 bits):
``atan x = pi/2 - atan(1/x)`` above 1, then the half-angle step ``atan t = 2 atan(t / (1 +
sqrt(1 + t^2)))`` until ``t <= 1/32``, then the odd Taylor series, with as many terms as bring the
first omitted one below ``2^-110 t`` (to ``t^23`` at ``t = 1/32``, fewer for a smaller ``t``). The
result's error is about ``2^-100`` relative, so it rounds to the
nearest float64 unless the exact value lies within that distance of a midpoint between two floats,
which no tested argument does (``tests/sim/test_elementary.py`` checks the rounding against mpmath
at 200 bits). glibc's ``atan`` is not correctly rounded: on x86-64 (glibc 2.36, its FMA variant) it
is one ulp off on about 2 arguments in 1 000 of ``[0, 1]``, so adopting this function moved the last
bit of a few reported errors (CHANGELOG, numerics epoch of the scoring's angle).

``sin``, ``cos``, ``tan``, ``acos``, ``atan2``, and ``exp`` and ``log1p`` (the sensors' ziggurat,
``sim/pcg64``) are built the same way: a reduction and a series in double-double, rounded once
(each one's docstring states its order), checked against mpmath the same way.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.core import types
from numba.core.extending import intrinsic

from scftc_cli.sim.rows import PARALLEL_MIN_BATCH, run_rows


@intrinsic
def fma(typingctx, a, b, c):  # pragma: no cover - compiled
    """``a * b + c`` with one rounding (numba only): LLVM's ``llvm.fma.f64``, the hardware
    instruction where the CPU has one and a correctly rounded library call where not, so the same
    bits either way."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        return builder.fma(*args)

    return signature, codegen


# --- double-double arithmetic: (hi, lo) with |lo| <= ulp(hi) / 2 ------------------------------


@numba.njit(inline="always")
def _two_sum(a, b):  # pragma: no cover - compiled
    """``a + b`` exactly, as ``(s, e)`` with ``s = fl(a + b)`` (Knuth)."""
    s = a + b
    v = s - a
    return s, (a - (s - v)) + (b - v)


@numba.njit(inline="always")
def _quick_two_sum(a, b):  # pragma: no cover - compiled
    """``a + b`` exactly where ``|a| >= |b|`` (Dekker)."""
    s = a + b
    return s, b - (s - a)


@numba.njit(inline="always")
def _dd_add(ah, al, bh, bl):  # pragma: no cover - compiled
    s, e = _two_sum(ah, bh)
    t, f = _two_sum(al, bl)
    e += t
    s, e = _quick_two_sum(s, e)
    e += f
    return _quick_two_sum(s, e)


@numba.njit(inline="always")
def _dd_mul(ah, al, bh, bl):  # pragma: no cover - compiled
    p = ah * bh
    e = fma(ah, bh, -p)  # type: ignore[call-arg,var-annotated]
    e += ah * bl + al * bh
    return _quick_two_sum(p, e)


@numba.njit(inline="always")
def _dd_div(ah, al, bh, bl):  # pragma: no cover - compiled
    """``a / b`` by one Newton correction of the float64 quotient."""
    q1 = ah / bh
    ph, pl = _dd_mul(q1, 0.0, bh, bl)
    rh, rl = _dd_add(ah, al, -ph, -pl)
    q2 = rh / bh
    ph, pl = _dd_mul(q2, 0.0, bh, bl)
    rh, rl = _dd_add(rh, rl, -ph, -pl)
    q3 = rh / bh
    q1, q2 = _quick_two_sum(q1, q2)
    return _dd_add(q1, q2, q3, 0.0)


@numba.njit(inline="always")
def _dd_sqrt(ah, al):  # pragma: no cover - compiled
    """``sqrt a`` for ``a > 0`` by one Newton correction of the float64 root."""
    s = np.sqrt(ah)
    ph, pl = _dd_mul(s, 0.0, s, 0.0)
    rh, rl = _dd_add(ah, al, -ph, -pl)
    return _quick_two_sum(s, rh / (2.0 * s))


def _dd_constant(value) -> tuple[float, float]:
    """A rational ``value`` (``fractions.Fraction``) as a double-double ``(hi, lo)``."""
    from fractions import Fraction

    hi = float(value)
    return hi, float(Fraction(value) - Fraction(hi))


def _constants():
    from fractions import Fraction
    from math import factorial

    pi = Fraction("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899")
    ln2 = Fraction("0.693147180559945309417232121458176568075500134360255254120680009493393621969694715")

    def three_parts(value):
        p1 = float(value)
        p2 = float(value - Fraction(p1))
        return p1, p2, float(value - Fraction(p1) - Fraction(p2))

    inv_odd = [_dd_constant(Fraction(1, 2 * j + 1)) for j in range(max(_ATAN_TERMS, _LOG_TERMS))]
    inv_fact = [_dd_constant(Fraction(1, factorial(j))) for j in range(2 * _TRIG_TERMS + 2)]
    return (
        _dd_constant(pi / 2),
        _dd_constant(pi),
        three_parts(pi / 2),
        three_parts(ln2),
        np.array([c[0] for c in inv_odd]),
        np.array([c[1] for c in inv_odd]),
        np.array([c[0] for c in inv_fact]),
        np.array([c[1] for c in inv_fact]),
    )


_ATAN_TERMS = 12  # (-1)^j t^(2j+1) / (2j+1), j < 12: the next is below 2^-110 t for t <= 1/32
_TRIG_TERMS = 15  # sin r = sum_j (-1)^j r^(2j+1) / (2j+1)!, j < 15: the next below 2^-110 for |r| <= pi/4
_EXP_TERMS = 24  # e^r - 1 = sum_j r^j / j!, 0 < j <= 24: the next below 2^-120 for |r| <= ln2 / 2
_LOG_TERMS = 21  # atanh f = sum_j f^(2j+1) / (2j+1), j < 21: the next below 2^-112 f for |f| <= 0.172
(
    (_HALF_PI_HI, _HALF_PI_LO),
    (_PI_HI, _PI_LO),
    (_PIO2_1, _PIO2_2, _PIO2_3),
    (_LN2_1, _LN2_2, _LN2_3),
    _INV_ODD_HI,
    _INV_ODD_LO,
    _INV_FACT_HI,
    _INV_FACT_LO,
) = _constants()


@numba.njit(inline="always")
def _atan_dd(th, tl):  # pragma: no cover - compiled
    """``atan t`` as a double-double for a finite double-double ``t >= 0`` (module docstring)."""
    inverted = th > 1.0
    if inverted:
        th, tl = _dd_div(1.0, 0.0, th, tl)
    halvings = 0
    while th > 0.03125:
        sh, sl = _dd_mul(th, tl, th, tl)
        sh, sl = _dd_add(1.0, 0.0, sh, sl)
        sh, sl = _dd_sqrt(sh, sl)
        sh, sl = _dd_add(1.0, 0.0, sh, sl)
        th, tl = _dd_div(th, tl, sh, sl)
        halvings += 1
    uh, ul = _dd_mul(th, tl, th, tl)
    # as many terms as reach 2^-110 relative: (t^2)^j < 2^-110 with t < 2^e needs j > 55 / -e
    exponent = -math.frexp(th)[1]  # t < 2^-exponent (t = m 2^e, 1/2 <= m < 1)
    terms = min(_ATAN_TERMS, 55 // max(exponent, 1) + 2)
    ph, pl = _INV_ODD_HI[terms - 1], _INV_ODD_LO[terms - 1]
    for j in range(terms - 2, -1, -1):
        ph, pl = _dd_mul(ph, pl, -uh, -ul)
        ph, pl = _dd_add(_INV_ODD_HI[j], _INV_ODD_LO[j], ph, pl)
    ah, al = _dd_mul(th, tl, ph, pl)
    for _ in range(halvings):  # times 2 each: exact
        ah, al = 2.0 * ah, 2.0 * al
    if inverted:
        ah, al = _dd_add(_HALF_PI_HI, _HALF_PI_LO, -ah, -al)
    return ah, al


@numba.njit
def atan(x):  # pragma: no cover - compiled
    """``arctan x`` correctly rounded (module docstring); odd, ``atan(+-inf) = +-pi/2``, NaN
    for NaN, the sign of a zero kept."""
    if x != x or x == 0.0:
        return x
    sign = 1.0
    if x < 0.0:
        sign, x = -1.0, -x
    if x == np.inf:
        return sign * _HALF_PI_HI
    ah, al = _atan_dd(x, 0.0)
    return sign * (ah + al)


@numba.njit
def atan2(y, x):  # pragma: no cover - compiled
    """The angle of ``(x, y)`` in ``[-pi, pi]``, rounded once from a double-double ``atan(|y/x|)``
    moved to its quadrant; the special cases (zeros, infinities, NaN) as C99's ``atan2``."""
    if x != x or y != y:
        return x + y
    sign = math.copysign(1.0, y)
    ay, ax = abs(y), abs(x)
    negative_x = math.copysign(1.0, x) < 0.0
    if ay == 0.0:
        return sign * (_PI_HI if negative_x else 0.0)
    if ax == 0.0 or ay == np.inf and ax != np.inf:
        return sign * _HALF_PI_HI
    if ay == np.inf:  # and ax infinite: a quarter or three quarters of pi
        ah, al = _dd_mul(_HALF_PI_HI, _HALF_PI_LO, 0.5, 0.0)
        if negative_x:
            ah, al = _dd_add(_PI_HI, _PI_LO, -ah, -al)
        return sign * (ah + al)
    if ax == np.inf:
        return sign * (_PI_HI if negative_x else 0.0)
    qh, ql = _dd_div(ay, 0.0, ax, 0.0)
    if qh == np.inf:
        ah, al = _HALF_PI_HI, _HALF_PI_LO
    else:
        ah, al = _atan_dd(qh, ql)
    if negative_x:
        ah, al = _dd_add(_PI_HI, _PI_LO, -ah, -al)
    return sign * (ah + al)


@numba.njit
def acos(x):  # pragma: no cover - compiled
    """``arccos x`` in ``[0, pi]``: ``2 atan(sqrt((1 - x) / (1 + x)))`` in double-double, rounded
    once; NaN outside ``[-1, 1]``."""
    if not (-1.0 <= x <= 1.0):
        return np.nan
    if x == -1.0:
        return _PI_HI
    nh, nl = _two_sum(1.0, -x)
    dh, dl = _two_sum(1.0, x)
    qh, ql = _dd_div(nh, nl, dh, dl)
    if qh == 0.0:
        return 0.0
    qh, ql = _dd_sqrt(qh, ql)
    ah, al = _atan_dd(qh, ql)
    return 2.0 * ah + 2.0 * al


@numba.njit(inline="always")
def _reduce(x):  # pragma: no cover - compiled
    """``x = k pi/2 + r`` with ``|r| <= pi/4`` about: ``(k mod 4, r_hi, r_lo)``, ``r`` from ``pi/2``
    in three parts, each product exact (``fma``). The quadrant ``k mod 4`` stays a float (0., 1.,
    2. or 3.): no conversion to an integer, so that ``_cos_sin_rows``' loop vectorizes."""
    k = np.floor(x * (2.0 / _PI_HI) + 0.5)
    rh, rl = x, 0.0
    for part in (_PIO2_1, _PIO2_2):
        p = k * part
        e = fma(k, part, -p)  # type: ignore[call-arg,var-annotated]
        rh, rl = _dd_add(rh, rl, -p, -e)
    rh, rl = _dd_add(rh, rl, -k * _PIO2_3, 0.0)
    return k - 4.0 * np.floor(k / 4.0), rh, rl


@numba.njit
def _series_term(sh, sl, ch, cl, nuh, nul, j):  # pragma: no cover - compiled
    """One Horner step of both series at term ``j``: ``s = 1/(2j+1)! - u s``, ``c = 1/(2j)! - u c``
    (``nu = -u``). Left to LLVM to inline (it does): numba's own inlining of fourteen copies
    multiplied the compile time of every caller by about three."""
    sh, sl = _dd_mul(sh, sl, nuh, nul)
    sh, sl = _dd_add(_INV_FACT_HI[2 * j + 1], _INV_FACT_LO[2 * j + 1], sh, sl)
    ch, cl = _dd_mul(ch, cl, nuh, nul)
    ch, cl = _dd_add(_INV_FACT_HI[2 * j], _INV_FACT_LO[2 * j], ch, cl)
    return sh, sl, ch, cl


@numba.njit(inline="always")
def _sin_cos_dd(rh, rl):  # pragma: no cover - compiled
    """``(sin r, cos r)`` as double-doubles for ``|r| <= pi/4`` (Taylor series, Horner in ``r^2``,
    terms ``j = _TRIG_TERMS - 2`` down to 0 after the leading one).

    The steps are written out, not looped: LLVM vectorizes only innermost loops, so a loop here
    would keep ``_cos_sin_rows``' loop over rows scalar (measured: 3 to 4 times slower). The
    operations and their order are those of the loop they replace, so the bits are too."""
    uh, ul = _dd_mul(rh, rl, rh, rl)
    nuh, nul = -uh, -ul
    sh, sl = _INV_FACT_HI[2 * _TRIG_TERMS - 1], _INV_FACT_LO[2 * _TRIG_TERMS - 1]
    ch, cl = _INV_FACT_HI[2 * _TRIG_TERMS - 2], _INV_FACT_LO[2 * _TRIG_TERMS - 2]
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 13)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 12)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 11)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 10)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 9)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 8)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 7)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 6)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 5)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 4)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 3)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 2)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 1)
    sh, sl, ch, cl = _series_term(sh, sl, ch, cl, nuh, nul, 0)
    sh, sl = _dd_mul(rh, rl, sh, sl)
    return sh, sl, ch, cl


assert _TRIG_TERMS == 15, "_sin_cos_dd writes out the terms 13 to 0"

_TRIG_LIMIT = 2.0**20
"""Largest ``|x|`` ``sin``, ``cos`` and ``tan`` take (beyond it the reduction loses bits): NaN there."""


@numba.njit(inline="always")
def _sine_in_quadrant(q, sh, sl, ch, cl):  # pragma: no cover - compiled
    """``sin(q pi/2 + r)`` rounded once, from ``sin r`` and ``cos r`` as double-doubles: ``sin r``,
    ``cos r``, ``-sin r``, ``-cos r`` for the float ``q`` = 0, 1, 2, 3, and ``sin r`` again for 4
    (a cosine's quadrant, one on). Selects, not branches, so that a loop over rows vectorizes."""
    s, c = sh + sl, ch + cl
    v = s if q == 0.0 or q == 4.0 else c
    v = -s if q == 2.0 else v
    return -c if q == 3.0 else v


@numba.njit
def sin(x):  # pragma: no cover - compiled
    """``sin x`` for ``|x| <= 2^20``, rounded once from double-double (module docstring)."""
    if not abs(x) <= _TRIG_LIMIT:
        return np.nan
    if x == 0.0:
        return x
    quadrant, rh, rl = _reduce(x)
    sh, sl, ch, cl = _sin_cos_dd(rh, rl)
    return _sine_in_quadrant(quadrant, sh, sl, ch, cl)


@numba.njit
def cos(x):  # pragma: no cover - compiled
    """``cos x = sin(x + pi/2)`` for ``|x| <= 2^20``: one quadrant on, rounded once."""
    if not abs(x) <= _TRIG_LIMIT:
        return np.nan
    quadrant, rh, rl = _reduce(x)
    sh, sl, ch, cl = _sin_cos_dd(rh, rl)
    return _sine_in_quadrant(quadrant + 1.0, sh, sl, ch, cl)


@numba.njit
def tan(x):  # pragma: no cover - compiled
    """``tan x`` for ``|x| <= 2^20``: ``sin r / cos r`` (or ``-cos r / sin r`` in odd quadrants) in
    double-double, rounded once."""
    if not abs(x) <= _TRIG_LIMIT:
        return np.nan
    if x == 0.0:
        return x
    quadrant, rh, rl = _reduce(x)
    sh, sl, ch, cl = _sin_cos_dd(rh, rl)
    if quadrant == 0.0 or quadrant == 2.0:
        th, tl = _dd_div(sh, sl, ch, cl)
    else:
        th, tl = _dd_div(-ch, -cl, sh, sl)
    return th + tl


@numba.njit(inline="always")
def _add_k_ln2(k, ah, al):  # pragma: no cover - compiled
    """``a + k ln2`` as a double-double, for an integer-valued ``|k| <= 1100``: ``ln2`` in three
    parts, the first two products exact (``fma``), each added to the running sum in turn."""
    for part in (_LN2_1, _LN2_2):
        p = k * part
        e = fma(k, part, -p)  # type: ignore[call-arg,var-annotated]
        ah, al = _dd_add(ah, al, p, e)
    return _dd_add(ah, al, k * _LN2_3, 0.0)


_EXP_MAX = 709.8  # exp x overflows above ln(2^1024) = 709.78...
_EXP_MIN = -745.2  # and rounds to 0 below ln(2^-1075) = -745.13...


@numba.njit(inline="always")
def _one_plus(ph, pl):  # pragma: no cover - compiled
    """``1 + p`` for a double-double ``p``, rounded once: the sum exactly as ``w + g + f``
    (``w = fl(1 + ph + pl)``, three ``_two_sum``), and where ``w + g`` is a tie (``1 + x`` for
    ``x = 2^-53``, say), ``f`` breaks it."""
    s, e = _two_sum(1.0, ph)
    t, f = _two_sum(e, pl)
    w, g = _two_sum(s, t)
    if f != 0.0 and (w + 2.0 * g) - w == 2.0 * g and (f > 0.0) == (g > 0.0):
        return w + 2.0 * g
    return w


@numba.njit
def exp(x):  # pragma: no cover - compiled
    """``e^x``, correctly rounded as ``atan`` is where the result is normal (``x >= -708.39``):
    ``x = k ln2 + r`` with ``k`` the integer nearest ``x / ln2`` and ``|r| <= ln2 / 2`` in
    double-double (``_add_k_ln2``), ``e^r - 1 = r (1 + r/2! + ... + r^23 / 24!)`` (Horner, in
    double-double: its error is relative to ``e^r - 1``, so the ties of ``1 + r`` near ``r = 0``
    are decided), ``1 + (e^r - 1)`` rounded once (``_one_plus``) and scaled by ``2^k`` (``ldexp``:
    exact). Where the result is subnormal that scaling rounds a second time, so it can be one unit
    of the last subnormal place off. ``exp(+inf) = inf``, ``exp(-inf) = 0``, NaN for NaN."""
    if x != x:
        return x
    if x > _EXP_MAX:
        return np.inf
    if x < _EXP_MIN:
        return 0.0
    k = np.floor(x * (1.0 / _LN2_1) + 0.5)
    rh, rl = _add_k_ln2(-k, x, 0.0)
    ph, pl = _INV_FACT_HI[_EXP_TERMS], _INV_FACT_LO[_EXP_TERMS]
    for j in range(_EXP_TERMS - 1, 0, -1):
        ph, pl = _dd_mul(ph, pl, rh, rl)
        ph, pl = _dd_add(_INV_FACT_HI[j], _INV_FACT_LO[j], ph, pl)
    ph, pl = _dd_mul(ph, pl, rh, rl)
    return math.ldexp(_one_plus(ph, pl), int(k))


@numba.njit
def log1p(x):  # pragma: no cover - compiled
    """``ln(1 + x)``, correctly rounded as ``atan`` is: ``1 + x`` exactly as a double-double
    ``s = 2^k m`` with ``sqrt(1/2) <= m < sqrt(2)``, then ``ln s = k ln2 + 2 atanh f`` with
    ``f = (m - 1) / (m + 1)`` (``|f| <= 0.172``; the odd series of ``atanh``, as many terms as
    reach ``2^-110 f``, Horner in ``f^2``), all in double-double, rounded once; ``x`` itself
    where ``|x| < 2^-54``. ``-inf`` at ``-1``, NaN below it and for NaN, ``+inf`` at ``+inf``."""
    if not x > -1.0:
        return -np.inf if x == -1.0 else np.nan
    if abs(x) < 2.0**-54 or x == np.inf:
        return x  # ln(1 + x) = x - x^2 / 2 + ... rounds to x (the sign of a zero kept)
    sh, sl = _two_sum(1.0, x)
    mantissa, k = math.frexp(sh)  # sh = mantissa 2^k, 1/2 <= mantissa < 1
    if mantissa < 0.7071067811865476:
        k -= 1
    mh, ml = math.ldexp(sh, -k), math.ldexp(sl, -k)  # exact
    if k == 0:
        nh, nl = x, 0.0  # m - 1, exactly
    else:
        nh, nl = _dd_add(mh, ml, -1.0, 0.0)
    dh, dl = _dd_add(mh, ml, 1.0, 0.0)
    fh, fl = _dd_div(nh, nl, dh, dl)
    uh, ul = _dd_mul(fh, fl, fh, fl)
    exponent = -math.frexp(fh)[1]  # as in _atan_dd: |f| < 2^-exponent
    terms = min(_LOG_TERMS, 55 // max(exponent, 1) + 2)
    ph, pl = _INV_ODD_HI[terms - 1], _INV_ODD_LO[terms - 1]
    for j in range(terms - 2, -1, -1):
        ph, pl = _dd_mul(ph, pl, uh, ul)
        ph, pl = _dd_add(_INV_ODD_HI[j], _INV_ODD_LO[j], ph, pl)
    ah, al = _dd_mul(2.0 * fh, 2.0 * fl, ph, pl)
    ah, al = _add_k_ln2(float(k), ah, al)
    return ah + al


# --- short forms: the project's own, in plain float64, not correctly rounded --------------------
#
# Where a kernel calls a trigonometric function per candidate inside a hot loop, the double-double
# forms above cost too much (about 200 ns a call). These evaluate a fixed Taylor polynomial by
# Horner's rule in float64, in the order written: the same bits on every IEEE machine, within a few
# ulp of the exact value (checked against mpmath in tests/sim/test_elementary.py), and no library.


def _taylor(kind: str, terms: int) -> np.ndarray:
    """Coefficients, highest power first, in float64: ``asin`` (odd powers ``t^(2k+1)``: ``(2k)! /
    (4^k (k!)^2 (2k+1))``) or ``cos`` (even powers: ``(-1)^k / (2k)!``)."""
    from fractions import Fraction

    if kind == "asin":
        c = [
            Fraction(math.factorial(2 * k), 4**k * math.factorial(k) ** 2 * (2 * k + 1)) for k in range(terms)
        ]
    else:
        c = [Fraction((-1) ** k, math.factorial(2 * k)) for k in range(terms)]
    return np.array([float(v) for v in reversed(c)])


_ASIN_SHORT = _taylor("asin", 28)
"""``asin t`` on ``|t| <= 1/2``: 28 terms, the first omitted below ``2^-60`` there."""
_COS_SHORT = _taylor("cos", 12)
"""``cos x`` on ``|x| <= pi/2``: 12 terms (to ``x^22``), the first omitted below ``2^-62`` there."""
_HALF_PI = math.pi / 2.0


@numba.njit(inline="always")
def _asin_short(t):  # pragma: no cover - compiled
    """``asin t`` for ``|t| <= 1/2``: ``t (c0 + t^2 (c1 + ...))`` by Horner in ``t^2``."""
    u = t * t
    acc = _ASIN_SHORT[0]
    for k in range(1, _ASIN_SHORT.shape[0]):
        acc = acc * u + _ASIN_SHORT[k]
    return t * acc


@numba.njit(inline="always")
def acos_short(x):  # pragma: no cover - compiled
    """``acos x`` for ``x`` in [-1, 1] (the short form): ``pi/2 - asin x`` for ``|x| <= 1/2``, else
    ``2 asin(sqrt((1 - x) / 2))`` or ``pi - 2 asin(sqrt((1 + x) / 2))``."""
    if abs(x) <= 0.5:
        return _HALF_PI - _asin_short(x)
    if x > 0.0:
        return 2.0 * _asin_short(math.sqrt((1.0 - x) / 2.0))
    return math.pi - 2.0 * _asin_short(math.sqrt((1.0 + x) / 2.0))


@numba.njit(inline="always")
def cos_short(x):  # pragma: no cover - compiled
    """``cos x`` for ``x`` in [0, pi] (the short form): the Taylor polynomial in ``x^2`` on [0, pi/2],
    ``-cos(pi - x)`` above."""
    sign = 1.0
    if x > _HALF_PI:
        x, sign = math.pi - x, -1.0
    u = x * x
    acc = _COS_SHORT[0]
    for k in range(1, _COS_SHORT.shape[0]):
        acc = acc * u + _COS_SHORT[k]
    return sign * acc


@numba.njit(cache=True)
def short_rows(x, out_acos, out_cos):  # pragma: no cover - compiled
    """``acos_short`` of ``x`` in [-1, 1] and ``cos_short`` of ``(x + 1) pi / 2`` (for the tests)."""
    for i in range(x.shape[0]):
        out_acos[i] = acos_short(x[i])
        out_cos[i] = cos_short((x[i] + 1.0) * _HALF_PI)


@numba.njit(cache=True, parallel=True)
def _unary_rows(which, x, out):  # pragma: no cover - compiled
    for i in numba.prange(x.size):
        v = x[i]
        if which == 0:
            out[i] = atan(v)
        elif which == 1:
            out[i] = acos(v)
        elif which == 2:
            out[i] = sin(v)
        elif which == 3:
            out[i] = cos(v)
        else:
            out[i] = tan(v)


@numba.njit(cache=True)
def _atan2_rows(y, x, out):  # pragma: no cover - compiled
    for i in range(y.size):
        out[i] = atan2(y[i], x[i])


@numba.njit(cache=True, parallel=True)
def _cos_sin_rows(x, out_cos, out_sin):  # pragma: no cover - compiled
    """``cos`` and ``sin`` of every ``x[i]``: ``cos``'s and ``sin``'s operations, without a branch
    (an argument out of range flies as 0 and its results are replaced by NaN), so that LLVM
    vectorizes the loop over rows; the same bits as the scalar functions."""
    for i in numba.prange(x.size):
        v = x[i]
        ok = abs(v) <= _TRIG_LIMIT
        q, rh, rl = _reduce(v if ok else 0.0)
        sh, sl, ch, cl = _sin_cos_dd(rh, rl)
        out_cos[i] = _sine_in_quadrant(q + 1.0, sh, sl, ch, cl) if ok else np.nan
        out_sin[i] = v if v == 0.0 else (_sine_in_quadrant(q, sh, sl, ch, cl) if ok else np.nan)


def _unary(which: int, x: np.ndarray | float) -> np.ndarray:
    flat = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    out = np.empty_like(flat)
    run_rows(_unary_rows, which, flat, out, parallel=flat.size >= PARALLEL_MIN_BATCH)
    return out.reshape(np.shape(x))


def arctan(x: np.ndarray | float) -> np.ndarray:
    """``atan`` elementwise over any array (a float64 array of ``x``'s shape)."""
    return _unary(0, x)


def arccos(x: np.ndarray | float) -> np.ndarray:
    """``acos`` elementwise."""
    return _unary(1, x)


def sine(x: np.ndarray | float) -> np.ndarray:
    """``sin`` elementwise."""
    return _unary(2, x)


def cosine(x: np.ndarray | float) -> np.ndarray:
    """``cos`` elementwise."""
    return _unary(3, x)


def cosine_sine(x: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """``(cos x, sin x)`` elementwise, the same bits as ``cosine`` and ``sine`` for the price of
    one: both come from one reduction and one pair of series."""
    flat = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    out_cos, out_sin = np.empty_like(flat), np.empty_like(flat)
    run_rows(_cos_sin_rows, flat, out_cos, out_sin, parallel=flat.size >= PARALLEL_MIN_BATCH)
    return out_cos.reshape(np.shape(x)), out_sin.reshape(np.shape(x))


def tangent(x: np.ndarray | float) -> np.ndarray:
    """``tan`` elementwise."""
    return _unary(4, x)


def arctan2(y: np.ndarray | float, x: np.ndarray | float) -> np.ndarray:
    """``atan2`` elementwise, ``y`` and ``x`` broadcast."""
    yb, xb = np.broadcast_arrays(np.asarray(y, dtype=np.float64), np.asarray(x, dtype=np.float64))
    flat_y, flat_x = np.ascontiguousarray(yb).reshape(-1), np.ascontiguousarray(xb).reshape(-1)
    out = np.empty_like(flat_y)
    _atan2_rows(flat_y, flat_x, out)
    return out.reshape(yb.shape)
