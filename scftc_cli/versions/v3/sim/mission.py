"""``scftc-v3``'s mission layer: the pointing windows, the error to the current target, and what the
controller is told of the mission (the current target and the time left in its window).

An episode of ``steps`` steps is ``windows`` windows of ``window_steps``; window ``w`` covers steps
``w window_steps .. (w + 1) window_steps - 1`` and points at ``targets[:, w]`` (inertial MRP). The
plants below are the physics of ``dynamics.py`` / ``fast.py`` unchanged; they only add the episode
mapping (``of``) and return, after each step, ``|sigma_BR|^2`` of the error ``sigma_BR`` between
the body and the window's target, which the gates score.
"""

from __future__ import annotations

from typing import Any, Self

import numpy as np

from scftc_cli.sim.mrp import compose, norm2
from scftc_cli.sim.mrp_fused import relative
from scftc_cli.versions.v3.sim.dynamics import V2_WHEELS, V3Constants, V3Plant
from scftc_cli.versions.v3.sim.environment import EnvironmentConstants
from scftc_cli.versions.v3.sim.fast import FastV3Plant
from scftc_cli.versions.v3.spec import V3, AgilePlant


def constants_of(plant: AgilePlant) -> V3Constants:
    """The physics' constants from the spec's plant (v2's wheels, the spec's environment)."""
    return V3Constants(
        wheels=V2_WHEELS,
        environment=EnvironmentConstants(
            mu_m3_s2=plant.mu_m3_s2,
            g10_t=plant.igrf_g10_t,
            g11_t=plant.igrf_g11_t,
            h11_t=plant.igrf_h11_t,
            facet_specular=plant.facet_specular,
            facet_diffuse=plant.facet_diffuse,
            rod_dipole_max_am2=plant.rod_dipole_max_am2,
        ),
        episode_steps=plant.steps,
    )


assert isinstance(V3.plant, AgilePlant)
PLANT: AgilePlant = V3.plant
CONSTANTS = constants_of(PLANT)


def window_of(k: int, plant: AgilePlant = PLANT) -> int:
    """The window step ``k`` belongs to."""
    return min(k // plant.window_steps, plant.windows - 1)


def window_ends(plant: AgilePlant = PLANT) -> tuple[int, ...]:
    """The steps after which each window ends (the last is ``steps``)."""
    return tuple((w + 1) * plant.window_steps for w in range(plant.windows))


def time_left_s(k: int, plant: AgilePlant = PLANT) -> float:
    """Seconds from the start of step ``k`` to the end of its window."""
    return ((window_of(k, plant) + 1) * plant.window_steps - k) * plant.dt_s


def target_error(sigma: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``sigma_BR`` ``(n, 3)``: the body attitude ``sigma`` (``B`` from ``N``) relative to the target
    ``target`` (``R`` from ``N``), ``C(BR) = C(BN) C(RN)'``, on the short branch."""
    return compose(-target, sigma)


class MissionMixin:
    """Maps episodes onto a v3 plant and scores each step against the window's target."""

    targets: np.ndarray

    @classmethod
    def of(cls, episodes: Any, constants: V3Constants | None = None, **options: Any) -> Self:
        plant = super().of(episodes, CONSTANTS if constants is None else constants, **options)  # type: ignore[misc]
        plant.targets = np.asarray(episodes.targets)
        return plant

    def step(self, k: int, command: np.ndarray) -> np.ndarray:
        """Advance step ``k``; return ``|sigma_BR|^2`` ``(n,)`` of the error to step ``k``'s target."""
        super().step(k, command)  # type: ignore[misc]
        error = self.error_to(self.sigma, self.targets[:, window_of(k)])  # type: ignore[attr-defined]
        return norm2(error)

    @staticmethod
    def error_to(sigma: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``target_error`` (numpy here: the reference plant's)."""
        return target_error(sigma, target)


class MissionFastPlant(MissionMixin, FastV3Plant):
    """The default backend: the fused kernel (``fast.py``), the error compiled too (the same bits)."""

    @staticmethod
    def error_to(sigma: np.ndarray, target: np.ndarray) -> np.ndarray:
        """``target_error``, compiled (``scftc_cli.sim.mrp_fused.relative``)."""
        return relative(sigma, target)


class MissionReferencePlant(MissionMixin, V3Plant):
    """The numpy reference (``dynamics.py``)."""
