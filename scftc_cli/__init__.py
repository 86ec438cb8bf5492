"""SCFTC: the honest benchmark for spacecraft attitude fault-tolerant control."""

from __future__ import annotations

__version__ = "0.2.0"
