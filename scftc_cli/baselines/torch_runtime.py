"""How the learned controllers run torch: inference only, one intra-op thread.

They evaluate a small network on a batch every 0.5 s step; on a 2-core machine torch's default
two threads only contend, with each other and with any other load: a 500-episode ``rma_dob`` cell
took ~1 s on one thread and 2.5-58 s on two (measured). Results are identical either way.
"""

from __future__ import annotations

import torch


def inference_mode_threads() -> None:
    """Pin torch to one intra-op thread (called when a learned controller loads its weights)."""
    if torch.get_num_threads() != 1:
        torch.set_num_threads(1)
