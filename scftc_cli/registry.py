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
V2 = ("scftc-v2",)


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
        family: ``reference`` (fault-unaware baselines), ``classical`` (adaptive and estimation
            laws), ``learned`` (trained networks) or ``oracle`` (privileged upper bounds): how
            tables and figures group the battery.
    """

    name: str
    entry_point: str
    summary: str
    privileged: bool = False
    benchmarks: tuple[str, ...] = V1
    artifacts: tuple[str, ...] = ()
    family: str = "classical"

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
    ControllerSpec(
        "pd", "scftc_cli.baselines.analytic:PD", "fault-unaware inertia-scaled PD on MRPs", family="reference"
    ),
    ControllerSpec(
        "pid",
        "scftc_cli.baselines.pid:PID",
        "PD + integral on sigma with conditional-integration and clamping anti-windup",
        artifacts=_params("pid"),
        family="reference",
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
        artifacts=("weights/e2e_ppo.npz",),
        family="learned",
    ),
    ControllerSpec(
        "rma_student",
        "scftc_cli.baselines.rma:RMAStudent",
        "RMA: latched GRU estimate of theta = g/f feeding the analytic law",
        artifacts=("weights/rma_student.npz",),
        family="learned",
    ),
    ControllerSpec(
        "rma_dob",
        "scftc_cli.baselines.rma:RMADob",
        "RMA gain student (trained with biases) + disturbance observer",
        artifacts=("weights/rma_dob.npz",),
        family="learned",
    ),
    ControllerSpec(
        "rls_dob",
        "scftc_cli.baselines.rls:RLSDob",
        "per-axis RLS on the measured torque + disturbance observer, latched (no learning)",
        artifacts=_params("rls_dob"),
    ),
    ControllerSpec(
        "rls_plan",
        "scftc_cli.baselines.plan:RLSPlan",
        "rls_dob + dead-axis plan (gyroscopic rate nulling, p-q-p slews) + low-margin bias plan",
        artifacts=_params("rls_plan"),
    ),
    ControllerSpec(
        "teacher",
        "scftc_cli.baselines.analytic:Teacher",
        "privileged: the analytic law fed the true theta = g/f",
        privileged=True,
        family="oracle",
    ),
    ControllerSpec(
        "bias_oracle",
        "scftc_cli.baselines.analytic:BiasOracle",
        "privileged: the analytic law fed the true theta and beta = b/f",
        privileged=True,
        family="oracle",
    ),
    # scftc-v2: the same methods, ported to four reaction wheels and noisy redundant sensors.
    ControllerSpec(
        "pd",
        "scftc_cli.baselines.v2.analytic:PD",
        "fault-unaware PD + gyroscopic and friction feed-forwards, median of the star-tracker heads",
        benchmarks=V2,
        family="reference",
    ),
    ControllerSpec(
        "pid",
        "scftc_cli.baselines.v2.pid:PID",
        "PD + integral on the fused attitude with anti-windup, nominal allocation (fault-unaware)",
        benchmarks=V2,
        artifacts=("params/v2/pid.yaml",),
        family="reference",
    ),
    ControllerSpec(
        "classical_adaptive",
        "scftc_cli.baselines.v2.adaptive:ClassicalAdaptive",
        "per-wheel sign vote + gradient law for gain, offset and friction on the tachometer torque",
        benchmarks=V2,
        artifacts=("params/v2/classical_adaptive.yaml",),
    ),
    ControllerSpec(
        "icl_adaptive",
        "scftc_cli.baselines.v2.icl:ICLAdaptive",
        "per-wheel integral concurrent learning of (g, b, friction); stacks purged on a change",
        benchmarks=V2,
        artifacts=("params/v2/icl_adaptive.yaml",),
    ),
    ControllerSpec(
        "nussbaum",
        "scftc_cli.baselines.v2.nussbaum:Nussbaum",
        "per-wheel Nussbaum gain on the wheel-space error + adaptive offset term (no identification)",
        benchmarks=V2,
        artifacts=("params/v2/nussbaum.yaml",),
    ),
    ControllerSpec(
        "rls_dob",
        "scftc_cli.baselines.v2.rls:RLSDob",
        "per-wheel RLS on the tachometer torque + disturbance observer, latched, re-opened on a change",
        benchmarks=V2,
        artifacts=("params/v2/rls_dob.yaml",),
    ),
    ControllerSpec(
        "e2e_ppo",
        "scftc_cli.baselines.v2.ppo:E2EPPO",
        "end-to-end recurrent policy (LSTM) on the 19 raw readings, trained from scratch with PPO",
        benchmarks=V2,
        artifacts=("weights/v2/e2e_ppo.npz",),
        family="learned",
    ),
    ControllerSpec(
        "rma_student",
        "scftc_cli.baselines.v2.rma:RMAStudent",
        "RMA: per-wheel GRU estimate of g from the tachometer torque, latched, re-opened on a change",
        benchmarks=V2,
        artifacts=("weights/v2/rma_student.npz",),
        family="learned",
    ),
    ControllerSpec(
        "rma_dob",
        "scftc_cli.baselines.v2.rma:RMADob",
        "RMA bias-invariant gain student + per-wheel offset and friction observer",
        benchmarks=V2,
        artifacts=("weights/v2/rma_dob.npz",),
        family="learned",
    ),
    ControllerSpec(
        "fdir",
        "scftc_cli.baselines.v2.fdir:FDIR",
        "flight-style FDIR: MEKF with gyro-bias and head tests + per-wheel CUSUM and re-identification",
        benchmarks=V2,
        artifacts=("params/v2/fdir.yaml",),
        family="classical",
    ),
    ControllerSpec(
        "teacher",
        "scftc_cli.baselines.v2.analytic:Teacher",
        "privileged: the analytic law allocated through the true wheel effectiveness g(t)",
        privileged=True,
        benchmarks=V2,
        family="oracle",
    ),
    ControllerSpec(
        "bias_oracle",
        "scftc_cli.baselines.v2.analytic:BiasOracle",
        "privileged: the teacher plus the true wheel offsets and friction",
        privileged=True,
        benchmarks=V2,
        family="oracle",
    ),
)


def registry(benchmark: str = DEFAULT_BENCHMARK) -> dict[str, ControllerSpec]:
    """The built-ins that fly ``benchmark``, deployable ones first, then the oracles, in battery
    order. A name is unique within a version; the same name on two versions (``pd``) is the same
    method, ported."""
    chosen = [c for c in BUILTINS if benchmark in c.benchmarks]
    ordered = sorted(chosen, key=lambda c: c.privileged)  # stable: battery order within each group
    return {c.name: c for c in ordered}


def builtin_names() -> set[str]:
    """Every built-in's name, on any benchmark version (reserved on every board)."""
    return {c.name for c in BUILTINS}


def controller_spec(name: str, benchmark: str = DEFAULT_BENCHMARK) -> ControllerSpec:
    """The entry of ``name`` for ``benchmark``.

    Raises:
        UnknownNameError: no built-in has that name (the closest names are suggested).
        UsageError: it exists, but flies other benchmark versions only (they are named).
    """
    if benchmark not in SPECS:
        raise UnknownNameError("benchmark version", benchmark, SPECS)
    here = registry(benchmark)
    if name in here:
        return here[name]
    versions = sorted({v for c in BUILTINS if c.name == name for v in c.benchmarks})
    if not versions:
        raise UnknownNameError("controller", name, here)
    raise UsageError(
        f"controller `{name}` flies {', '.join(versions)} only, not {benchmark}; "
        f"pick one of its versions with --benchmark, or a controller of {benchmark} (`scftc list`)"
    )


def make_controller(name: str, benchmark: str = DEFAULT_BENCHMARK) -> Controller:
    """A fresh instance of the built-in controller ``name``."""
    return controller_spec(name, benchmark).make()
