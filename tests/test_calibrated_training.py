"""Calibration reaches training (issue 66): ``reality=PROFILE.yaml reality_draw=intervals`` draws each
episode's identified layer parameters from the profile's intervals (comat.reality.randomize).

Same seed, same draws; every draw inside its interval and applied to the layer; each episode draws
afresh; the point default unchanged bit for bit; the run records the profile's path, hash and the
draw mode; a profile with a bad interval is refused in one line, exit 2, nothing written."""

import dataclasses
import hashlib
import pickle

import numpy as np
import pytest
import yaml

from comat.cli import main
from comat.envs import make_vec_env
from comat.reality import resolve_reality
from comat.reality.config import PROFILE_FORMAT
from comat.reality.randomize import CalibratedReality, calibrated, profile_intervals, profile_sha256
from comat.rl import RunConfig, apply_overrides, load_preset, resolve

POINT = {
    "level": "nominal",
    "pose_delay_ticks": 2,
    "pose_delay_spread_ticks": 1,
    "pose_delay_jitter_prob": 0.17,
    "pose_hold_prob": 0.31,
    "pose_noise_xy_m": 0.001,
    "pose_noise_theta_rad": 0.01,
    "command_delay_ticks": 0,
    "command_delay_spread_ticks": 0,
    "motor_tau_min_s": 0.05,
    "motor_tau_max_s": 0.065,
    "motor_dead_zone_radps": 1.9,
    "wheel_gain_mean": 0.97,
    "wheel_gain_spread": 0.04,
    "top_speed_derate_min": 0.9,
}
FIT = [  # as comat calibrate writes them (name, estimate, lo, hi, interval kind)
    ("pose_delay_ticks", 2, 2, 3, "range"),
    ("pose_delay_jitter_prob", 0.17, 0.15, 0.20, "block95"),
    ("motor_tau_s", 0.0575, 0.049, 0.068, "t95"),
    ("speed_gain", 0.97, 0.93, 1.01, "t95"),
    ("turn_gain", 0.99, 0.98, 1.0, "t95"),
    ("top_speed_fraction", 0.91, 0.87, 0.94, "range"),
    ("top_speed_derate_min", 0.9, 0.57, 1.0, "order95"),
    ("wheel_gain_spread", 0.04, 0.005, 0.17, "chi2_95"),
    ("pose_noise_xy_m", 0.001, 0.0009, 0.0011, "t95"),
    ("pose_noise_theta_rad", 0.01, 0.009, 0.011, "t95"),
    ("pose_hold_prob", 0.31, 0.29, 0.34, "block95"),
    ("motor_dead_zone_radps", 1.9, 1.85, 1.93, "t95"),
    ("loop_tick_s", 0.033, 0.033, 0.033, "t95_runs"),
    ("pose_bias_xy_m", None, None, None, None),
]


def _profile(path, fit=FIT, point=POINT):
    rows = [{"name": n, "estimate": e, "lo": lo, "hi": hi, "interval": k} for n, e, lo, hi, k in fit]
    path.write_text(yaml.safe_dump({"format": PROFILE_FORMAT, "reality": dict(point), "fit": rows}))
    return str(path)


def _env(reality, seed=3, n=4):
    env = make_vec_env("hmt_v0", n, seed=seed, reality=reality)
    env.reset()
    return env


def _trajectory(env, steps=6) -> str:
    rng, h = np.random.default_rng(0), hashlib.sha256()
    for _ in range(steps):
        obs, rewards, *_ = env.step(rng.integers(0, 5, size=(env.num_envs, env.max_robots)))
        h.update(obs.tobytes())
        h.update(rewards.tobytes())
        h.update(env.core.poses().tobytes())
    return h.hexdigest()


def _calibrated(path) -> CalibratedReality:
    return calibrated(resolve_reality(path), profile_intervals(path), path, profile_sha256(path))


def _team_draws(env) -> dict[str, np.ndarray]:
    """name -> (B,) each team's draw (its first robot's)."""
    layer = env.core.safe.reality
    return {name: v[layer._first].copy() for name, v in layer.drawn.items()}


def test_intervals_are_read_mapped_and_the_layer_is_built_for_their_widest(tmp_path):
    path = _profile(tmp_path / "p.yaml")
    got = profile_intervals(path)
    # range rows and rows not in the layer are not drawn; the lag's interval becomes a shift of its range
    assert set(got) == {
        "pose_delay_jitter_prob",
        "pose_hold_prob",
        "pose_noise_xy_m",
        "pose_noise_theta_rad",
        "motor_dead_zone_radps",
        "wheel_gain_mean",
        "wheel_gain_spread",
        "top_speed_derate_min",
        "motor_tau_shift_s",
    }
    assert got["motor_tau_shift_s"] == pytest.approx((0.049 - 0.0575, 0.068 - 0.0575))
    assert got["wheel_gain_mean"] == (0.93, 1.01)
    c = _calibrated(path)
    assert c.point == resolve_reality(path) and c.label == "calibrated"
    assert c.top_speed_derate_min == 0.57 and c.pose_noise_xy_m == 0.0011  # the envelope
    assert c.motor_tau_max_s == pytest.approx(0.065 + 0.068 - 0.0575)
    assert pickle.loads(pickle.dumps(c)) == c  # env worker processes get the same draws


def test_same_seed_same_draws_each_episode_afresh_within_the_intervals_and_applied(tmp_path):
    path = _profile(tmp_path / "p.yaml")
    c = _calibrated(path)
    a, b = _env(c), _env(c)
    first = _team_draws(a)
    assert all(np.array_equal(first[k], v) for k, v in _team_draws(b).items())  # same seed, same draws
    assert _trajectory(a) == _trajectory(b)
    other = _team_draws(_env(c, seed=4))
    assert all(not np.allclose(first[k], other[k]) for k in first)  # another seed, other draws
    seen = {k: [v] for k, v in first.items()}
    for _ in range(4):
        a.reset()
        for k, v in _team_draws(a).items():
            seen[k].append(v)
    for name, values in seen.items():
        v = np.concatenate(values)
        lo, hi = c.intervals[name]
        assert lo <= v.min() and v.max() <= hi, name
        assert np.unique(v).size == v.size, name  # every team and episode draws its own
    # the draws reach the layer's components (each robot has its team's)
    layer = a.core.safe.reality
    drawn = layer.drawn
    assert np.array_equal(layer.motors.dead_zone, drawn["motor_dead_zone_radps"])
    assert np.array_equal(layer.pose.scale[:, 0], drawn["pose_noise_xy_m"])
    assert np.array_equal(layer.pose.scale[:, 2], drawn["pose_noise_theta_rad"])
    cap = layer.motors.cap / layer.profile.max_wheel_velocity_radps
    assert np.all(cap >= drawn["top_speed_derate_min"] - 1e-12)
    gain, spread = layer.motors.gain, drawn["wheel_gain_spread"][:, None]
    assert np.all(np.abs(gain - drawn["wheel_gain_mean"][:, None]) <= spread + 1e-12)


def test_the_point_default_is_unchanged_bit_for_bit(tmp_path):
    """reality=PROFILE (no reality_draw) resolves to the profile's own config; a calibrated layer
    whose intervals are the point values runs the profile's episodes bit for bit (the draws change
    nothing but the drawn values); real intervals change them."""
    path = _profile(tmp_path / "p.yaml")
    point = resolve(apply_overrides(load_preset("quick"), [f"reality={path}"]), "ippo", "hmt", 0)
    assert type(point.reality) is type(resolve_reality(path)) and point.reality == resolve_reality(path)
    assert point.to_dict()["reality_draw"]["mode"] == "point"
    p = resolve_reality(path)
    same = {
        "pose_delay_jitter_prob": (p.pose_delay_jitter_prob,) * 2,
        "pose_hold_prob": (p.pose_hold_prob,) * 2,
        "pose_noise_xy_m": (p.pose_noise_xy_m,) * 2,
        "pose_noise_theta_rad": (p.pose_noise_theta_rad,) * 2,
        "motor_dead_zone_radps": (p.motor_dead_zone_radps,) * 2,
        "wheel_gain_mean": (p.wheel_gain_mean,) * 2,
        "wheel_gain_spread": (p.wheel_gain_spread,) * 2,
        "top_speed_derate_min": (p.top_speed_derate_min,) * 2,
        "motor_tau_shift_s": (0.0, 0.0),
    }
    reference = _trajectory(_env(path))
    assert _trajectory(_env(calibrated(p, same, path, "x"))) == reference
    assert _trajectory(_env(_calibrated(path))) != reference


def test_the_run_records_the_profile_path_hash_and_mode_and_loads_back(tmp_path):
    path = _profile(tmp_path / "p.yaml")
    config = resolve(
        apply_overrides(load_preset("quick"), [f"reality={path}", "reality_draw=intervals"]), "ippo", "hmt", 0
    )
    assert isinstance(config.reality, CalibratedReality)
    stored = config.to_dict()
    record = stored["reality_draw"]
    assert record["mode"] == "intervals" and record["profile"] == path
    assert record["sha256"] == hashlib.sha256((tmp_path / "p.yaml").read_bytes()).hexdigest()
    assert record["intervals"]["top_speed_derate_min"] == [0.57, 1.0]
    assert stored["reality"] == dataclasses.asdict(resolve_reality(path))  # the profile's point values
    again = RunConfig.from_dict(yaml.safe_load(yaml.safe_dump(stored)))  # config.yaml round trip
    assert again == config and again.reality.intervals == config.reality.intervals
    plain = resolve(load_preset("quick"), "ippo", "hmt", 0)
    assert "reality_draw" not in plain.to_dict() and RunConfig.from_dict(plain.to_dict()) == plain


@pytest.mark.parametrize(
    ("row", "message"),
    [
        (("pose_hold_prob", 0.3, 0.2, 0.4, "sideways95"), "interval kind must be one of"),
        (("pose_hold_prob", 0.3, 0.4, 0.2, "block95"), "lo <= hi, got lo=0.4 > hi=0.2"),
        (("floor_wax", 0.3, 0.2, 0.4, "t95"), "must be a RealityConfig field or a fitted parameter"),
        (("command_loss_prob", 0.01, 0.0, 0.02, "t95"), "must be a field drawn per episode"),
        (("pose_hold_prob", 0.3, 0.2, 0.4, "t95"), "kind must be 'block95', its parameter's, got 't95'"),
    ],
)
def test_a_profile_with_a_bad_interval_is_refused_in_one_line_exit_2_nothing_written(tmp_path, capsys, row, message):
    path = _profile(tmp_path / "bad.yaml", fit=[*FIT[:-3], row])
    with pytest.raises(ValueError, match=message) as err:
        profile_intervals(path)
    assert "\n" not in str(err.value) and "bad.yaml" in str(err.value)
    out = tmp_path / "run"
    argv = ["train", "--algo", "ippo", "--task", "hmt", "--preset", "quick", "--out", str(out)]
    assert main([*argv, f"reality={path}", "reality_draw=intervals"]) == 2
    err_text = capsys.readouterr().err
    assert err_text.count("\n") == 1 and "reality_draw" in err_text and not out.exists()


def test_intervals_need_a_profile_and_the_mode_is_checked():
    with pytest.raises(ValueError, match="needs reality=PROFILE.yaml"):
        resolve(apply_overrides(load_preset("quick"), ["reality=nominal", "reality_draw=intervals"]), "ippo", "hmt", 0)
    with pytest.raises(ValueError, match=r"reality_draw must be one of \['point', 'intervals'\], got 'uniform'"):
        resolve(apply_overrides(load_preset("quick"), ["reality_draw=uniform"]), "ippo", "hmt", 0)
