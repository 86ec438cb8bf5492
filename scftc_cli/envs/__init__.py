"""Gymnasium environments of the benchmark, registered by id.

``import scftc_cli`` is enough for ``gymnasium.make("scftc/AttitudeFTC-v1")`` (and
``"scftc/AttitudeFTC-v2"``: the suffix is the benchmark version) and
``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``: the package registers these
ids as soon as gymnasium is imported (before or after it), and never imports gymnasium itself, so
``scftc --help`` stays fast. The entry points are strings: the environment modules load on ``make``.
Needs ``gymnasium`` (``pip install scftc[rl]``). Observation, action, reward and episodes:
``docs/rl.md``.
"""

from __future__ import annotations

ENVS: dict[str, tuple[str, str]] = {
    "scftc/AttitudeFTC-v1": (
        "scftc_cli.envs.attitude:AttitudeFTCEnv",
        "scftc_cli.envs.attitude:AttitudeFTCVectorEnv",
    ),
    "scftc/AttitudeFTC-v2": (
        "scftc_cli.envs.wheels:AttitudeFTCv2Env",
        "scftc_cli.envs.wheels:AttitudeFTCv2VectorEnv",
    ),
}


V1_OUT_OF_DATE = r".*The environment scftc/AttitudeFTC-v1 is out of date"
"""Gymnasium's warning on ``make("scftc/AttitudeFTC-v1")`` once ``-v2`` exists: it reads ``-v2`` as
v1's successor, but the two are separate benchmark tracks, so the warning would mislead."""


def register() -> None:
    """Register every environment of ``ENVS`` with gymnasium (idempotent), and silence the one
    misleading "out of date" warning about ``scftc/AttitudeFTC-v1``."""
    import warnings

    import gymnasium

    warnings.filterwarnings("ignore", message=V1_OUT_OF_DATE, category=DeprecationWarning)

    for env_id, (entry_point, vector_entry_point) in ENVS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point, vector_entry_point=vector_entry_point)
