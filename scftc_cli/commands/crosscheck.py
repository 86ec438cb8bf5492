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

    Prints one JSON document; exits 1 if any state differs by more than the version's tolerance
    (printed as `tolerance`: 1e-9 on v1 and v2, 1e-8 over v3's six-times-longer flights) in sigma,
    omega in rad/s or a state of the version's own (wheel speeds as a fraction of their speed
    limit), if any gate outcome differs, or, on v3, if one step from identical states differs by
    more than 1e-12. On v3 a flight whose own closed loop amplifies rounding past the tolerance is
    held to 8.8 times the departure of its rounding twin (the same flight with every state moved
    one rounding unit a step) instead: `flight_bound` per flight in the JSON.
    """
    from scftc_cli.errors import ScftcError
    from scftc_cli.study.crosscheck import crosscheck, default_controllers, plan, total_steps

    version = plan(benchmark).spec.version
    controllers = tuple(controller) if controller else default_controllers(version)
    steps = total_steps(episodes, controllers, version)
    with progress_bar(f"crosscheck: {episodes} episodes", steps, benchmark=version) as progress:
        result = crosscheck(episodes, controllers, benchmark=version, progress=progress)
    typer.echo(json.dumps(result.dump(), indent=2))
    if not result.passed:
        why = [] if result.gates_agree else ["gate outcomes differ"]
        failures = result.state_failures()
        if failures:
            why.extend(failures)
            why.append(f"one-step max_abs_step_diff {result.max_abs_step_diff:.3g}")
        elif not why:
            why.append(f"one-step max_abs_step_diff {result.max_abs_step_diff:.3g} above its bound")
        raise ScftcError("crosscheck failed: " + "; ".join(why))
