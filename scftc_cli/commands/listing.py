"""``scftc list``: the registered controllers, classes and sensor faults of a benchmark version."""

from __future__ import annotations

from scftc_cli.commands.common import DEFAULT, BenchmarkOption, exits_cleanly


@exits_cleanly
def list_command(benchmark: BenchmarkOption = DEFAULT) -> None:
    """List the controllers, fault classes and sensor faults of a benchmark version."""
    from rich.table import Table

    from scftc_cli.registry import registry
    from scftc_cli.render import print_table, print_text
    from scftc_cli.spec import get_spec

    spec = get_spec(benchmark)
    table = Table(title=f"controllers of {spec.version} ({spec.title})")
    table.add_column("name")
    table.add_column("privileged")
    table.add_column("what it is")
    for entry in registry(spec.version).values():
        table.add_row(entry.name, "yes (oracle)" if entry.privileged else "no", entry.summary)
    print_table(table)
    print_text(f"fault classes: {', '.join(spec.fault_classes)}")
    print_text(f"sensor faults (on {spec.sensor_base_class} faults): {', '.join(spec.sensor_faults)}")
