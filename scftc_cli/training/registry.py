"""Imports every trainer module so that each registers itself (one line per module)."""

from scftc_cli.training import tuning  # noqa: F401  (the classical battery)
