"""The built-in controllers of each benchmark version: data, imported on first use.

Like Gymnasium's registry, an entry names its class as a ``"module:Class"`` string, so listing the
battery, or running ``pd``, never imports the learned controllers (or torch). Each version lists its
own (``Version.controllers``, in battery order: deployable controllers, then the privileged
oracles). An unknown name suggests the closest one; a name that exists for another benchmark
version says which versions it flies.
"""

from __future__ import annotations

from scftc_cli.errors import UnknownNameError, UsageError
from scftc_cli.protocol import Controller
from scftc_cli.versions import ControllerSpec, all_versions, default_version, get_version, version_names

__all__ = ["ControllerSpec", "builtin_names", "controller_spec", "make_controller", "registry"]


def registry(benchmark: str | None = None) -> dict[str, ControllerSpec]:
    """The built-ins that fly ``benchmark`` (the default version when ``None``), deployable ones
    first, then the oracles, in battery order. A name is unique within a version; the same name on
    two versions (``pd``) is the same method, ported."""
    chosen = get_version(benchmark or default_version()).controllers
    ordered = sorted(chosen, key=lambda c: c.privileged)  # stable: battery order within each group
    return {c.name: c for c in ordered}


def builtin_names() -> set[str]:
    """Every built-in's name, on any benchmark version, ports still in training included (reserved
    on every board: a submission cannot take the name a built-in is about to have)."""
    return {c.name for version in all_versions() for c in (*version.controllers, *version.in_training)}


def controller_spec(name: str, benchmark: str | None = None, in_training: bool = False) -> ControllerSpec:
    """The entry of ``name`` for ``benchmark`` (the default version when ``None``); with
    ``in_training``, also a port of that version whose committed artifact does not exist yet
    (``Version.in_training``: what ``scftc train`` writes, flown only from the file it wrote).

    Raises:
        UnknownNameError: no built-in has that name, or no version that one (the closest names are
            suggested).
        UsageError: it exists, but flies other benchmark versions only (they are named), or is
            still in training there.
    """
    benchmark = benchmark or default_version()
    if benchmark not in version_names():
        raise UnknownNameError("benchmark version", benchmark, version_names())
    here = registry(benchmark)
    if name in here:
        return here[name]
    pending = {c.name: c for c in get_version(benchmark).in_training}
    if name in pending:
        if in_training:
            return pending[name]
        raise UsageError(
            f"`{name}` is still in training on {benchmark}: it has no committed artifact yet; "
            f"`scftc train --benchmark {benchmark} --controller {name} --out FILE` writes one, and "
            f"`--params FILE` flies it"
        )
    versions = [v.name for v in all_versions() if any(c.name == name for c in v.controllers)]
    if not versions:
        raise UnknownNameError("controller", name, here)
    raise UsageError(
        f"controller `{name}` flies {', '.join(versions)} only, not {benchmark}; "
        f"pick one of its versions with --benchmark, or a controller of {benchmark} (`scftc list`)"
    )


def make_controller(name: str, benchmark: str | None = None) -> Controller:
    """A fresh instance of the built-in controller ``name``."""
    return controller_spec(name, benchmark).make()
