"""``check_controller``: the one checker every registered controller (and submission) passes.

Like gymnasium's ``check_env``: shapes, finite and bounded commands, and determinism — the same
observations after a fresh ``reset`` give bit-identical commands. It flies the benchmark's own
closed loop (``sim/rollout.py``) on a short prefix of a few train episodes.
"""

from __future__ import annotations

import numpy as np

from scftc_cli.protocol import Context, Controller
from scftc_cli.sim.rollout import rollout
from scftc_cli.sim.testbed import testbed
from scftc_cli.spec import DEFAULT_BENCHMARK


class _Recorder(Controller):
    """Passes everything through to ``inner`` and keeps a copy of every command it returned."""

    def __init__(self, inner: Controller) -> None:
        self.inner = inner
        self.commands: list[np.ndarray] = []
        # an instance attribute shadows the class default: the rollout hands the true fault only
        # to a privileged inner controller
        self.privileged = inner.privileged  # type: ignore[misc]

    def reset(self, n: int, context: Context) -> None:
        self.inner.reset(n, context)

    def act(self, obs: np.ndarray) -> np.ndarray:
        command = self.inner.act(obs)
        if isinstance(command, np.ndarray) and np.any(np.abs(command) > 1.0):
            raise AssertionError(f"{type(self.inner).__name__} returned commands outside [-1, 1]")
        self.commands.append(np.array(command, copy=True))
        return command


def fly_prefix(controller: Controller, benchmark: str, fault_class: str, steps: int) -> np.ndarray:
    """The commands ``(n, steps, action_dim)`` ``controller`` gives over the first ``steps`` steps
    of 6 pinned train episodes of ``fault_class`` (3 faults x 2 initial conditions)."""
    episodes = testbed(benchmark).draw("train", fault_class, n_faults=3, n_seeds=2)
    recorder = _Recorder(controller)
    rollout(recorder, episodes, steps=steps)
    return np.stack(recorder.commands, axis=1)


def check_controller(
    controller: Controller,
    steps: int = 40,
    benchmark: str = DEFAULT_BENCHMARK,
    classes: tuple[str, ...] = ("gain_bias", "loss"),
) -> None:
    """Raise ``AssertionError`` (or ``ControllerError``) if ``controller`` breaks the protocol on
    ``benchmark``: wrong shape or dtype, non-finite or out-of-range commands, or commands that
    differ between two flights of the same episodes."""
    for fault_class in classes:
        first = fly_prefix(controller, benchmark, fault_class, steps)
        again = fly_prefix(controller, benchmark, fault_class, steps)
        if not np.array_equal(first, again):
            raise AssertionError(f"{type(controller).__name__} is not deterministic after reset()")
