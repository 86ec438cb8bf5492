"""Imports every trainer module so that each registers itself (one line per module)."""
