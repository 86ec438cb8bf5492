"""Episodes and their seeds: what every benchmark version's draws have in common.

A cell's episodes come from ``numpy.random.SeedSequence``s keyed by the benchmark version, the
split, the class and the episode's index (``seed_sequence``); a ``salt`` keys a sealed draw
instead. Each version subclasses ``Episodes`` with its own fault and initial-state arrays; the
generic ``subset`` and ``concat`` work on any subclass whose batch arrays lead with ``n``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass
from typing import Any, Self

import numpy as np


def seed_sequence(
    version: str, *key: str, index: tuple[int, ...], salt: bytes = b""
) -> np.random.SeedSequence:
    """A ``SeedSequence`` keyed by ``version``, the names in ``key`` and ``index``.

    The entropy is the first 16 bytes (little-endian) of ``sha256("|".join((version, *key)) + salt)``
    and ``index`` is the spawn key, so every stream is independent of every other and of how many
    episodes a cell holds.
    """
    digest = hashlib.sha256("|".join((version, *key)).encode() + salt).digest()
    return np.random.SeedSequence(int.from_bytes(digest[:16], "little"), spawn_key=index)


def generator(version: str, *key: str, index: tuple[int, ...], salt: bytes = b"") -> np.random.Generator:
    """``np.random.default_rng`` of ``seed_sequence(...)``."""
    return np.random.default_rng(seed_sequence(version, *key, index=index, salt=salt))


def unit_norm(v: np.ndarray) -> float:
    """``|v|`` of a 3-vector summed left to right: the same bits on every CPU (``np.linalg.norm``
    goes through BLAS, whose kernels differ in the last bit between CPUs, and a draw must not)."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def take_rows(value: Any, idx: np.ndarray | slice, n: int) -> Any:
    """``value`` with every array that leads with ``n`` (a batch array) cut to the rows ``idx``,
    through nested dataclasses and dicts; anything else as it is."""
    if isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == n:
        return value[idx]
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.replace(
            value, **{f.name: take_rows(getattr(value, f.name), idx, n) for f in dataclasses.fields(value)}
        )
    if isinstance(value, dict):
        return {key: take_rows(item, idx, n) for key, item in value.items()}
    return value


def _join(values: list[Any]) -> Any:
    first = values[0]
    if isinstance(first, np.ndarray):
        return np.concatenate(values)
    if dataclasses.is_dataclass(first) and not isinstance(first, type):
        return dataclasses.replace(
            first, **{f.name: _join([getattr(v, f.name) for v in values]) for f in dataclasses.fields(first)}
        )
    return first


@dataclass(frozen=True)
class Episodes:
    """A batch of episodes of one benchmark version (subclassed per version).

    Attributes:
        benchmark: the version that defines them.
        split, fault_class, sensor: the cell they belong to (``sensor`` ``None``: healthy sensors).
        fault_index, seed_index: ``(n,)`` which fault and which initial-condition seed of the cell.
    """

    benchmark: str
    split: str
    fault_class: str
    sensor: str | None
    fault_index: np.ndarray
    seed_index: np.ndarray

    @property
    def n(self) -> int:
        return len(self.fault_index)

    def subset(self, idx: np.ndarray | slice) -> Self:
        """The episodes at ``idx`` (every batch array sliced alike)."""
        return take_rows(self, idx, self.n)

    @classmethod
    def concat(cls, parts: list[Self]) -> Self:
        """One batch of several batches' episodes (their cell labels joined with ``+``)."""
        joined = _join(parts)
        label = "+".join(dict.fromkeys(p.fault_class for p in parts))
        return dataclasses.replace(joined, fault_class=label)

    def describe(self, i: int) -> dict[str, Any]:
        """Episode ``i``'s fault and initial state as plain JSON values, nested names joined with
        dots (``fault.gain``): what a per-episode log records."""
        out: dict[str, Any] = {}

        def walk(prefix: str, value: Any) -> None:
            if dataclasses.is_dataclass(value) and not isinstance(value, type):
                for f in dataclasses.fields(value):
                    walk(f"{prefix}{f.name}.", getattr(value, f.name))
            elif isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == self.n:
                item = value[i]
                out[prefix.rstrip(".")] = item.tolist() if isinstance(item, np.ndarray) else item.item()
            elif value is None and prefix:
                out[prefix.rstrip(".")] = None

        for f in dataclasses.fields(self):
            if f.name not in ("benchmark", "split", "fault_class", "sensor"):
                walk(f"{f.name}.", getattr(self, f.name))
        return out

    def readonly(self) -> Self:
        """Mark every batch array read-only (cached draws are shared between callers)."""

        def freeze(value: Any) -> None:
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
            elif dataclasses.is_dataclass(value) and not isinstance(value, type):
                for f in dataclasses.fields(value):
                    freeze(getattr(value, f.name))

        freeze(self)
        return self
