"""``scftc crosscheck``: show the default backend equal to Basilisk on the same episodes."""

from __future__ import annotations

import json
from typing import Annotated

import typer

from scftc_cli.commands.common import DEFAULT, BenchmarkOption, exits_cleanly, progress_bar


@exits_cleanly
def crosscheck_command(
    episodes: Annotated[
        int, typer.Option(help="Episodes in all, mixed classes and sensor faults.", min=1)
    ] = 20,
    controller: Annotated[
        list[str] | None,
        typer.Option(
            help="Controller in the loop, repeatable [default: pd and an adaptive law].", show_default=False
        ),
    ] = None,
    benchmark: BenchmarkOption = DEFAULT,
) -> None:
    """Fly the same episodes through the default backend and Basilisk and compare every state.

    Prints one JSON document; exits 1 if any state differs by more than 1e-9 (sigma, omega in
    rad/s, and any state of the version's own, such as wheel speeds as a fraction of their speed limit)
    or any gate
    outcome differs.
    """
    from scftc_cli.errors import ScftcError
    from scftc_cli.study.crosscheck import TOLERANCE, crosscheck, default_controllers, plan, total_steps

    version = plan(benchmark).spec.version
    controllers = tuple(controller) if controller else default_controllers(version)
    steps = total_steps(episodes, controllers, version)
    with progress_bar(f"crosscheck: {episodes} episodes", steps) as progress:
        result = crosscheck(episodes, controllers, benchmark=version, progress=progress)
    typer.echo(json.dumps(result.dump(), indent=2))
    if not result.passed:
        why = [] if result.gates_agree else ["gate outcomes differ"]
        if not result.max_abs_state_diff <= TOLERANCE:
            why.append(
                f"max_abs_state_diff {result.max_abs_state_diff:.3g} > {TOLERANCE:g} "
                f"(one-step max_abs_step_diff {result.max_abs_step_diff:.3g})"
            )
        raise ScftcError("crosscheck failed: " + "; ".join(why))
