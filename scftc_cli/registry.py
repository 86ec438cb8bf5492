"""The registry of built-in controllers: data, imported on first use.

Like Gymnasium's registry, an entry names its class as a ``"module:Class"`` string, so listing the
battery, or running ``pd``, never imports the learned controllers (or torch). The order of
``BUILTINS`` is the battery's table order: deployable controllers, then the privileged oracles.
An unknown name suggests the closest one; a name that exists for another benchmark version says
which versions it flies.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.protocol import Controller
from scftc_cli.spec import DEFAULT_BENCHMARK, SPECS

PACKAGE_DIR = Path(__file__).resolve().parent
V1 = ("scftc-v1",)


@dataclass(frozen=True)
class ControllerSpec:
    """One built-in controller.

    Attributes:
        name: the name on the command line and the board.
        entry_point: ``"module:Class"``; the class is built with no arguments.
        summary: one line for ``scftc list`` and the board.
        privileged: an oracle that is handed the true fault (an upper bound, never ranked).
        benchmarks: the benchmark versions it can fly.
        artifacts: package-relative files it loads (tuned parameters, weights), hashed into every
            result's provenance.
    """

    name: str
    entry_point: str
    summary: str
    privileged: bool = False
    benchmarks: tuple[str, ...] = V1
    artifacts: tuple[str, ...] = ()

    def load(self) -> type[Controller]:
        """Import the controller's class."""
        module, _, attr = self.entry_point.partition(":")
        return getattr(importlib.import_module(module), attr)

    def make(self) -> Controller:
        """A fresh instance."""
        return self.load()()

    def artifact_paths(self) -> list[Path]:
        return [PACKAGE_DIR / a for a in self.artifacts]


def _params(name: str) -> tuple[str, ...]:
    return (f"params/{name}.yaml",)


BUILTINS: tuple[ControllerSpec, ...] = (
    ControllerSpec("pd", "scftc_cli.baselines.analytic:PD", "fault-unaware inertia-scaled PD on MRPs"),
    ControllerSpec(
        "pid",
        "scftc_cli.baselines.pid:PID",
        "PD + integral on sigma with conditional-integration and clamping anti-windup",
        artifacts=_params("pid"),
    ),
    ControllerSpec(
        "classical_adaptive",
        "scftc_cli.baselines.adaptive:ClassicalAdaptive",
        "per-axis sign identification (vote) + adaptive gain magnitude and bias",
        artifacts=_params("classical_adaptive"),
    ),
    ControllerSpec(
        "icl_adaptive",
        "scftc_cli.baselines.icl:ICLAdaptive",
        "integral concurrent learning of (theta, beta) with a history stack (Parikh 2019)",
        artifacts=_params("icl_adaptive"),
    ),
    ControllerSpec(
        "nussbaum",
        "scftc_cli.baselines.nussbaum:Nussbaum",
        "per-axis Nussbaum gain for unknown direction + adaptive bias term (Nussbaum 1983)",
        artifacts=_params("nussbaum"),
    ),
    ControllerSpec(
        "e2e_ppo",
        "scftc_cli.baselines.ppo:E2EPPO",
        "end-to-end recurrent policy (LSTM) trained from scratch with PPO",
        artifacts=("weights/e2e_ppo.pt",),
    ),
    ControllerSpec(
        "rma_student",
        "scftc_cli.baselines.rma:RMAStudent",
        "RMA: latched GRU estimate of theta = g/f feeding the analytic law",
        artifacts=("weights/rma_student.pt",),
    ),
    ControllerSpec(
        "rma_dob",
        "scftc_cli.baselines.rma:RMADob",
        "RMA gain student (trained with biases) + disturbance observer",
        artifacts=("weights/rma_dob.pt",),
    ),
    ControllerSpec(
        "rls_dob",
        "scftc_cli.baselines.rls:RLSDob",
        "per-axis RLS on the measured torque + disturbance observer, latched (no learning)",
        artifacts=_params("rls_dob"),
    ),
    ControllerSpec(
        "teacher",
        "scftc_cli.baselines.analytic:Teacher",
        "privileged: the analytic law fed the true theta = g/f",
        privileged=True,
    ),
    ControllerSpec(
        "bias_oracle",
        "scftc_cli.baselines.analytic:BiasOracle",
        "privileged: the analytic law fed the true theta and beta = b/f",
        privileged=True,
    ),
)


def registry(benchmark: str | None = DEFAULT_BENCHMARK) -> dict[str, ControllerSpec]:
    """The built-ins that fly ``benchmark`` (every one with ``None``), deployable ones first, then
    the oracles, in battery order."""
    chosen = [c for c in BUILTINS if benchmark is None or benchmark in c.benchmarks]
    ordered = sorted(chosen, key=lambda c: c.privileged)  # stable: battery order within each group
    return {c.name: c for c in ordered}


def controller_spec(name: str, benchmark: str = DEFAULT_BENCHMARK) -> ControllerSpec:
    """The entry of ``name`` for ``benchmark``.

    Raises:
        UnknownNameError: no built-in has that name (the closest names are suggested).
        UsageError: it exists, but flies other benchmark versions only (they are named).
    """
    if benchmark not in SPECS:
        raise UnknownNameError("benchmark version", benchmark, SPECS)
    everything = registry(None)
    if name not in everything:
        raise UnknownNameError("controller", name, registry(benchmark))
    entry = everything[name]
    if benchmark not in entry.benchmarks:
        raise UsageError(
            f"controller `{name}` flies {', '.join(entry.benchmarks)} only, not {benchmark}; "
            f"pick one of its versions with --benchmark, or a controller of {benchmark} (`scftc list`)"
        )
    return entry


def make_controller(name: str, benchmark: str = DEFAULT_BENCHMARK) -> Controller:
    """A fresh instance of the built-in controller ``name``."""
    return controller_spec(name, benchmark).make()
