"""Gymnasium environments of the benchmark. Importing this package registers
``scftc/AttitudeFTC-v1`` (``gymnasium.make`` and, vectorized over the batch simulator,
``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``). Needs ``gymnasium``
(``pip install scftc[rl]``)."""

from __future__ import annotations

import gymnasium

from scftc_cli.envs.attitude import ENV_ID, AttitudeFTCEnv, AttitudeFTCVectorEnv

__all__ = ["ENV_ID", "AttitudeFTCEnv", "AttitudeFTCVectorEnv"]

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="scftc_cli.envs.attitude:AttitudeFTCEnv",
        vector_entry_point="scftc_cli.envs.attitude:AttitudeFTCVectorEnv",
    )
