"""The intervals a calibration profile states (issue 66, "intervals that cover"): each kind covers
what it is for in simulation, a t-interval over robots would not for a team-wide process, the pose
jitter is fitted (not kept on top of the fitted delay), and a profile with an interval of the wrong
kind, or fitted before these kinds, is refused in one line with nothing written."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from comat.calibration.experiments import simulate
from comat.calibration.fit import fit_steps_team
from comat.calibration.intervals import derate_interval, read_fit, spread_interval
from comat.calibration.recovery import level_truth
from comat.cli import main
from comat.measure.stats import block_bootstrap_mean, block_length, t_interval
from comat.reality import resolve_reality


def _holds(rng: np.random.Generator, ticks: int, p: float, run: float) -> np.ndarray:
    """(ticks,) a team's hold indicator: holds start with a probability that gives the share p, and
    last a geometric run of mean ``run`` ticks (1: independent ticks)."""
    out = np.zeros(ticks)
    k = 0
    while k < ticks:
        if rng.random() < p / (p + run * (1 - p)):
            n = rng.geometric(1.0 / run)
            out[k : k + n] = 1.0
            k += n
        else:
            k += 1
    return out


def test_a_team_wide_share_needs_blocks_of_ticks_not_robots():
    """Holds in runs of 5 ticks, seen alike by four robots (each with its own rare freezes too): the
    t-interval over the robots' shares (what profiles wrote before) is as narrow as the freezes and
    misses the truth almost always; the block bootstrap over ticks covers it near 95 % (60 teams of
    900 ticks: measured 5 and 56 of 60)."""
    rng = np.random.default_rng(0)
    t_cover = block_cover = 0
    trials = 60
    for k in range(trials):
        team = _holds(rng, 900, 0.2, 5.0)
        freezes = rng.random((4, team.size)) < 0.006
        robots = np.maximum(team, freezes)  # every robot repeats where the message did not come
        t = t_interval(robots.mean(1))
        t_cover += t["lo"] <= 0.2 <= t["hi"]
        b = block_bootstrap_mean([team], reps=400, seed=k)
        block_cover += b["lo"] <= 0.2 <= b["hi"]
    assert t_cover <= 0.1 * trials
    assert block_cover >= 0.85 * trials, block_cover


def test_the_block_length_follows_the_series_and_the_interval_is_seeded():
    rng = np.random.default_rng(1)
    independent, bursts = _holds(rng, 1800, 0.2, 1.0), _holds(rng, 1800, 0.2, 20.0)
    assert block_length(independent) == 13  # n^(1/3) for independent ticks
    assert block_length(bursts) > 2 * block_length(independent)  # longer where the ticks depend
    a = block_bootstrap_mean([independent, bursts[:700]], reps=300, seed=3)
    assert a == block_bootstrap_mean([independent, bursts[:700]], reps=300, seed=3)
    assert a["lo"] < a["mean"] < a["hi"] and a["n"] == 2500
    flat = block_bootstrap_mean([np.zeros(50)])
    assert flat["lo"] == flat["hi"] == 0.0  # nothing varies: nothing to resample
    with pytest.raises(ValueError, match="series must hold at least one"):
        block_bootstrap_mean([])


def test_the_derate_interval_covers_the_fleets_smallest_cap():
    """Four robots' caps from U(a, 1), some unseen above what they were sent: the order-statistic
    interval covers a in 93-99 % of 2000 draws (censoring only widens it)."""
    rng = np.random.default_rng(2)
    a, covered = 0.85, 0
    for _ in range(2000):
        caps = a + (1 - a) * rng.random(4)
        sent = rng.uniform(0.88, 0.93, 4)  # a cap above what the robot reaches is not seen
        seen = caps < sent
        _, lo, hi = derate_interval(caps[seen], sent[~seen])
        covered += lo <= a <= hi
    assert 0.93 * 2000 <= covered <= 0.99 * 2000, covered
    estimate, lo, hi = derate_interval([0.9], [0.95, 0.97, 0.93])
    assert lo < estimate < 0.9 and hi == pytest.approx(1 - 0.1 / 0.975**0.25)
    assert derate_interval([], [0.93, 0.95]) == (1.0, pytest.approx(1 - 0.07 / 0.025**0.5), 1.0)


def test_the_spread_interval_covers_the_layers_spread_with_each_robots_error_taken_out():
    """Half gain differences s (u_r - u_l) with s = 0.04, read with 0.01 of error each: the chi-square
    interval over four robots, the error's mean square taken out, covers s in at least 93 % of 2000."""
    rng = np.random.default_rng(3)
    s, covered = 0.04, 0
    for _ in range(2000):
        diffs = s * (rng.random(4) - rng.random(4)) + rng.normal(0, 0.01, 4)
        _, lo, hi = spread_interval(diffs, np.full(4, 0.01))
        covered += lo <= s <= hi
    assert covered >= 0.93 * 2000, covered
    assert spread_interval([0.01], [0.001]) == (pytest.approx(float("nan"), nan_ok=True), None, None)


@pytest.mark.parametrize("jitter", [0.0, 0.3])
def test_the_pose_jitter_is_fitted_and_the_lag_no_longer_takes_it(jitter):
    """Nominal's nuisances with a known jitter: the team's share of late ticks comes back within 0.06,
    every robot's delay exactly, and the shared lag within 0.01 s of the robots' mean (a jitter of 0.2
    left unmodelled read as 0.01 s more lag)."""
    config = resolve_reality({"level": "nominal", "pose_delay_jitter_prob": jitter})
    rows, told = fit_steps_team(simulate("steps", config, n=4, seed=4))
    truth = level_truth(config, 4)
    assert abs(told.mean() - jitter) <= 0.06 and told.size > 300
    assert [r["delay_ticks"] for r in rows] == truth["delay"].tolist()
    assert abs(rows[0]["tau_s"] - truth["tau"].mean()) <= 0.01


def _old_profile(path) -> None:
    """A profile as comat calibrate wrote it before format 2: holds with a t-interval over robots."""
    fit = [
        {"name": "pose_hold_prob", "estimate": 0.33, "lo": 0.32, "hi": 0.34, "interval": "t95", "robots": 4},
        {"name": "wheel_gain_spread", "estimate": 0.03, "lo": 0.01, "hi": 0.04, "interval": "bootstrap95"},
    ]
    data = {"reality": {"level": "nominal", "pose_hold_prob": 0.33}, "fit": fit, "logs": ["cal/calib_still.npy"]}
    path.write_text(yaml.safe_dump(data))


def test_a_profile_fitted_before_these_intervals_is_refused_by_name(tmp_path, capsys):
    """Everywhere a profile is read (train, eval, replay through resolve_reality; calibrate's
    --simulate and --truth): one line naming the profile and the command that regenerates it from its
    own logs; exit 2; nothing written."""
    old = tmp_path / "old.yaml"
    _old_profile(old)
    with pytest.raises(ValueError, match="fitted by an earlier comat calibrate") as err:
        resolve_reality(str(old))
    assert "comat calibrate cal/calib_still.npy --out" in str(err.value) and "\n" not in str(err.value)
    out = tmp_path / "logs"
    assert main(["calibrate", "--simulate", str(old), "--out", str(out)]) == 2
    message = capsys.readouterr().err
    assert message.count("\n") == 1 and "old.yaml" in message and not out.exists()


def test_a_profile_with_an_interval_of_the_wrong_kind_is_refused(tmp_path, capsys):
    """A format-2 profile whose holds carry a t-interval over robots (hand-edited, or an old row
    pasted in): read_fit and comat calibrate --truth refuse it in one line, naming the parameter, the
    kind found and the kind it must be; nothing is written."""
    from comat.reality.config import PROFILE_FORMAT

    bad = tmp_path / "bad.yaml"
    _old_profile(bad)
    data = yaml.safe_load(bad.read_text())
    data["format"] = PROFILE_FORMAT
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ValueError, match="pose_hold_prob's interval is 't95', but its kind is 'block95'"):
        read_fit(bad)
    np.save(tmp_path / "calib_still.npy", simulate("still", "nominal", n=2))
    target = tmp_path / "p.yaml"
    assert main(["calibrate", str(tmp_path / "calib_still.npy"), "--truth", str(bad), "--out", str(target)]) == 2
    message = capsys.readouterr().err
    assert message.count("\n") == 1 and "'block95'" in message and not target.exists()
