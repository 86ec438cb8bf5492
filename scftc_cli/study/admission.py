"""The admission rule of a version's ranked classes (``spec.AdmissionRule``), measured.

A fault class ranks only if the privileged oracle settles at least ``oracle_at_least`` of its
cell (the class can be flown) and the fault-unaware, train-tuned controller at most
``unaware_at_most`` (it cannot be flown without fault tolerance). The rule is decided on the train
split, on whole pinned cells; the held-out split only reports it, and only once the battery is
frozen (the unaware controller is deployable: flying it held out is a look at held-out results).
``nominal`` is never ranked (no fault to tolerate); it is listed for its false alarms.
"""

from __future__ import annotations

from dataclasses import dataclass

from scftc_cli.distributed.refs import BuiltinRef
from scftc_cli.errors import UsageError
from scftc_cli.evaluate import Cell, ControllerFactory, evaluate_cells
from scftc_cli.protocol import NO_PROGRESS, Controller, Progress
from scftc_cli.records import GateStat
from scftc_cli.registry import controller_spec
from scftc_cli.spec import AdmissionRule, BenchmarkSpec
from scftc_cli.versions import ControllerSpec, get_spec


@dataclass(frozen=True)
class AdmissionRow:
    """One class under the rule on one split.

    Attributes:
        fault_class: the class.
        oracle, unaware: each controller's settled gate on the whole cell (``k``, rate, Wilson and
            by-fault intervals).
        admitted: the rates pass the rule.
        ranked: the spec ranks the class (``BenchmarkSpec.ranked_classes``).
    """

    fault_class: str
    oracle: GateStat
    unaware: GateStat
    admitted: bool
    ranked: bool

    @property
    def consistent(self) -> bool:
        """The spec ranks the class exactly when the rule admits it (``nominal`` aside: never)."""
        return self.ranked == (self.admitted and self.fault_class != "nominal")


def rule_of(spec: BenchmarkSpec) -> AdmissionRule:
    """The version's rule; a clear error for a version that predates it."""
    if spec.admission is None:
        raise UsageError(f"{spec.version} has no admission rule (it predates them)")
    return spec.admission


def built_in(entry: ControllerSpec) -> ControllerFactory:
    """A factory of fresh instances of built-in ``entry``, one per cell."""

    def make(_cell: Cell) -> Controller:
        return entry.make()

    return make


def admission_table(
    benchmark: str,
    split: str | None = None,
    *,
    n_faults: int | None = None,
    n_seeds: int | None = None,
    progress: Progress = NO_PROGRESS,
) -> list[AdmissionRow]:
    """Fly the rule's oracle and unaware controller on every actuator class of ``split`` (the
    rule's own by default) and say which classes it admits, in the spec's class order."""
    spec = get_spec(benchmark)
    rule = rule_of(spec)
    split = rule.split if split is None else split
    spec.check_cell(split, spec.fault_classes[0])
    cells = [Cell(split, name) for name in spec.fault_classes]
    stats: dict[str, list[GateStat]] = {}
    for name in (rule.oracle, rule.unaware):
        entry = controller_spec(name, spec.version)
        runs = evaluate_cells(
            built_in(entry),
            spec,
            cells,
            n_faults=n_faults,
            n_seeds=n_seeds,
            progress=progress,
            label=name,
            ref=BuiltinRef(name, spec.version),
        )
        stats[name] = [run.result.settled for run in runs]
    return [
        AdmissionRow(
            fault_class=cell.fault_class,
            oracle=oracle,
            unaware=unaware,
            admitted=rule.admits(oracle.rate, unaware.rate),
            ranked=cell.fault_class in spec.ranked_classes,
        )
        for cell, oracle, unaware in zip(cells, stats[rule.oracle], stats[rule.unaware], strict=True)
    ]


def markdown(rows: list[AdmissionRow], rule: AdmissionRule, split: str) -> str:
    """The table as markdown: each class's two settled rates with their by-fault intervals, the
    rule's verdict and whether the spec ranks it."""

    def cell(stat: GateStat) -> str:
        band = stat.interval_by_fault
        interval = f" [{100 * band[0]:.1f}, {100 * band[1]:.1f}]" if band else ""
        return f"{100 * stat.rate:.1f}{interval}"

    lines = [
        f"| class ({split}) | {rule.oracle} settled % (>= {100 * rule.oracle_at_least:.0f}) "
        f"| {rule.unaware} settled % (<= {100 * rule.unaware_at_most:.0f}) | rule | ranked |",
        "|---|---|---|---|---|",
    ]
    for row in rows:
        verdict = "admits" if row.admitted else "refuses"
        if row.fault_class == "nominal":
            verdict = "never ranked (no fault)"
        lines.append(
            f"| {row.fault_class} | {cell(row.oracle)} | {cell(row.unaware)} | {verdict} | "
            f"{'yes' if row.ranked else 'no'} |"
        )
    return "\n".join(lines) + "\n"
