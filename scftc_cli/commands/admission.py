"""``scftc admission``: which fault classes of a version may rank, measured."""

from __future__ import annotations

from typing import Annotated

import typer

from scftc_cli.commands.common import DEFAULT, BenchmarkOption, exits_cleanly, progress_bar


@exits_cleanly
def admission_command(
    split: Annotated[
        str | None,
        typer.Option(help="Split to fly [default: the rule's own, train]. The held-out split only reports."),
    ] = None,
    n_faults: Annotated[
        int | None, typer.Option(help="Faults per cell [default: the spec's].", min=1)
    ] = None,
    n_seeds: Annotated[int | None, typer.Option(help="Seeds per fault [default: the spec's].", min=1)] = None,
    benchmark: BenchmarkOption = DEFAULT,
) -> None:
    """Fly the admission rule's oracle and fault-unaware controller on every actuator class.

    A class may rank only if the privileged oracle settles at least the rule's share of it and the
    fault-unaware, train-tuned controller at most its share (a version's definition, section "The
    admission rule"; versions without a rule are refused). Prints a markdown table; exits 1 if the
    spec ranks a class the rule refuses, or leaves out one it admits, on the rule's own split.
    """
    from scftc_cli.errors import ScftcError
    from scftc_cli.evaluate import Cell, planned_steps
    from scftc_cli.study.admission import admission_table, markdown, rule_of
    from scftc_cli.versions import get_spec

    spec = get_spec(benchmark)
    rule = rule_of(spec)
    split = rule.split if split is None else split
    cells = [Cell(split, name) for name in spec.fault_classes]
    steps = 2 * planned_steps(spec, cells)  # the oracle's flights, then the unaware controller's
    with progress_bar(f"admission on {split}", steps, benchmark=spec.version) as progress:
        rows = admission_table(spec.version, split, n_faults=n_faults, n_seeds=n_seeds, progress=progress)
    typer.echo(markdown(rows, rule, split), nl=False)
    wrong = [row.fault_class for row in rows if not row.consistent]
    if split == rule.split and wrong:
        raise ScftcError(f"the spec's ranked classes disagree with the rule on {', '.join(wrong)}")
