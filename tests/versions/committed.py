"""What every version's committed learned weights must satisfy (shared by the versions' tests)."""

from __future__ import annotations

import numpy as np
import yaml

from scftc_cli.baselines import recurrent
from scftc_cli.versions import get_version


def check_committed_weights(version: str, name: str) -> None:
    """``name``'s committed ``.npz`` of ``version``: small, finite float32 arrays, with a ``.yaml``
    sidecar that describes them and records the full-budget, seed-0 command that regenerates them."""
    path = get_version(version).weights_dir / f"{name}.npz"
    assert path.stat().st_size < 1_000_000
    arrays, config = recurrent.load_weights(path)
    assert arrays and all(a.dtype == np.float32 and np.all(np.isfinite(a)) for a in arrays.values())
    doc = yaml.safe_load(path.with_suffix(".yaml").read_text())
    assert doc["controller"] == name and doc["params"]["weights_file"] == path.name
    assert doc["params"]["config"] == config  # the sidecar describes the weights beside it
    prov = doc["provenance"]
    assert prov["command"].startswith(f"scftc train --benchmark {version} --controller {name}")
    assert prov["benchmark_version"] == version and prov["budget"] == "full" and prov["seed"] == 0
    assert 0.0 <= prov["train_settled_rate"] <= 1.0
