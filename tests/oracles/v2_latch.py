"""``WheelLatch.update`` (``scftc_cli/versions/v2/controllers/latch.py``) in numpy: the readable
form the compiled pass (``_latch_rows``) is tested against, bit for bit."""

from __future__ import annotations

import numpy as np

from scftc_cli.versions.v2.controllers.latch import WheelLatch


def update(self: WheelLatch, raw: np.ndarray, excitation: np.ndarray) -> np.ndarray:
    """``WheelLatch.update`` in numpy: fold in the live estimate; returns the estimate to use."""
    cfg = self.config
    slot = self.count % (cfg.window + 1)
    np.put_along_axis(self.history, slot[None], raw[None], axis=0)
    self.count += 1
    full = self.count > cfg.window
    recent = np.where(full, self.history, raw)  # before a full window, only what is there
    spread = recent.max(axis=0) - recent.min(axis=0)
    still = full & (spread <= cfg.tolerance * np.maximum(np.abs(raw), 0.1))
    due = still | (self.count > cfg.max_steps)
    now = ~self.latched & (self.count > cfg.min_steps) & due & (excitation >= cfg.min_excitation)
    self.frozen = np.where(now, raw, self.frozen)
    self.latched |= now
    return np.where(self.latched, self.frozen, raw)
