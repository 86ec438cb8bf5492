"""Gymnasium environments of the benchmark, registered by id: each version declares its own
(``Version.envs``, e.g. ``scftc/AttitudeFTC-v1``: the suffix is the benchmark version).

``import scftc_cli`` is enough for ``gymnasium.make(id)`` and ``gymnasium.make_vec(...,
vectorization_mode="vector_entry_point")``, whichever of the two is imported first: the package
root installs a hook that calls ``register`` once gymnasium is imported, and never imports
gymnasium itself, so ``scftc --help`` stays fast. After ``import gymnasium`` alone,
``gymnasium.make("scftc_cli:<id>")`` imports the package and so registers them (gymnasium's own
``module:id`` form). The entry points are strings: the environment modules load on ``make``.
Needs ``gymnasium`` (``pip install scftc[rl]``). Observation, action, reward and episodes:
``docs/rl.md``.
"""

from __future__ import annotations

import re

from scftc_cli.versions import GymEnv, all_versions


def environments() -> list[GymEnv]:
    """Every registered version's environments."""
    return [env for version in all_versions() for env in version.envs]


def out_of_date_warning(env_id: str) -> str:
    """The regex of gymnasium's warning on ``make(env_id)`` when an id with a higher version suffix
    exists: it reads another benchmark version's environment as the newer edition of this one, but
    versions are separate tracks, so the warning would mislead."""
    return rf".*The environment {re.escape(env_id)} is out of date"


def register() -> None:
    """Register every version's environments with gymnasium (idempotent), and silence the
    misleading "out of date" warning about each of them."""
    import warnings

    import gymnasium

    for env in environments():
        warnings.filterwarnings("ignore", message=out_of_date_warning(env.id), category=DeprecationWarning)
        if env.id not in gymnasium.registry:
            gymnasium.register(
                id=env.id, entry_point=env.entry_point, vector_entry_point=env.vector_entry_point
            )
