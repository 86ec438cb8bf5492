"""``wheel_features`` (``scftc_cli/versions/v2/controllers/student.py``) in numpy: the readable
form the compiled pass (``_feature_rows``) is tested against, bit for bit."""

from __future__ import annotations

import numpy as np

from scftc_cli.versions.v2.controllers.student import INNOVATION_CLIP, N_FEATURES, RATIO_CLIP, RATIO_EPS


def wheel_features(
    a: np.ndarray,
    y: np.ndarray,
    da: np.ndarray,
    dy: np.ndarray,
    psi: np.ndarray,
    speed: np.ndarray,
    innovation: np.ndarray,
    after_alarm: np.ndarray,
    clipped: np.ndarray,
    valid_raw: np.ndarray,
    valid_diff: np.ndarray,
) -> np.ndarray:
    """``student.wheel_features`` in numpy: ``(n * m, N_FEATURES)`` features, invalid pairs zeroed."""
    a_r, y_r = a * valid_raw, y * valid_raw
    da_d, dy_d = da * valid_diff, dy * valid_diff
    ratio = np.clip(a_r * y_r / (a_r * a_r + RATIO_EPS), -RATIO_CLIP, RATIO_CLIP)
    ratio_diff = np.clip(da_d * dy_d / (da_d * da_d + RATIO_EPS), -RATIO_CLIP, RATIO_CLIP)
    cols = (
        a_r,
        y_r,
        da_d,
        dy_d,
        a_r * y_r,
        a_r * a_r,
        ratio,
        ratio_diff,
        psi,
        speed,
        np.clip(innovation, -INNOVATION_CLIP, INNOVATION_CLIP),
        after_alarm,
        clipped,
        np.where(clipped, np.sign(y * a), 0.0),
        valid_raw,
        valid_diff,
    )
    return np.stack([np.asarray(c, dtype=np.float64) for c in cols], axis=-1).reshape(-1, N_FEATURES)
