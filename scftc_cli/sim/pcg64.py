"""numpy's ``PCG64`` streams and their standard normals, drawn inside a numba kernel.

``Generator(PCG64(seed)).standard_normal()`` is numpy's ziggurat (``random_standard_normal`` in
numpy's ``distributions.c``) on PCG64's 64-bit outputs (``pcg64.h``: the 128-bit LCG step
``state = state * M + inc``, then the XSL-RR output of the new state). ``standard_normal`` below
is the same algorithm, the same tables and the same floating-point operations, except that the
wedges' ``exp`` and the tail's ``log1p`` are the project's own (``sim/elementary``: correctly
rounded, the same bits on every machine) where numpy calls libm's. A kernel that draws a stream's
normals one at a time gets the numbers numpy would have drawn from it, and ends at the same place
in the stream, but for the last bit of a few draws beyond ``r = 3.654`` (the tail, one draw in
4 000): glibc 2.36's ``log1p`` is one ulp off on about 7 in 100 of the tail's arguments, which
moves about one tail draw in 200 by one ulp (36 of 32 million draws; glibc's ``exp`` is off on
about 7 wedge arguments in 10 000, but no wedge test flipped). ``tests/sim/test_pcg64.py`` checks
the body and the wedges against numpy bit for bit on millions of draws, and the tail against
numpy's tail with mpmath's ``log1p``. What it buys: one Python call per batch instead
of one per episode, no block of normals in memory, and the draws of different episodes can run in
parallel.

A stream's state is four ``uint64`` words, ``(state >> 64, state & M64, inc >> 64, inc & M64)``;
a batch of streams is an ``(n, 4)`` ``uint64`` array (``states_of``), advanced in place.
``seeded_states`` seeds a batch as ``PCG64(SeedSequence(entropy))`` would (numpy's
``bit_generator.pyx``: the SeedSequence's hash mixing of the entropy into a pool of four words,
``generate_state(4, uint64)``, then ``pcg64_set_seed``), without building a Python object per
stream: seeding 10 000 streams took about a second in Python.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.core.extending import intrinsic

# numpy's ziggurat tables for the normal distribution (numpy/random/src/distributions/
# ziggurat_constants.h), as numba's own Generator support carries them
from numba.np.random._constants import (
    fi_double,
    ki_double,
    wi_double,
    ziggurat_nor_inv_r,
    ziggurat_nor_r,
)

from scftc_cli.sim.elementary import exp, log1p

_MASK64 = (1 << 64) - 1
_MULT_HI = np.uint64(2549297995355413924)  # PCG_DEFAULT_MULTIPLIER_128, high and low words
_MULT_LO = np.uint64(4865540595714422341)
_KI = np.asarray(ki_double, dtype=np.uint64)
_WI = np.asarray(wi_double, dtype=np.float64)
_FI = np.asarray(fi_double, dtype=np.float64)
_R = float(ziggurat_nor_r)
_INV_R = float(ziggurat_nor_inv_r)
_U0, _U1, _U8, _U11, _U58, _U63, _U64 = (np.uint64(v) for v in (0, 1, 8, 11, 58, 63, 64))
_U255 = np.uint64(0xFF)
_U52 = np.uint64(0x000FFFFFFFFFFFFF)
_TO_DOUBLE = 1.0 / 9007199254740992.0  # 2^-53, numpy's next_double


def states_of(generators: Sequence[np.random.Generator]) -> np.ndarray:
    """``(n, 4)`` ``uint64`` states of ``n`` PCG64 generators, as they stand (a copy: drawing from
    it leaves the generators where they are)."""
    out = np.empty((len(generators), 4), dtype=np.uint64)
    for e, generator in enumerate(generators):
        state = generator.bit_generator.state
        if state["bit_generator"] != "PCG64":
            raise ValueError(f"a PCG64 stream is needed, got {state['bit_generator']}")
        s, inc = state["state"]["state"], state["state"]["inc"]
        out[e] = (s >> 64, s & _MASK64, inc >> 64, inc & _MASK64)
    return out


@intrinsic
def _mulhi(typingctx, a, b):
    """The high 64 bits of the 128-bit product of two ``uint64`` (one ``mul`` instruction)."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, signature, args):
        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


@numba.njit(inline="always")
def next_uint64(state: np.ndarray, e: int) -> np.uint64:  # pragma: no cover - compiled
    """Advance stream ``e`` of ``state`` ``(n, 4)`` one step; its next 64-bit output."""
    hi, lo = state[e, 0], state[e, 1]
    product_lo = lo * _MULT_LO
    product_hi = _mulhi(lo, _MULT_LO) + lo * _MULT_HI + hi * _MULT_LO  # type: ignore[call-arg]
    new_lo = product_lo + state[e, 3]
    carry = _U1 if new_lo < product_lo else _U0
    new_hi = product_hi + state[e, 2] + carry
    state[e, 0], state[e, 1] = new_hi, new_lo
    word = new_hi ^ new_lo
    turn = new_hi >> _U58
    return (word >> turn) | (word << ((_U64 - turn) & _U63))


@numba.njit(inline="always")
def next_double(state: np.ndarray, e: int) -> float:  # pragma: no cover - compiled
    """numpy's ``next_double``: the top 53 bits of the next output, in [0, 1)."""
    return float(next_uint64(state, e) >> _U11) * _TO_DOUBLE


@numba.njit(inline="always")
def _tail(state: np.ndarray, e: int, negative: bool) -> float:  # pragma: no cover - compiled
    """A normal beyond ``r``, numpy's tail (Marsaglia's): ``1 - U`` so that the log never sees 0."""
    while True:
        xx = -_INV_R * log1p(-next_double(state, e))
        yy = -log1p(-next_double(state, e))
        if yy + yy > xx * xx:
            return -(_R + xx) if negative else _R + xx


@numba.njit(inline="always")
def standard_normal(state: np.ndarray, e: int) -> float:  # pragma: no cover - compiled
    """The next standard normal of stream ``e``: numpy's ``random_standard_normal``."""
    while True:
        r = next_uint64(state, e)
        idx = r & _U255
        r = r >> _U8
        rabs = (r >> _U1) & _U52
        x = float(rabs) * _WI[idx]
        if r & _U1:
            x = -x
        if rabs < _KI[idx]:
            return x  # 99.3 % of the draws
        if idx == 0:
            return _tail(state, e, (rabs >> _U8) & _U1 != _U0)
        if (_FI[idx - _U1] - _FI[idx]) * next_double(state, e) + _FI[idx] < exp(-0.5 * x * x):
            return x


@numba.njit(cache=True)
def fill_standard_normal(state: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """``out[e] = `` the next ``out.shape[1]`` normals of stream ``e``, for every row ``e``
    (what ``generator.standard_normal(out=out[e])`` draws)."""
    for e in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[e, j] = standard_normal(state, e)


_M32 = np.uint64(0xFFFFFFFF)
_U16, _U32 = np.uint64(16), np.uint64(32)
# SeedSequence's hash constants (numpy/random/bit_generator.pyx), uint32 arithmetic
_INIT_A, _MULT_A = np.uint64(0x43B0D7E5), np.uint64(0x931E8875)
_INIT_B, _MULT_B = np.uint64(0x8B51F9DD), np.uint64(0x58F38DED)
_MIX_MULT_L, _MIX_MULT_R = np.uint64(0xCA01F9DD), np.uint64(0x4973F715)
POOL_WORDS = 4  # SeedSequence's default pool size


@numba.njit(inline="always")
def _hashmix(value, hash_const):  # pragma: no cover - compiled
    value = (value ^ hash_const) & _M32
    hash_const = (hash_const * _MULT_A) & _M32
    value = (value * hash_const) & _M32
    return value ^ (value >> _U16), hash_const


@numba.njit(inline="always")
def _mix(x, y):  # pragma: no cover - compiled
    result = (_MIX_MULT_L * x - _MIX_MULT_R * y) & _M32
    return result ^ (result >> _U16)


def numpy_stream(entropy: np.ndarray, spawn_key: tuple[int, ...] = ()) -> np.random.Generator:
    """The numpy generator whose state ``seeded_states`` computes for one row of ``entropy``:
    ``Generator(PCG64(SeedSequence(entropy.tolist(), spawn_key=spawn_key)))`` (what the readable
    references draw from)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy.tolist(), spawn_key=spawn_key)))


def seeded_states(entropy: np.ndarray, spawn_key: tuple[int, ...] = ()) -> np.ndarray:
    """``(n, 4)`` states of ``PCG64(SeedSequence(entropy[e].tolist(), spawn_key=spawn_key))`` for
    every row of ``entropy`` ``(n, 4)`` ``uint32``: four words, exactly SeedSequence's pool, the
    only case written here (with a spawn key its words follow the entropy's and are mixed in after
    the pool's own; keys below 2^32, one word each)."""
    entropy = np.asarray(entropy)
    if entropy.ndim != 2 or entropy.shape[1] != POOL_WORDS or entropy.dtype != np.uint32:
        raise ValueError(f"entropy must be (n, {POOL_WORDS}) uint32, got {entropy.shape} {entropy.dtype}")
    if not all(0 <= int(key) < 2**32 for key in spawn_key):
        raise ValueError(f"spawn keys must be in [0, 2^32), got {spawn_key}")
    words = np.empty((len(entropy), POOL_WORDS + len(spawn_key)), dtype=np.uint32)
    words[:, :POOL_WORDS] = entropy
    words[:, POOL_WORDS:] = np.asarray(spawn_key, dtype=np.uint32)
    return _seeded_states(words)


@numba.njit(cache=True)
def _seeded_states(entropy: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n = entropy.shape[0]
    out = np.zeros((n, 4), dtype=np.uint64)
    pool = np.empty(POOL_WORDS, dtype=np.uint64)
    words = np.empty(2 * POOL_WORDS, dtype=np.uint64)
    for e in range(n):
        hash_const = _INIT_A
        for i in range(POOL_WORDS):  # mix_entropy
            pool[i], hash_const = _hashmix(np.uint64(entropy[e, i]), hash_const)
        for i_src in range(POOL_WORDS):
            for i_dst in range(POOL_WORDS):
                if i_src != i_dst:
                    hashed, hash_const = _hashmix(pool[i_src], hash_const)
                    pool[i_dst] = _mix(pool[i_dst], hashed)
        for i_src in range(POOL_WORDS, entropy.shape[1]):  # the words past the pool (a spawn key)
            for i_dst in range(POOL_WORDS):
                hashed, hash_const = _hashmix(np.uint64(entropy[e, i_src]), hash_const)
                pool[i_dst] = _mix(pool[i_dst], hashed)
        hash_const = _INIT_B
        for i in range(2 * POOL_WORDS):  # generate_state(4, uint64): eight uint32, little-endian pairs
            value = (pool[i % POOL_WORDS] ^ hash_const) & _M32
            hash_const = (hash_const * _MULT_B) & _M32
            value = (value * hash_const) & _M32
            words[i] = value ^ (value >> _U16)
        seed_hi, seed_lo = words[0] | (words[1] << _U32), words[2] | (words[3] << _U32)
        seq_hi, seq_lo = words[4] | (words[5] << _U32), words[6] | (words[7] << _U32)
        # pcg_setseq_128_srandom_r: inc = seq << 1 | 1; step from 0; add the seed; step
        out[e, 2] = (seq_hi << _U1) | (seq_lo >> _U63)
        out[e, 3] = (seq_lo << _U1) | _U1
        next_uint64(out, e)
        lo = out[e, 1] + seed_lo
        carry = _U1 if lo < seed_lo else _U0
        out[e, 0], out[e, 1] = out[e, 0] + seed_hi + carry, lo
        next_uint64(out, e)
    return out


@numba.njit(cache=True)
def fill_uniform(state: np.ndarray, low: float, high: float, out: np.ndarray) -> None:  # pragma: no cover
    """``out[e] =`` what ``generator.uniform(low, high, out.shape[1])`` draws from stream ``e``."""
    span = high - low
    for e in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[e, j] = low + span * next_double(state, e)
