"""Tuned parameters on disk: ``scftc_cli/params/<controller>.yaml``, with provenance.

A params file is small, versioned and committed; ``scftc eval`` reads it and never tunes.
"""

from __future__ import annotations

import datetime as dt
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from pydantic import BaseModel, Field

from scftc_cli import __version__
from scftc_cli.errors import ScftcError, UsageError

if TYPE_CHECKING:
    from scftc_cli.protocol import Controller
    from scftc_cli.registry import ControllerSpec

PACKAGE_DIR = Path(__file__).resolve().parent.parent
PARAMS_DIR = PACKAGE_DIR / "params"
WEIGHTS_DIR = PACKAGE_DIR / "weights"


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
    benchmark_version: str = "scftc-v1"
    package_version: str = __version__
    created_utc: str = ""
    notes: str = ""


class ParamsFile(BaseModel):
    controller: str
    params: dict[str, Any]
    provenance: Provenance


def params_path(controller: str) -> Path:
    return PARAMS_DIR / f"{controller}.yaml"


def save_params(
    controller: str, params: dict[str, Any], provenance: Provenance, path: Path | None = None
) -> Path:
    """Write a params file (creating folders); returns its path."""
    path = path or params_path(controller)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not provenance.created_utc:
        stamp = dt.datetime.now(dt.UTC).replace(microsecond=0).isoformat()
        provenance = provenance.model_copy(update={"created_utc": stamp})
    doc = ParamsFile(controller=controller, params=params, provenance=provenance)
    path.write_text(yaml.safe_dump(doc.model_dump(mode="json"), sort_keys=False))
    return path


def v2_params_path(controller: str) -> Path:
    """The committed tuned parameters of ``scftc-v2`` controller ``controller``."""
    return PARAMS_DIR / "v2" / f"{controller}.yaml"


def load_v2_params(controller: str) -> dict[str, Any]:
    """The ``params`` mapping of ``controller``'s committed ``scftc-v2`` params file."""
    path = v2_params_path(controller)
    if not path.exists():
        command = f"scftc train --benchmark scftc-v2 --controller {controller} --in-place"
        raise ScftcError(f"no tuned parameters at {path}; run `{command}`")
    return load_params(controller, path).params


def load_params(controller: str, path: Path | None = None) -> ParamsFile:
    """Read and validate a params file; a missing one names the command that makes it."""
    path = path or params_path(controller)
    if not path.exists():
        raise ScftcError(f"no tuned parameters at {path}; run `scftc train --controller {controller}`")
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
