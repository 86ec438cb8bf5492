"""Inference of the learned controllers' recurrent networks: numba kernels, no torch.

The weights are trained in float32 with torch (``scftc_cli/training``) and evaluated here in
float64, one kernel call per control step for the whole batch. Every number must come out with
the same bits on every x86-64 machine, so the kernels avoid everything whose last bit depends on
the CPU or the library build:

- matrix-vector products are explicit loops that sum each output in one fixed order (over the
  inputs, first to last, then the bias), never BLAS (whose blocking and SIMD width change the
  order between machines);
- ``exp`` and ``tanh`` are computed here from ``+ - * /`` only (Cody-Waite range reduction and a
  Taylor polynomial; see ``_reduce``), not by numpy's SIMD kernels, whose last bit differs between
  CPUs, nor by libm: glibc's ``tanh`` goes through ``expm1``, which glibc 2.36 picks per CPU at
  load time (an ifunc with an FMA variant), and at ~17 ns a call it would cost more than the whole
  network. Errors within 1.5 ulp for ``exp`` and 3.5 ulp for ``tanh`` (measured 1.13 and 2.95;
  ``tests/baselines/test_inference.py`` checks both against extended precision);
- no fast-math and no parallel reduction: LLVM then emits IEEE operations as written (no
  reassociation, no contraction into fused multiply-adds), and vectorizes only across outputs,
  which does not change any single output's operations. Threads share out whole rows (chunks of
  ``CHUNK_ROWS``, through ``sim/rows.run_rows``), so which thread computes a row changes no bit.
  ``error_model="numpy"``: a division is IEEE (no zero check, which would keep the loops from
  vectorizing).

``softplus`` keeps libm's ``log1p`` (one call per sequence and step; not CPU-dispatched in glibc
2.36). ``tests/baselines/test_inference.py`` pins the bits of both kernels on fixed inputs. Torch
computes the same functions with its own kernels (BLAS sums, SLEEF functions), so the two agree to
rounding, not to the bit: ~1e-14 of each sequence's scale over whole episodes, and the numba
kernels are at least as close to an extended-precision evaluation as torch is.

Weights live in ``.npz`` files (float32 arrays as trained, keyed like the torch state dict, and the
architecture as a JSON string under ``config``), written with fixed zip timestamps so that the
same weights give the same bytes; they load with ``allow_pickle=False``.
"""

from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from scftc_cli.errors import ScftcError
from scftc_cli.sim.rows import CHUNK_ROWS

CONFIG_KEY = "config"
_ZIP_EPOCH = (1980, 1, 1, 0, 0, 0)


def save_weights(path: Path, arrays: dict[str, np.ndarray], config: dict[str, Any]) -> Path:
    """Write the float32 ``arrays`` and ``config`` (JSON) to the ``.npz`` file ``path``.

    The bytes depend only on the contents (entries in the given order, fixed timestamps)."""
    if CONFIG_KEY in arrays:
        raise ValueError(f"`{CONFIG_KEY}` is reserved for the configuration")
    wrong = sorted(k for k, v in arrays.items() if np.asarray(v).dtype != np.float32)
    if wrong:
        raise ValueError(f"weights are stored as trained, in float32; got another dtype for {wrong}")
    path.parent.mkdir(parents=True, exist_ok=True)
    entries = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
    entries[CONFIG_KEY] = np.array(json.dumps(config, sort_keys=True))
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED) as archive:
        for key, value in entries.items():
            with archive.open(zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_EPOCH), "w") as f:
                np.lib.format.write_array(f, value, allow_pickle=False)
    return path


def load_weights(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(arrays, config)`` of a file written by ``save_weights`` (no pickle, no torch).

    Raises:
        ScftcError: ``path`` is not such a file (e.g. a torch ``.pt`` state dict).
    """
    try:
        with np.load(path, allow_pickle=False) as blob:
            if not isinstance(blob, np.lib.npyio.NpzFile) or CONFIG_KEY not in blob.files:
                raise ValueError("no weights archive with a `config` entry")
            config = json.loads(str(blob[CONFIG_KEY][()]))
            arrays = {k: blob[k] for k in blob.files if k != CONFIG_KEY}
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        raise ScftcError(f"{path} is not a weights file written by `scftc train` (.npz): {err}") from err
    if not all(isinstance(a, np.ndarray) and a.dtype == np.float32 for a in arrays.values()):
        raise ScftcError(f"{path} holds entries that are not float32 arrays")
    return arrays, config


def transposed(weight: np.ndarray) -> np.ndarray:
    """A torch ``(out, in)`` weight as the kernels' contiguous float64 ``(in, out)`` layout
    (float32 -> float64 is exact)."""
    return np.ascontiguousarray(np.asarray(weight, dtype=np.float64).T)


def as_float64(bias: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(bias, dtype=np.float64)


# ---------------------------------------------------------------------------------------------
# Elementary functions from + - * / only.

_INV_LN2 = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01  # 32 significant bits: n * _LN2_HI is exact for |n| < 2^21
_LN2_LO = 1.90821492927058770002e-10
_SHIFT = 6755399441055744.0  # 1.5 * 2^52: (v + _SHIFT) - _SHIFT rounds v to an integer
_EXP_MIN, _EXP_MAX = -708.0, 709.0  # exp stays a normal number
_TANH_CLAMP = 20.0  # tanh(20) rounds to 1


@intrinsic
def _float_from_bits(typingctx, bits):
    """The float64 whose IEEE bits are the int64 ``bits`` (a plain bit cast)."""
    if not isinstance(bits, types.Integer):
        return None
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


@intrinsic
def _bits_from_float(typingctx, x):
    """The int64 whose bits are those of the float64 ``x`` (a plain bit cast)."""
    if not isinstance(x, types.Float):
        return None
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


_SHIFT_BITS = int(np.float64(_SHIFT).view(np.int64))


@numba.njit(error_model="numpy")
def _reduce(x):
    """``(2^n, e^r - 1)`` with ``x = n ln2 + r``, ``|r| <= ln2 / 2`` (Cody-Waite, ``ln2`` in two
    parts; ``x`` within [-708, 709]), ``e^r - 1`` by its Taylor polynomial to ``r^13`` (remainder
    < 5e-18 relative) and ``2^n`` built from its bits.

    ``n`` is read off the bits of ``x / ln2 + _SHIFT``, whose last bits hold it as an integer
    (``_SHIFT`` = 1.5 * 2^52 fixes the exponent), instead of converting the float ``n`` to an
    integer: the same ``2^n``, with integer operations LLVM vectorizes on every x86-64 (a float to
    int64 conversion vectorizes only with AVX-512DQ)."""
    shifted = x * _INV_LN2 + _SHIFT
    n = shifted - _SHIFT
    r = (x - n * _LN2_HI) - n * _LN2_LO
    q = 1.6059043836821613e-10  # 1/13!
    q = q * r + 2.08767569878681e-09
    q = q * r + 2.505210838544172e-08
    q = q * r + 2.755731922398589e-07
    q = q * r + 2.755731922398589e-06
    q = q * r + 2.48015873015873e-05
    q = q * r + 0.0001984126984126984
    q = q * r + 0.001388888888888889
    q = q * r + 0.008333333333333333
    q = q * r + 0.041666666666666664
    q = q * r + 0.16666666666666666
    q = q * r + 0.5
    q = q * r + 1.0
    return _float_from_bits((_bits_from_float(shifted) - _SHIFT_BITS + 1023) << 52), q * r  # type: ignore[call-arg]


@numba.njit(error_model="numpy")
def _exp(x):
    """``e^x = 2^n (1 + (e^r - 1))``, ``x`` clamped to [-708, 709] (a normal result)."""
    scale, q = _reduce(min(max(x, _EXP_MIN), _EXP_MAX))
    return scale * (1.0 + q)


@numba.njit(error_model="numpy")
def _tanh(x):
    """``tanh x = E / (E + 2)`` with ``E = expm1(2|x|) = 2^n (e^r - 1) + (2^n - 1)`` (two terms of
    one sign unless ``r < 0``, then at most a factor 2.5 cancels; exact ``e^r - 1`` for ``n = 0``,
    i.e. small ``x``); the sign of ``x`` (and of zero) kept; ``|x|`` clamped at 20, where tanh rounds
    to 1."""
    scale, q = _reduce(2.0 * min(abs(x), _TANH_CLAMP))
    e = scale * q + (scale - 1.0)
    return math.copysign(e / (e + 2.0), x)


@numba.njit(error_model="numpy")
def _sigmoid(x):
    """``1 / (1 + e^-x)``, as torch computes it."""
    return 1.0 / (1.0 + _exp(-x))


@numba.njit(error_model="numpy")
def _softplus(x):
    """torch's ``softplus`` (beta 1, threshold 20): ``x`` above 20, else ``log1p(e^x)``."""
    if x > 20.0:
        return x
    return math.log1p(_exp(x))


@numba.njit(cache=True, error_model="numpy")
def exp_array(x):
    """``_exp`` elementwise over a 1-d array (for the tests)."""
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        out[i] = _exp(x[i])
    return out


@numba.njit(cache=True, error_model="numpy")
def tanh_array(x):
    """``_tanh`` elementwise over a 1-d array (for the tests)."""
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        out[i] = _tanh(x[i])
    return out


# ---------------------------------------------------------------------------------------------
# Layers, on blocks of ``ROWS`` sequences at a time (each weight loaded once for the block). ``w``
# is a transposed weight ``(in, out)``. Every output of every row sums its products in one fixed
# order, ``((0 + w_0 v_0) + w_1 v_1) + ...`` over the inputs first to last, then adds the bias,
# whatever block the row sits in; the loops over outputs are the ones LLVM vectorizes, and four
# inputs are folded in per pass so that the partial sums stay in registers for four products.

ROWS = 4
assert CHUNK_ROWS % ROWS == 0  # a thread's chunk of rows (sim/rows.py) is whole blocks


@numba.njit(error_model="numpy")
def _affine(w, b, v, out):
    """``out[r, :n_out] = v[r, :n_in] @ w + b`` for the ``ROWS`` rows ``r`` of ``v`` and ``out``."""
    n_in, n_out = w.shape
    for i in range(n_out):
        out[0, i] = 0.0
        out[1, i] = 0.0
        out[2, i] = 0.0
        out[3, i] = 0.0
    j = 0
    while j + 4 <= n_in:
        a0, a1, a2, a3 = v[0, j], v[0, j + 1], v[0, j + 2], v[0, j + 3]
        b0, b1, b2, b3 = v[1, j], v[1, j + 1], v[1, j + 2], v[1, j + 3]
        c0, c1, c2, c3 = v[2, j], v[2, j + 1], v[2, j + 2], v[2, j + 3]
        d0, d1, d2, d3 = v[3, j], v[3, j + 1], v[3, j + 2], v[3, j + 3]
        for i in range(n_out):
            w0, w1, w2, w3 = w[j, i], w[j + 1, i], w[j + 2, i], w[j + 3, i]
            out[0, i] = (((out[0, i] + w0 * a0) + w1 * a1) + w2 * a2) + w3 * a3
            out[1, i] = (((out[1, i] + w0 * b0) + w1 * b1) + w2 * b2) + w3 * b3
            out[2, i] = (((out[2, i] + w0 * c0) + w1 * c1) + w2 * c2) + w3 * c3
            out[3, i] = (((out[3, i] + w0 * d0) + w1 * d1) + w2 * d2) + w3 * d3
        j += 4
    while j < n_in:
        a0, b0, c0, d0 = v[0, j], v[1, j], v[2, j], v[3, j]
        for i in range(n_out):
            w0 = w[j, i]
            out[0, i] = out[0, i] + w0 * a0
            out[1, i] = out[1, i] + w0 * b0
            out[2, i] = out[2, i] + w0 * c0
            out[3, i] = out[3, i] + w0 * d0
        j += 1
    for i in range(n_out):
        out[0, i] = out[0, i] + b[i]
        out[1, i] = out[1, i] + b[i]
        out[2, i] = out[2, i] + b[i]
        out[3, i] = out[3, i] + b[i]


@numba.njit(cache=True, error_model="numpy")
def affine_rows(w, b, v):
    """``_affine`` over every row of ``v`` ``(B, n_in)`` -> ``(B, n_out)`` (for the tests)."""
    n_rows = v.shape[0]
    out = np.empty((n_rows, w.shape[1]))
    vb = np.zeros((ROWS, w.shape[0]))
    ob = np.empty((ROWS, w.shape[1]))
    for start in range(0, n_rows, ROWS):
        rows = min(ROWS, n_rows - start)
        vb[:rows] = v[start : start + rows]
        _affine(w, b, vb, ob)
        out[start : start + rows] = ob[:rows]
    return out


@numba.njit(error_model="numpy")
def _student_rows(
    todo,
    lo,
    hi,
    x,
    scale,
    h,
    sums,
    theta,
    w_in,
    b_in,
    w_ih,
    b_ih,
    w_hh,
    b_hh,
    w_1,
    b_1,
    w_2,
    b_2,
    col_x,
    col_y,
    col_valid,
    prior_weight,
    log_mag_min,
    log_mag_max,
):
    """``student_step`` for the rows ``todo[lo:hi]``."""
    n_feat = x.shape[1]
    hidden = h.shape[1]
    xs = np.zeros((ROWS, n_feat))
    u = np.empty((ROWS, hidden))
    hb = np.zeros((ROWS, hidden))
    gi = np.empty((ROWS, 3 * hidden))
    gh = np.empty((ROWS, 3 * hidden))
    t = np.empty((ROWS, hidden))
    out = np.empty((ROWS, 3))
    for start in range(lo, hi, ROWS):
        rows = min(ROWS, hi - start)
        for k in range(rows):
            row = todo[start + k]
            for j in range(n_feat):
                xs[k, j] = x[row, j] * scale[j]
            for i in range(hidden):
                hb[k, i] = h[row, i]
        _affine(w_in, b_in, xs, u)
        for k in range(ROWS):
            for i in range(hidden):
                u[k, i] = _tanh(u[k, i])
        _affine(w_ih, b_ih, u, gi)
        _affine(w_hh, b_hh, hb, gh)
        for k in range(ROWS):
            for i in range(hidden):
                r = _sigmoid(gh[k, i] + gi[k, i])
                z = _sigmoid(gh[k, hidden + i] + gi[k, hidden + i])
                n = _tanh(gi[k, 2 * hidden + i] + gh[k, 2 * hidden + i] * r)
                hb[k, i] = (hb[k, i] - n) * z + n
        _affine(w_1, b_1, hb, t)
        for k in range(ROWS):
            for i in range(hidden):
                t[k, i] = _tanh(t[k, i])
        _affine(w_2, b_2, t, out)
        for k in range(rows):
            row = todo[start + k]
            for i in range(hidden):
                h[row, i] = hb[k, i]
            log_mag = min(max(out[k, 1], log_mag_min), log_mag_max)
            prior = _tanh(0.5 * out[k, 0]) * _exp(log_mag)
            wx = (_softplus(out[k, 2]) * x[row, col_valid]) * x[row, col_x]
            sums[row, 0] = sums[row, 0] + wx * x[row, col_y]
            sums[row, 1] = sums[row, 1] + wx * x[row, col_x]
            theta[row] = (sums[row, 0] + prior_weight * prior) / (sums[row, 1] + prior_weight)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def student_step(
    x,
    active,
    scale,
    h,
    sums,
    theta,
    w_in,
    b_in,
    w_ih,
    b_ih,
    w_hh,
    b_hh,
    w_1,
    b_1,
    w_2,
    b_2,
    col_x,
    col_y,
    col_valid,
    prior_weight,
    log_mag_min,
    log_mag_max,
):
    """One step of the RMA student (``training/student.py``'s ``StudentModule``) for the rows of
    ``x`` ``(B, F)`` where ``active`` ``(B,)`` is set; the other rows (latched axes) are left as they are.

    Updates the GRU state ``h`` ``(B, H)`` and the running sums ``sums`` ``(B, 2)`` (``sum w x y``,
    ``sum w x^2``) in place and writes ``theta_hat`` into ``theta`` ``(B,)``, with the torch module's
    operations: ``u = tanh(W_in (x * scale) + b_in)``; GRU with ``r = sigmoid(h_r + i_r)``,
    ``z = sigmoid(h_z + i_z)``, ``n = tanh(i_n + h_n r)``, ``h' = (h - n) z + n``; head
    ``(logit, log_mag, w_raw) = W_2 tanh(W_1 h' + b_1) + b_2``; prior ``tanh(logit / 2)
    e^clamp(log_mag)``; ``wx = (softplus(w_raw) x_valid) x``; ``sxy += wx y``, ``sxx += wx x``;
    ``theta = (sxy + P prior) / (sxx + P)``.
    """
    todo = np.flatnonzero(active)
    chunks = (todo.shape[0] + CHUNK_ROWS - 1) // CHUNK_ROWS
    for chunk in numba.prange(chunks):
        lo = chunk * CHUNK_ROWS
        hi = min(lo + CHUNK_ROWS, todo.shape[0])
        _student_rows(
            todo,
            lo,
            hi,
            x,
            scale,
            h,
            sums,
            theta,
            w_in,
            b_in,
            w_ih,
            b_ih,
            w_hh,
            b_hh,
            w_1,
            b_1,
            w_2,
            b_2,
            col_x,
            col_y,
            col_valid,
            prior_weight,
            log_mag_min,
            log_mag_max,
        )


@numba.njit(error_model="numpy")
def _policy_rows(lo, hi, x, h, c, action, w_ih, b_ih, w_hh, b_hh, w_mlp, b_mlp, w_out, b_out):
    """``policy_step`` for the rows ``lo..hi-1``."""
    n_in = x.shape[1]
    hidden = h.shape[1]
    n_act = w_out.shape[1]
    width = hidden
    for w in w_mlp:
        width = max(width, w.shape[1])
    xb = np.zeros((ROWS, n_in))
    hb = np.zeros((ROWS, hidden))
    cb = np.zeros((ROWS, hidden))
    gi = np.empty((ROWS, 4 * hidden))
    gh = np.empty((ROWS, 4 * hidden))
    a = np.empty((ROWS, width))
    y = np.empty((ROWS, width))
    out = np.empty((ROWS, n_act))
    for start in range(lo, hi, ROWS):
        rows = min(ROWS, hi - start)
        for k in range(rows):
            for j in range(n_in):
                xb[k, j] = x[start + k, j]
            for i in range(hidden):
                hb[k, i] = h[start + k, i]
                cb[k, i] = c[start + k, i]
        _affine(w_ih, b_ih, xb, gi)
        _affine(w_hh, b_hh, hb, gh)
        for k in range(ROWS):
            for i in range(hidden):
                ig = _sigmoid(gh[k, i] + gi[k, i])
                fg = _sigmoid(gh[k, hidden + i] + gi[k, hidden + i])
                cg = _tanh(gh[k, 2 * hidden + i] + gi[k, 2 * hidden + i])
                og = _sigmoid(gh[k, 3 * hidden + i] + gi[k, 3 * hidden + i])
                cb[k, i] = fg * cb[k, i] + ig * cg
                hb[k, i] = og * _tanh(cb[k, i])
        for k in range(ROWS):
            for i in range(hidden):
                a[k, i] = hb[k, i]
        for layer in range(len(w_mlp)):
            w = w_mlp[layer]
            _affine(w, b_mlp[layer], a, y)
            for k in range(ROWS):
                for i in range(w.shape[1]):
                    a[k, i] = _tanh(y[k, i])
        _affine(w_out, b_out, a, out)
        for k in range(rows):
            for i in range(hidden):
                h[start + k, i] = hb[k, i]
                c[start + k, i] = cb[k, i]
            for i in range(n_act):
                action[start + k, i] = out[k, i]


@numba.njit(cache=True, error_model="numpy", parallel=True)
def policy_step(x, h, c, action, w_ih, b_ih, w_hh, b_hh, w_mlp, b_mlp, w_out, b_out):
    """One step of the e2e actor (``RecurrentPolicy``, ``training/policy.py``) for every row of the
    scaled input ``x`` ``(B, 9)``: LSTM (gates ``(W_hh h + b_hh) + (W_ih x + b_ih)``, split into
    input, forget, cell and output gates; ``c' = f c + i g``, ``h' = o tanh(c')``), a tanh layer per
    entry of the tuples ``w_mlp``, ``b_mlp``, then the linear action head. Updates ``h`` and ``c``
    ``(B, H)`` in place and writes the unclipped mean action into ``action`` ``(B, 3)``."""
    n_rows = x.shape[0]
    chunks = (n_rows + CHUNK_ROWS - 1) // CHUNK_ROWS
    for chunk in numba.prange(chunks):
        lo = chunk * CHUNK_ROWS
        _policy_rows(
            lo,
            min(lo + CHUNK_ROWS, n_rows),
            x,
            h,
            c,
            action,
            w_ih,
            b_ih,
            w_hh,
            b_hh,
            w_mlp,
            b_mlp,
            w_out,
            b_out,
        )
