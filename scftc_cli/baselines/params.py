"""Tuned parameters and trained weights on disk, with provenance.

A version's committed artifacts live in its folder: ``versions/<name>/params/<controller>.yaml``
(small, versioned; ``scftc eval`` reads it and never tunes) and ``versions/<name>/weights/`` (a
learned controller's ``.npz`` with a ``.yaml`` sidecar). ``committed_params`` and
``committed_weights`` find them for any version, and name the command that regenerates a missing one.
"""

from __future__ import annotations

import datetime as dt
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import yaml
from pydantic import BaseModel, Field

from scftc_cli import __version__
from scftc_cli.errors import ScftcError, UsageError
from scftc_cli.versions import benchmark_option, get_version

if TYPE_CHECKING:
    from scftc_cli.protocol import Controller
    from scftc_cli.registry import ControllerSpec


class Provenance(BaseModel):
    """How an artifact was made, so that anyone can regenerate it."""

    command: str
    seed: int
    budget: str
    train_settled_rate: float
    seeds_tried: int = Field(
        default=1,
        ge=1,
        description="Training seeds run before this artifact was committed (1: no selection).",
    )
    benchmark_version: str = Field(description="The version whose train split made it.")
    package_version: str = __version__
    created_utc: str = ""
    notes: str = ""


class ParamsFile(BaseModel):
    controller: str
    params: dict[str, Any]
    provenance: Provenance


def train_command(controller: str, benchmark: str) -> str:
    """The command that regenerates ``controller``'s committed artifact of ``benchmark``."""
    return f"scftc train {benchmark_option(benchmark)}--controller {controller} --in-place"


def committed_params(controller: str, benchmark: str) -> dict[str, Any]:
    """The ``params`` mapping of ``controller``'s committed params file of version ``benchmark``."""
    path = get_version(benchmark).params_dir / f"{controller}.yaml"
    return load_params(controller, path, benchmark).params


def committed_weights(controller: str, benchmark: str) -> Path:
    """The committed weights file of learned ``controller`` of version ``benchmark`` (it exists)."""
    path = get_version(benchmark).weights_dir / f"{controller}.npz"
    if not path.exists():
        raise ScftcError(f"no weights at {path}; run `{train_command(controller, benchmark)}`")
    return path


class Tuned:
    """Mixin of a controller with tuned parameters (a frozen dataclass ``params_type``): built with
    ``params``, or with the committed ones of ``tuned_as = (controller name, version)``."""

    params_type: ClassVar[type]
    tuned_as: ClassVar[tuple[str, str]]

    def __init__(self, params: Any = None) -> None:
        self.params = params if params is not None else self.params_type(**committed_params(*self.tuned_as))


def save_params(controller: str, params: dict[str, Any], provenance: Provenance, path: Path) -> Path:
    """Write a params file (creating folders); returns its path."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not provenance.created_utc:
        stamp = dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat()
        provenance = provenance.model_copy(update={"created_utc": stamp})
    doc = ParamsFile(controller=controller, params=params, provenance=provenance)
    path.write_text(yaml.safe_dump(doc.model_dump(mode="json"), sort_keys=False))
    return path


def load_params(controller: str, path: Path, benchmark: str | None = None) -> ParamsFile:
    """Read and validate a params file; a missing one names the command that makes it (for the
    committed file of ``benchmark``)."""
    if not path.exists():
        how = (
            f"run `{train_command(controller, benchmark)}`"
            if benchmark
            else "pass the file `scftc train --out` wrote"
        )
        raise ScftcError(f"no tuned parameters at {path}; {how}")
    return ParamsFile.model_validate(yaml.safe_load(path.read_text()))


def controller_from_artifact(entry: ControllerSpec, path: Path) -> Callable[[], Controller]:
    """A factory of built-in ``entry`` built from an artifact ``scftc train`` wrote: a params file
    (``.yaml``) for a tuned controller, a weights file for a learned one.

    Raises:
        UsageError: the file is missing, belongs to another controller, or the controller takes no
            such artifact.
    """
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"no such file: {path}; pass the file `scftc train --out` wrote")
    cls: Any = entry.load()  # a concrete controller class, whose constructor takes its artifact
    if path.suffix in (".yaml", ".yml"):
        params_type = getattr(cls, "params_type", None)
        if params_type is None:
            raise UsageError(
                f"`{entry.name}` has no tuned parameters; --params takes a params file of a tuned controller"
            )
        doc = load_params(entry.name, path)
        if doc.controller != entry.name:
            raise UsageError(f"{path} holds parameters of `{doc.controller}`, not `{entry.name}`")
        params = params_type(**doc.params)
        return lambda: cls(params)
    if "path" not in inspect.signature(cls).parameters:
        raise UsageError(f"`{entry.name}` loads no weights; --params takes a .yaml params file for it")
    return lambda: cls(path=path)
