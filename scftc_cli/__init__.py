"""SCFTC: the honest benchmark for spacecraft attitude fault-tolerant control."""

from __future__ import annotations

__version__ = "0.1.0"
BENCHMARK_VERSION = "scftc-v1"
