"""``scftc list``: the registered controllers, classes and sensor faults."""

from __future__ import annotations

from rich.table import Table

from scftc_cli.baselines.base import registry
from scftc_cli.render import print_table
from scftc_cli.spec import SPEC


def list_command() -> None:
    """List registered controllers, fault classes and sensor faults."""
    table = Table(title="controllers")
    table.add_column("name")
    table.add_column("privileged")
    table.add_column("what it is")
    for info in registry().values():
        table.add_row(info.name, "yes (oracle)" if info.privileged else "no", info.summary)
    print_table(table)
    print("fault classes:", ", ".join(SPEC.fault_classes))
    print("sensor faults:", ", ".join(SPEC.sensor_faults))
