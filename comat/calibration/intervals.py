"""The intervals a calibration profile states: one kind per parameter, chosen by what replicates it.

A quantity each robot has on its own (its gains, lag, noise, dead zone) is replicated by robots: the
95 % interval over them is for the fleet the robots come from. A quantity common to the team — one
pose message per tick carries every robot's pose, so its holds and its jitter happen to all robots at
once — has one replicate per tick, not per robot: a t-interval over robots counts one process as many
(it covered the holds' truth in 1 of 5 runs). Its interval is over blocks of ticks, each run
resampled on its own.

==============  =======================================================  ====================================
kind            interval                                                  parameters
==============  =======================================================  ====================================
``t95``         95 % Student-t over robots (the fleet's mean)             lag, speed and turn gains, tracked
                                                                          point, pose noise, dead zone
``t95_runs``    95 % Student-t over runs                                  loop tick
``block95``     95 % circular block bootstrap over ticks, runs apart      holds, pose jitter
                (:func:`comat.measure.stats.block_bootstrap_mean`)
``chi2_95``     95 % chi-square over robots, their own error taken out    the wheels' gain spread
``order95``     95 % for the fleet's smallest cap from the smallest of     top-speed derate
                n robots' caps (caps uniform, unseen ones censored)
``range``       the robots' range: a description, not a 95 % interval     delay, reachable speeds
==============  =======================================================  ====================================

Profiles written before these kinds (``format`` missing: holds with a t-interval over robots, the
gain spread with a bootstrap over four robots, nominal's jitter kept on top of a fitted total delay)
are refused by name with the command that regenerates them (:func:`check_fit`,
:func:`comat.reality.config.read_profile`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from comat.reality.config import KINDS, PARAMETER_KINDS, PROFILE_FORMAT

__all__ = [
    "KINDS",
    "PARAMETER_KINDS",
    "check_fit",
    "derate_interval",
    "read_fit",
    "spread_interval",
]

CONFIDENCE = 0.95


def derate_interval(
    reachable: Sequence[float], censored: Sequence[float], errors: Sequence[float] | None = None
) -> tuple[float, float, float]:
    """(estimate, lo, hi) of the fleet's ``top_speed_derate_min`` a from n robots: ``reachable``, the
    caps seen binding (fraction of the top wheel speed) with their standard ``errors`` (0 if None),
    and ``censored``, for each robot whose cap was not seen, the level its cap is at least (what it
    reached, its own error taken off).

    The layer draws each robot's cap from U(a, 1), so for the smallest m of n caps
    P(m > t) = ((1 - t) / (1 - a))^n. The interval inverts that at 2.5 % and 97.5 %: the upper end from
    the smallest cap seen, read at its upper 97.5 % bound (a cap read low would otherwise put the
    fleet's minimum too low), the lower from the smallest of every level known at its lower bound (a
    censored robot's cap is only known to lie above its level). The estimate is median-unbiased for a;
    with no cap seen it is 1 (none seen) and the interval says how low a may still be. Four robots say
    little about the fleet's smallest cap: at a smallest cap of 0.90 the interval is [0.75, 0.90]."""
    seen, above = np.asarray(reachable, float), np.asarray(censored, float)
    err = np.zeros(seen.size) if errors is None else np.nan_to_num(np.asarray(errors, float))
    n = seen.size + above.size
    if n == 0:
        raise ValueError("derate_interval needs at least one robot, got none")
    tail = (1.0 - CONFIDENCE) / 2.0
    z = 1.959963984540054  # the normal's 97.5 % point
    low_level = float(min((seen - z * err).min(initial=1.0), above.min(initial=1.0)))
    lo = 1.0 - (1.0 - low_level) / tail ** (1.0 / n)
    if seen.size == 0:
        return 1.0, lo, 1.0
    estimate = 1.0 - (1.0 - float(seen.min())) / 0.5 ** (1.0 / n)
    hi = 1.0 - (1.0 - min(float((seen + z * err).min()), 1.0)) / (1.0 - tail) ** (1.0 / n)
    return estimate, lo, hi


def spread_interval(diffs: Sequence[float], errors: Sequence[float]) -> tuple[float, float | None, float | None]:
    """(estimate, lo, hi) of the layer's ``wheel_gain_spread`` s from each robot's half gain
    difference (g_r - g_l)/2 (n,) and its standard error (n,) (a jackknife over time blocks).

    The layer draws each wheel's gain from U(m - s, m + s), so a robot's half difference has variance
    s²/6; its estimate adds its own error, whose mean square is taken out: s² = 6 (S² - mean SE²)
    with S² the variance over robots. The interval is the chi-square one for the variance over robots
    (n - 1 degrees of freedom), less the same mean square, floored at 0. None with fewer than 2 robots."""
    from scipy import stats

    d, e = np.asarray(diffs, float), np.asarray(errors, float)
    n = d.size
    if n < 2:
        return float("nan"), None, None
    var, own = float(d.var(ddof=1)), float(np.nanmean(e**2)) if np.isfinite(e).any() else 0.0
    tail = (1.0 - CONFIDENCE) / 2.0
    hi_var = (n - 1) * var / stats.chi2.ppf(tail, n - 1)
    lo_var = (n - 1) * var / stats.chi2.ppf(1.0 - tail, n - 1)

    def spread(v: float) -> float:
        return math.sqrt(6.0 * max(v - own, 0.0))

    return spread(var), spread(lo_var), spread(hi_var)


def check_fit(rows: list, path: str, logs: Sequence[str] | None = None) -> list[dict]:
    """The fit rows of the profile ``path`` if every interval is of its parameter's kind
    (:data:`PARAMETER_KINDS`); a one-line ValueError naming the profile, the parameter, the kind found,
    the kind expected and the command that regenerates the profile from its ``logs`` otherwise."""
    if not isinstance(rows, list) or not all(isinstance(r, dict) and "name" in r for r in rows):
        raise ValueError(f"profile {path!r}: 'fit' must be a list of rows with a 'name', as comat calibrate writes")
    for r in rows:
        kind, want = r.get("interval"), PARAMETER_KINDS.get(r["name"])
        if kind is not None and kind != want:
            raise ValueError(
                f"profile {path!r}: {r['name']}'s interval is {kind!r}, but its kind is {want!r}; regenerate it: "
                f"comat calibrate {' '.join(str(x) for x in logs or ['LOGS...'])} --out {path} --force"
            )
    return rows


def read_fit(path: str | Path) -> list[dict]:
    """The fit rows (name, estimate, lo, hi, interval, ...) of a profile ``comat calibrate`` wrote,
    checked (:func:`check_fit`): what reads a profile's intervals reads them through this. One-line
    errors for a file that is not a profile, one written before the present kinds (its ``format``
    older than :data:`~comat.reality.config.PROFILE_FORMAT`: refused by
    :func:`~comat.reality.config.read_profile` with the command that regenerates it), or a row of
    the wrong kind."""
    import yaml

    from comat.reality.config import read_profile

    read_profile(str(path), "profile")  # a profile at all, and of the present format
    data = yaml.safe_load(Path(path).read_text())
    if "fit" not in data:
        raise ValueError(f"profile {str(path)!r} holds no fit (it was not written by comat calibrate)")
    if data.get("format") != PROFILE_FORMAT:
        raise ValueError(f"profile {str(path)!r}: format {data.get('format')!r}, expected {PROFILE_FORMAT}")
    return check_fit(data["fit"], str(path), data.get("logs"))
