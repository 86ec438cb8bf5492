"""``fdir``: a flight-style fault detection, isolation and recovery controller for ``scftc-v2``
(docs/fdir.md).

Deployable (it never sees the fault). Three layers, each in its own module:

- attitude determination (``mekf.py``): a multiplicative extended Kalman filter on the three
  star-tracker heads and the gyro, estimating the gyro bias (its constant part and a step), with
  per-head innovation tests that latch out a frozen or biased head and ride through an outage;
- wheel FDI (``detection.py``): per-wheel CUSUM on the tachometer-derived torque residuals,
  re-identification of each wheel's effectiveness, offset and Coulomb friction by least squares
  restarted at a confirmed change; a wheel identified dead leaves the allocation;
- recovery: the analytic law of ``law.py`` (PD on the filtered attitude and the bias-corrected
  rate, gyroscopic feed-forward), allocated through the estimated effective matrix
  ``pinv(G diag(g_hat))`` with each working wheel cancelling its estimated offset and friction.

Tuned on the train split only (this version's ``training/fdir.py``); the committed parameters are
its ``params/fdir.yaml``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scftc_cli.baselines.params import committed_params, load_params
from scftc_cli.protocol import Context, Controller
from scftc_cli.versions.v2.controllers.detection import DetectorSettings, WheelMonitor
from scftc_cli.versions.v2.controllers.law import (
    allocate,
    friction_nm,
    pseudo_inverse,
    split_observation,
    torque_demand,
    wheels_of,
)
from scftc_cli.versions.v2.controllers.mekf import MEKF, MEKFFields, inv3
from scftc_cli.versions.v2.spec import V2

NAME = "fdir"


@dataclass(frozen=True)
class FDIRParams(MEKFFields):
    """Every tunable figure, flat (filter ``mekf_*``, wheel detector ``wheel_*``); the defaults
    are the untuned starting point of docs/fdir.md."""

    wheel_drift: float = DetectorSettings.drift
    wheel_threshold: float = DetectorSettings.threshold
    wheel_model_noise: float = DetectorSettings.model_noise
    wheel_consistent: float = DetectorSettings.consistent
    wheel_buffer: int = DetectorSettings.buffer
    wheel_prior_gain: float = DetectorSettings.prior_gain
    wheel_prior_bias: float = DetectorSettings.prior_bias
    wheel_prior_friction: float = DetectorSettings.prior_friction
    wheel_prior_start: float = DetectorSettings.prior_start
    wheel_clip_margin: float = DetectorSettings.clip_margin
    wheel_reid_sd: float = DetectorSettings.reid_sd
    wheel_dead_gain: float = DetectorSettings.dead_gain
    wheel_revive_gain: float = DetectorSettings.revive_gain
    dither: float = 0.02
    probe: float = 0.1

    def detector(self) -> DetectorSettings:
        return DetectorSettings(**_strip(self, "wheel_", DetectorSettings))


def _strip(params: FDIRParams, prefix: str, target: type) -> dict[str, Any]:
    """The fields of ``target`` from ``params``' fields named ``prefix + name``."""
    return {f.name: getattr(params, prefix + f.name) for f in dataclasses.fields(target)}


def pseudo_inverse3(matrix: np.ndarray, damping: float = 1e-12) -> np.ndarray:
    """``law.pseudo_inverse`` (``M' (M M' + eps I)^-1``, ``(n, 3, m) -> (n, m, 3)``) with the
    3x3 inverse in closed form (``inv3``) and ``eps`` the plain ``damping`` times the trace: the
    same allocation ``pinv(G diag(g_hat))``, faster per step."""
    return pseudo_inverse(matrix, damping, invert=inv3, floor_zero_trace=False)


def null_direction(axes: np.ndarray) -> np.ndarray:
    """The null direction ``n`` ``(4,)`` of four wheels' spin axes ``G`` ``(3, 4)`` (``G n = 0``):
    the signed 3x3 minors ``n_j = (-1)^j det(G without column j)``, each determinant
    ``(a (e i - f h) + b (f g - d i)) + c (d h - e g)`` of its rows ``(a b c), (d e f), (g h i)``
    (products rounded, then added in that order), scaled so that its largest entry in magnitude is
    one and its entries sum to a positive number (``(1, 1, 1, 1)`` for the pyramid). Exact where
    the minors are, with no library's choice of sign or scale."""
    axes = np.asarray(axes, dtype=np.float64)
    if axes.shape != (3, 4):
        raise ValueError(f"fdir's null-space dither needs four wheels: spin axes {axes.shape[::-1]}")
    minors = np.empty(4)
    for j in range(4):
        (a, b, c), (d, e, f), (g, h, i) = np.delete(axes, j, axis=1).tolist()
        minors[j] = (-1.0) ** j * ((a * (e * i - f * h) + b * (f * g - d * i)) + c * (d * h - e * g))
    largest = np.abs(minors).max()
    if not largest > 0.0:
        raise ValueError("fdir's null-space dither needs spin axes of full rank")
    total = ((minors[0] + minors[1]) + minors[2]) + minors[3]
    return minors / (largest if total > 0.0 else -largest)


def load_fdir_params(path: Path | None = None) -> FDIRParams:
    """The committed (or ``path``'s) tuned parameters."""
    return FDIRParams(**(load_params(NAME, path).params if path else committed_params(NAME, V2.version)))


class FDIR(Controller):
    """MEKF + per-wheel CUSUM/least-squares FDI + the analytic law through the estimated
    effective matrix (module docstring). Deployable.

    After a rollout: ``detected_step`` ``(n, m)`` (first confirmed wheel change, -1 if none),
    ``alarm_steps`` ``(n, steps, m)`` (CUSUM alarms per step), ``head_out_step`` ``(n, 3)`` and
    ``bias_alarm_step`` ``(n,)`` (the filter's), for the study's detection plots.
    """

    params_type = FDIRParams

    def __init__(self, params: FDIRParams | None = None) -> None:
        self.params = params if params is not None else load_fdir_params()

    def reset(self, n: int, context: Context) -> None:
        self.context, self.wheels = context, wheels_of(context)
        assert context.sensors is not None  # wheels_of checked it
        self.filter = MEKF(n, context.sensors, context.dt_s, self.params.mekf())
        self.monitor = WheelMonitor(n, self.wheels, context.sensors, context.dt_s, self.params.detector())
        self.null = null_direction(self.wheels.spin_axes.T)  # (m,): G n = 0
        self.k = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        heads, valid, gyro, tach = split_observation(obs)
        sigma, rate = self.filter.step(heads, valid, gyro)
        self.monitor.observe(tach, gyro)
        working = self.monitor.in_service
        gain = np.where(working, self.monitor.gain, 0.0)
        demand = torque_demand(sigma, rate, tach, self.context)
        # a wheel out of service: its torque (friction and offset) is cancelled by the others
        friction = friction_nm(tach, self.monitor.coulomb_nm, self.wheels)
        friction = friction + np.where(working, 0.0, self.monitor.bias * self.wheels.u_max_nm)
        bias = np.where(working, self.monitor.bias, 0.0)
        command = allocate(demand, self._allocation(gain), gain, friction, bias, self.wheels)
        # headroom for the dither, so that a saturated wheel still carries information
        p = self.params
        command = np.clip(command, p.dither - 1.0, 1.0 - p.dither)
        sign = 1.0 if self.k % 2 == 0 else -1.0
        command = command + sign * self._probe(gain, self.monitor.isolated)
        self.monitor.commanded(command)
        self.k += 1
        return command

    def _allocation(self, gain: np.ndarray) -> np.ndarray:
        """``pinv(G diag(g))`` ``(n, m, 3)``; zero where no wheel is in service (every wheel
        isolated at once: a few steps of coasting while the probes re-identify them)."""
        none = ~(gain != 0.0).any(axis=1)
        effective = self.wheels.spin_axes.T[None, :, :] * np.where(none[:, None], 1.0, gain)[:, None, :]
        return np.where(none[:, None, None], 0.0, pseudo_inverse3(effective))

    def _probe(self, gain: np.ndarray, isolated: np.ndarray) -> np.ndarray:
        """The excitation ``(n, m)`` of this step (times the alternating sign): ``probe`` on an
        isolated wheel (it carries no control), ``dither`` on a dead one; when every wheel is in
        service, ``dither`` along the null space of the estimated effective matrix
        ``G diag(g_hat)``, ``n_G / g_hat`` (``G n_G = 0``), which excites every wheel without a body
        torque when the estimates are right."""
        p = self.params
        out_of_service = gain == 0.0
        null = self.null / np.where(out_of_service, 1.0, gain)
        null = p.dither * null / np.abs(null).max(axis=1, keepdims=True)
        outside = np.where(isolated, p.probe, p.dither)
        return np.where(out_of_service.any(axis=1)[:, None], np.where(out_of_service, outside, 0.0), null)

    # -- diagnostics --------------------------------------------------------------------------

    @property
    def detected_step(self) -> np.ndarray:
        return self.monitor.detected_step

    @property
    def alarm_steps(self) -> np.ndarray:
        return np.stack(self.monitor.alarm_log, axis=1)

    @property
    def change_steps(self) -> np.ndarray:
        return np.stack(self.monitor.change_log, axis=1)

    @property
    def head_out_step(self) -> np.ndarray:
        return self.filter.head_out_step

    @property
    def bias_alarm_step(self) -> np.ndarray:
        return self.filter.bias_alarm_step

    def false_alarms(self, onset_step: np.ndarray) -> np.ndarray:
        """Wheel-steps with a CUSUM alarm up to each episode's onset ``(n,)``: false by
        construction (the alarm of step ``k`` tests the step ``k - 1`` just flown, healthy while
        ``k <= onset``)."""
        before = np.arange(self.alarm_steps.shape[1])[None, :] <= np.asarray(onset_step)[:, None]
        return (self.alarm_steps & before[:, :, None]).sum(axis=(1, 2))
