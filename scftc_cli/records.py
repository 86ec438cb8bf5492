"""Result records: the pydantic models that land on disk and on stdout (SPEC section 6)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from scftc_cli import BENCHMARK_VERSION


class GateStat(BaseModel):
    """Episodes passing one gate: ``k`` of the cell's ``n``, the rate and its Wilson interval."""

    k: int = Field(ge=0)
    rate: float = Field(ge=0, le=1)
    ci_low: float = Field(ge=0, le=1)
    ci_high: float = Field(ge=0, le=1)


class FinalError(BaseModel):
    median: float
    mean: float


class CellResult(BaseModel):
    """One cell (controller, split, class, sensor fault) scored on the true state."""

    model_config = ConfigDict(populate_by_name=True)

    split: str
    fault_class: str = Field(alias="class")
    sensor: str | None
    n: int = Field(gt=0)
    settled: GateStat
    operational: GateStat
    touch_once: GateStat
    final_error_deg: FinalError

    @property
    def key(self) -> tuple[str, str, str | None]:
        return (self.split, self.fault_class, self.sensor)


class EvalResult(BaseModel):
    """The JSON document ``scftc eval --format json`` prints."""

    benchmark_version: str = BENCHMARK_VERSION
    controller: str
    privileged: bool
    backend: str
    cells: list[CellResult]

    def dump(self) -> dict:
        return self.model_dump(mode="json", by_alias=True)
