"""Calibrated randomization: a fitted profile's intervals drawn afresh every episode.

``comat train ... reality=PROFILE.yaml reality_draw=intervals`` trains under a layer whose
identified parameters are not the profile's point values but one draw per episode and team from
each parameter's 95 % interval (the ``fit`` rows ``comat calibrate`` writes, with ``lo``, ``hi``
and an ``interval`` kind, :mod:`comat.calibration.intervals`). Fields without an interval keep the
profile's value; the default (``reality_draw=point``) is the profile's point values, as before.

==========================  ================================  ==============================================
fit row                     drawn into                        per episode and team
==========================  ================================  ==============================================
``pose_delay_jitter_prob``  ``pose_delay_jitter_prob``        U[lo, hi] ∩ [0, 1]
``pose_hold_prob``          ``pose_hold_prob``                U[lo, hi] ∩ [0, 1]
``pose_noise_xy_m``         ``pose_noise_xy_m``               U[lo, hi] ∩ [0, ∞)
``pose_noise_theta_rad``    ``pose_noise_theta_rad``          U[lo, hi] ∩ [0, ∞)
``motor_dead_zone_radps``   ``motor_dead_zone_radps``         U[lo, hi] ∩ [0, ∞)
``speed_gain``              ``wheel_gain_mean``               U[lo, hi] ∩ [0.01, 2]
``wheel_gain_spread``       ``wheel_gain_spread``             U[lo, hi] ∩ [0, 0.99]
``top_speed_derate_min``    ``top_speed_derate_min``          U[lo, hi] ∩ [0.01, 1]
``motor_tau_s``             both ends of the lag's range      moved by U[lo, hi] - estimate, floored at 0
==========================  ================================  ==============================================

Not drawn (:data:`NOT_DRAWN`): the ``range`` rows (the delay, the reachable speeds) describe the
robots' spread, which the layer already draws robot by robot within the profile's range; the turn
gain, the tracked point and the loop tick are not in the layer.

Why uniform: an interval is what the logs cannot rule out, not a belief centred on the estimate;
several are lopsided (``order95``, ``chi2_95``: the estimate is not their middle) and a truncated
normal would need a centre and a width the fit does not give. Uniform draws visit the interval's
ends as often as its middle, so a policy meets the worst plausible robot as often as the likeliest
(the usual choice of domain randomization: Tobin et al. 2017, OpenAI et al. 2019).

Randomness: each team's draws come from its first robot's episode key (stream
:data:`EPISODE_STREAM`), so the same seed gives the same draws, every episode draws afresh, and one
parameter's draw does not depend on which others the profile has (one stream per name,
:data:`DRAW_NAMES`). The layer's own draws are untouched: a run at ``reality_draw=point`` is the
profile's run bit for bit.

The layer is built for the widest the draws reach (:func:`envelope`: the noise and lag at their
upper ends, the derate at its lower one): its buffers, its switches and the safety filter's margin
(:func:`comat.reality.margin.robust_safety`) cover every episode's draw.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from pathlib import Path
from typing import Any

import numpy as np

from comat.reality.config import KINDS, LEVELS, PARAMETER_KINDS, RealityConfig, read_profile

__all__ = [
    "DRAW_MODES",
    "DRAW_NAMES",
    "EPISODE_STREAM",
    "NOT_DRAWN",
    "CalibratedReality",
    "calibrated",
    "draw_values",
    "envelope",
    "profile_intervals",
    "profile_sha256",
]

DRAW_MODES = ("point", "intervals")
"""``point``: the profile's values (the default); ``intervals``: each episode draws the identified
parameters from their intervals."""
DRAWS: dict[str, tuple[str, float, float]] = {
    "pose_delay_jitter_prob": ("pose_delay_jitter_prob", 0.0, 1.0),
    "pose_hold_prob": ("pose_hold_prob", 0.0, 1.0),
    "pose_noise_xy_m": ("pose_noise_xy_m", 0.0, math.inf),
    "pose_noise_theta_rad": ("pose_noise_theta_rad", 0.0, math.inf),
    "motor_dead_zone_radps": ("motor_dead_zone_radps", 0.0, math.inf),
    "speed_gain": ("wheel_gain_mean", 0.01, 2.0),
    "wheel_gain_spread": ("wheel_gain_spread", 0.0, 0.99),
    "top_speed_derate_min": ("top_speed_derate_min", 0.01, 1.0),
    "motor_tau_s": ("motor_tau_shift_s", -math.inf, math.inf),
}
"""Fit row -> (what it draws, the lowest and highest value the layer accepts)."""
DRAW_NAMES = tuple(name for name, _, _ in DRAWS.values())
"""What a profile's intervals can draw, in stream order: RealityConfig fields, and
``motor_tau_shift_s`` (s), added to both ends of the profile's lag range."""
NOT_DRAWN = {
    "pose_delay_ticks": "a range over robots: the layer draws each episode's delay within it",
    "top_speed_fraction": "a range over robots: the layer draws each robot's cap from [derate, 1]",
    "turn_gain": "not in the layer (its turn gain is the speed gain)",
    "tracked_ahead_m": "not in the layer",
    "loop_tick_s": "not in the layer",
}
"""Fit rows whose interval is not drawn, and why."""
EPISODE_STREAM = 800
"""The per-episode stream offset of the draws (the layer's own use 100 ... 700)."""


def profile_sha256(path: str | Path) -> str:
    """The SHA-256 of a profile file's bytes (what a run's config records beside its path)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def profile_intervals(path: str, name: str = "reality_draw") -> dict[str, tuple[float, float]]:
    """Draw name -> (lo, hi) from the ``fit`` rows of the profile ``path`` that have an interval,
    mapped and clipped as :data:`DRAWS` says. One-line ValueError naming ``name``, the profile, the
    row, the expectation and the value for: a profile without fit rows, an interval kind that is not
    one of :data:`~comat.reality.config.KINDS` (or not its parameter's), lo > hi or an end not
    finite, a row that names no RealityConfig field or fitted parameter, or a RealityConfig field the
    layer cannot draw per episode."""
    import yaml

    read_profile(path, name)  # a profile at all, of the present format
    data = yaml.safe_load(Path(path).read_text())
    rows = data.get("fit")
    where = f"{name}: profile {path!r}"
    if not isinstance(rows, list) or not rows:
        raise ValueError(f"{where} has no fit rows with intervals to draw from (write it with comat calibrate --out)")
    out = {}
    for row in rows:
        if not isinstance(row, dict) or "name" not in row:
            raise ValueError(f"{where}: fit rows must be mappings with a 'name', got {row!r}")
        param, kind = row["name"], row.get("interval")
        if kind is None:
            continue  # no interval (too few robots or runs): the profile's value stays
        if kind not in KINDS:
            raise ValueError(f"{where}: {param}'s interval kind must be one of {list(KINDS)}, got {kind!r}")
        if param not in DRAWS and param not in NOT_DRAWN:
            fields = set(LEVELS["off"])
            if param in fields:
                raise ValueError(
                    f"{where}: {param} must be a field drawn per episode ({sorted(DRAWS)}) to have an "
                    f"interval, got one ({kind!r})"
                )
            raise ValueError(
                f"{where}: fit row name must be a RealityConfig field or a fitted parameter "
                f"({sorted({*DRAWS, *NOT_DRAWN})}), got {param!r}"
            )
        if kind != PARAMETER_KINDS.get(param, kind):
            raise ValueError(
                f"{where}: {param}'s interval kind must be {PARAMETER_KINDS[param]!r}, its parameter's, got {kind!r}"
            )
        lo, hi = row.get("lo"), row.get("hi")
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (lo, hi)):
            raise ValueError(f"{where}: {param}'s lo and hi must be finite numbers, got lo={lo!r}, hi={hi!r}")
        if lo > hi:
            raise ValueError(f"{where}: {param}'s interval must have lo <= hi, got lo={lo!r} > hi={hi!r}")
        if param in NOT_DRAWN:
            continue
        draw, least, most = DRAWS[param]
        if draw == "motor_tau_shift_s":
            estimate = row.get("estimate")
            if not isinstance(estimate, (int, float)) or not math.isfinite(estimate):
                raise ValueError(f"{where}: {param}'s estimate must be a finite number, got {estimate!r}")
            lo, hi = lo - estimate, hi - estimate
        out[draw] = (float(min(max(lo, least), most)), float(min(max(hi, least), most)))
    return {k: out[k] for k in DRAW_NAMES if k in out}


def envelope(point: RealityConfig, intervals: dict[str, tuple[float, float]]) -> dict[str, Any]:
    """The fields of the layer that covers every draw of ``intervals`` around ``point``: each drawn
    field at the end farthest from the ideal world (noise, holds, jitter, dead zone, spread at their
    upper ends; the derate at its lower one; the gain at the end farther from 1; the lag range moved
    by the shift's ends). Its switches, buffers and the filter's margin are then those of the worst
    episode the draws can make."""
    out = dataclasses.asdict(point)
    for draw, (lo, hi) in intervals.items():
        if draw == "motor_tau_shift_s":
            out["motor_tau_min_s"] = max(point.motor_tau_min_s + lo, 0.0)
            out["motor_tau_max_s"] = max(point.motor_tau_max_s + hi, 0.0, out["motor_tau_min_s"])
        elif draw == "top_speed_derate_min":
            out[draw] = lo
        elif draw == "wheel_gain_mean":
            out[draw] = lo if abs(lo - 1.0) > abs(hi - 1.0) else hi
        else:
            out[draw] = hi
    return out


def draw_values(intervals: dict[str, tuple[float, float]], u: np.ndarray) -> dict[str, np.ndarray]:
    """Draw name -> (b,) values, uniform in each interval, from uniforms ``u`` (b, len(DRAW_NAMES))
    (one column per name in :data:`DRAW_NAMES` order, whether the profile has it or not)."""
    return {name: lo + (hi - lo) * u[:, DRAW_NAMES.index(name)] for name, (lo, hi) in intervals.items()}


class CalibratedReality(RealityConfig):
    """A :class:`RealityConfig` whose identified fields are drawn per episode from a profile's
    intervals. Its fields are the :func:`envelope` (what the layer and the filter are built for);
    :attr:`point` holds the profile's own values, :attr:`intervals` draw name -> (lo, hi),
    :attr:`profile` and :attr:`sha256` the file they came from. Build it with :func:`calibrated`."""

    point: RealityConfig
    intervals: dict[str, tuple[float, float]]
    profile: str
    sha256: str

    @property
    def label(self) -> str:
        """``calibrated`` (a row's reality label): the profile's intervals, drawn every episode."""
        return "calibrated"

    def record(self) -> dict[str, Any]:
        """What a run's config stores of the draws: mode, profile path, its hash and the intervals."""
        return {
            "mode": "intervals",
            "profile": self.profile,
            "sha256": self.sha256,
            "intervals": {k: [lo, hi] for k, (lo, hi) in self.intervals.items()},
        }

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, CalibratedReality)
            and self.point == other.point
            and self.intervals == other.intervals
            and self.sha256 == other.sha256
        )

    def __hash__(self) -> int:
        return hash((self.point, tuple(self.intervals.items()), self.sha256))

    def __reduce__(self):  # pickled to env worker processes: rebuilt through calibrated()
        return (calibrated, (self.point, self.intervals, self.profile, self.sha256))


def calibrated(
    point: RealityConfig, intervals: dict[str, tuple[float, float]], profile: str, sha256: str
) -> CalibratedReality:
    """The layer that draws ``intervals`` (:func:`profile_intervals`) per episode around the point
    values ``point`` (the profile's fields), recorded as coming from ``profile`` with hash ``sha256``."""
    unknown = sorted(set(intervals) - set(DRAW_NAMES))
    if unknown:
        raise ValueError(f"reality_draw.intervals names must be among {list(DRAW_NAMES)}, got {unknown}")
    for name, (lo, hi) in intervals.items():
        if not lo <= hi:
            raise ValueError(f"reality_draw.intervals.{name} must have lo <= hi, got [{lo}, {hi}]")
    config = CalibratedReality(**envelope(point, intervals))
    for attr, value in (
        ("point", point),
        ("intervals", {k: (float(lo), float(hi)) for k, (lo, hi) in intervals.items()}),
        ("profile", str(profile)),
        ("sha256", str(sha256)),
    ):
        object.__setattr__(config, attr, value)
    return config
