"""The reality layer (comat.reality): off equals the ideal world bit for bit; levels are
deterministic per seed; each component shows its effect in isolation; judging stays on true poses."""

from __future__ import annotations

import contextlib
import hashlib

import numpy as np
import pytest

from comat import constants as C
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams
from comat.envs import core as env_core
from comat.envs import make_env, make_vec_env
from comat.reality import LEVELS, SOURCES, RealityConfig, RealityLayer, resolve_reality
from comat.reality.paths import CommandPath
from comat.sim.kinematics import uni_to_diff
from comat.sim.layout import team_layout

PROFILE = C.DEFAULT_PROFILE


# -- off == today, bit for bit -------------------------------------------------------------------------
def _vec_digest(env_id: str, tier: str, reality=None, seed: int = 11, forced_layer: bool = False) -> str:
    """Hash of a whole vector-env rollout: 3 U_train teams, 75 steps of 3 ticks (HMT's 70-step
    horizon passes: autoreset included), fixed actions; observations, graphs, rewards, flags,
    states, true poses and every episode metric. ``forced_layer``: a reality layer at ``off`` is
    built anyway (the env builds none for an ``off`` config), so every one of its code paths runs."""
    opts = {"seed": seed, "tier": tier, "coalitions": "train", "ticks_per_step": 3}
    if reality is not None:
        opts["reality"] = reality
    with _off_layer_forced(forced_layer):
        env = make_vec_env(env_id, 3, **opts)
        obs, info = env.reset()
    h = hashlib.sha256()
    h.update(obs.tobytes())
    h.update(info["agent_mask"].tobytes())
    h.update(env.graph()["edge_attr"].tobytes())
    arng = np.random.default_rng(5)
    for _ in range(75):
        a = arng.integers(0, 5, (3, env.max_robots))
        obs, r, te, tr, info = env.step(a)
        for x in (obs, r, te, tr, env.state()):
            h.update(np.ascontiguousarray(x).tobytes())
        h.update(env.core.safe.world.pose_view.tobytes())
        if "_episode" in info:
            for k in sorted(info["episode"]):
                h.update(info["episode"][k].tobytes())
    for b in range(3):
        for _, v in sorted(env.core.episode_metrics(b).items()):
            h.update(np.float64(v).tobytes())
    env.close()
    return h.hexdigest()[:16]


@contextlib.contextmanager
def _off_layer_forced(on: bool):
    """While on, the envs' SafeTeams put a reality layer whose every component is off between the
    world and the decisions (the envs build them lazily, at the first reset)."""
    if not on:
        yield
        return

    class Forced(SafeTeams):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            assert self.reality.is_off
            self.reality = RealityLayer(RealityConfig(), self.world.profile, self.world.layout, 0)

    real = env_core.SafeTeams
    env_core.SafeTeams = Forced
    try:
        yield
    finally:
        env_core.SafeTeams = real


def _pz_digest(env_id: str, tier: str, reality=None, forced_layer: bool = False) -> str:
    """Hash of a PettingZoo-env rollout (8 steps of 6 ticks, seed 3, fixed actions)."""
    opts = {"tier": tier, "ticks_per_step": 6}
    if reality is not None:
        opts["reality"] = reality
    with _off_layer_forced(forced_layer):
        env = make_env(env_id, **opts)
        obs, _ = env.reset(seed=3)
    h = hashlib.sha256()
    arng = np.random.default_rng(9)
    for _ in range(8):
        for a in sorted(obs):
            h.update(obs[a].tobytes())
        obs, rew, _, _, _ = env.step({a: int(arng.integers(5)) for a in env.agents})
        h.update(np.float64(sum(rew.values())).tobytes())
        if not env.agents:
            break
    h.update(env.core.safe.world.pose_view.tobytes())
    return h.hexdigest()[:16]


@pytest.mark.parametrize("env_id,tier", [(e, t) for e in ("hmt_v0", "pcp_v0") for t in ("unicycle", "wheels")])
def test_off_equals_the_world_before_the_layer_bit_for_bit(env_id, tier):
    """Both worlds run here, in one process: a digest recorded on one CPU does not hold on another
    (MuJoCo's and numba's floating point follow the CPU's instruction set; docs/contributing.md)."""
    vec = _vec_digest(env_id, tier)  # the identity layer (IdentityReality): nothing between
    assert _vec_digest(env_id, tier, "off") == vec
    assert _vec_digest(env_id, tier, forced_layer=True) == vec  # the layer's every path, at zero
    pz = _pz_digest(env_id, tier)
    assert _pz_digest(env_id, tier, RealityConfig()) == pz
    assert _pz_digest(env_id, tier, forced_layer=True) == pz
    # all components at zero is the ideal world too, whatever the level's name says
    assert RealityConfig(level="nominal", **{k: v for k, v in LEVELS["off"].items()}).is_off


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
@pytest.mark.parametrize("loop", ["comat", "robotarium_legacy"])
def test_identity_layer_ticks_as_the_bare_world_bit_for_bit(tier, loop):
    """At ``off`` the layer is :class:`IdentityReality` and a tick through it is the bare world's:
    the commands each tick's loop sent, replayed on a world with no layer, filter or loop around it,
    give the same poses and events bit for bit (90 ticks of 3 teams swapping places on a circle,
    the barrier intervening). The comat loop's filtered point velocities also replay
    through :meth:`World.step_points` (the fused conversion) to the same poses."""
    from comat.reality import IdentityReality
    from comat.sim import BatchWorld

    sizes = (3, 4, 2)
    teams = SafeTeams(sizes, SimConfig(tier=tier), SafetyConfig(loop=loop), reality=RealityConfig())
    assert isinstance(teams.reality, IdentityReality)
    bare, by_points = BatchWorld(sizes, SimConfig(tier=tier)), BatchWorld(sizes, SimConfig(tier=tier))
    angles = np.concatenate([np.arange(n) * 2 * np.pi / n for n in sizes])
    start = np.column_stack([0.3 * np.cos(angles), 0.3 * np.sin(angles), angles + np.pi])  # on a circle, inward
    for world in (teams, bare, by_points):
        world.reset(start)
    sent, filtered = [], []
    actuate = teams.reality.actuate
    teams.reality.actuate = lambda dxu: sent.append(dxu.copy()) or actuate(dxu)
    teams.tick_observers.append(lambda nominal, out, events, info: filtered.append(out.copy()))
    d = teams.safety_config.projection_distance_m
    for _ in range(90):
        dxi = 0.4 * (-start[:, :2] - teams.measured_points)  # to the antipode, through each other
        events = teams.tick(dxi)[0] if loop == "comat" else teams.tick_deployed(dxi)[0]
        bare_events = bare.advance(sent[-1], events.actuator)
        for field in ("collision", "boundary", "robot_contact", "wall_contact"):
            np.testing.assert_array_equal(getattr(events, field), getattr(bare_events, field))
        np.testing.assert_array_equal(teams.world.pose_view, bare.pose_view)
        if loop == "comat":
            by_points.step_points(filtered[-1], d)
            np.testing.assert_array_equal(teams.world.pose_view, by_points.pose_view)
    assert teams.interventions.sum() > 0  # the crossing engages the barrier: its answers are what replays


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
def test_levels_are_deterministic_per_seed_and_change_the_rollout(tier):
    for level in ("nominal", "stress"):
        a = _vec_digest("pcp_v0", tier, level)
        assert a == _vec_digest("pcp_v0", tier, level)
        assert a != _vec_digest("pcp_v0", tier)
        assert a != _vec_digest("pcp_v0", tier, level, seed=12)
    assert _pz_digest("hmt_v0", tier, "nominal") == _pz_digest("hmt_v0", tier, "nominal")


def test_levels_draw_the_same_teams_and_starts():
    """The layer's keys come from the env generator without advancing it: paired episodes."""
    off = make_vec_env("hmt_v0", 4, seed=3, tier="unicycle", ticks_per_step=2)
    nom = make_vec_env("hmt_v0", 4, seed=3, tier="unicycle", ticks_per_step=2, reality="nominal")
    off.reset()
    nom.reset()
    assert [t.to_dict() for t in off.teams()] == [t.to_dict() for t in nom.teams()]
    start_off, start_nom = off.core.poses(), nom.core.poses()
    err = np.abs(start_nom - start_off)[off.core.mask]
    assert 0 < err[:, :2].max() <= 0.05 + 1e-12 and err[:, 2].max() > 0
    assert (np.minimum(err[:, 2], 2 * np.pi - err[:, 2]) <= 0.2 + 1e-12).all()


# -- config and validation -----------------------------------------------------------------------------
def test_levels_carry_their_sources_and_overrides():
    assert set(SOURCES) == set(LEVELS["off"])
    assert all(mark in ("measured", "derived", "assumed") for mark, _ in SOURCES.values())
    c = resolve_reality({"level": "nominal", "pose_delay_ticks": 2})
    assert c.pose_delay_ticks == 2 and c.pose_noise_xy_m == LEVELS["nominal"]["pose_noise_xy_m"]
    assert c.overrides() == {"pose_delay_ticks": 2}
    alone = resolve_reality({"command_loss_prob": 0.1})  # no level: that component alone
    assert alone.level == "off" and not alone.is_off and alone.pose_noise_xy_m == 0
    assert RealityConfig(level="stress").command_brake_after_ticks == 15


@pytest.mark.parametrize(
    "value,match",
    [
        ({"pose_delay_ticks": -1}, r"RealityConfig.pose_delay_ticks must be an integer >= 0.*got -1"),
        ({"pose_noise_xy_m": -0.1}, r"RealityConfig.pose_noise_xy_m must be a number >= 0, got -0.1"),
        ({"command_loss_prob": 1.5}, r"RealityConfig.command_loss_prob must be a probability in \[0, 1\], got 1.5"),
        ({"pose_hold_prob": -0.01}, r"pose_hold_prob must be a probability in \[0, 1\]"),
        ({"motor_tau_min_s": 0.1, "motor_tau_max_s": 0.05}, r"motor_tau_max_s must be a number >= motor_tau_min_s"),
        ({"bogus_delay": 1}, r"unknown key\(s\) \['bogus_delay'\] for reality; valid keys: \[.*'pose_delay_ticks'"),
        ({"level": "harsh"}, r"RealityConfig.level must be one of \['off', 'nominal', 'stress'\], got 'harsh'"),
        ("harsh", r"reality must be one of \['off', 'nominal', 'stress'\].*got 'harsh'"),
    ],
)
def test_bad_values_get_one_line_errors(value, match):
    with pytest.raises(ValueError, match=match):
        resolve_reality(value)
    with pytest.raises(ValueError, match=match):
        make_vec_env("pcp_v0", 1, tier="unicycle", reality=value)


def test_wrong_types_are_named():
    with pytest.raises(TypeError, match=r"reality.pose_delay_ticks must be int"):
        resolve_reality({"pose_delay_ticks": 1.5})
    with pytest.raises(TypeError, match=r"reality must be one of .* got list"):
        resolve_reality([1])


# -- components in isolation -----------------------------------------------------------------------------
def _layer(n: int = 4, **fields) -> RealityLayer:
    layer = RealityLayer(RealityConfig(**fields), PROFILE, team_layout((n,)), seed=1)
    poses = np.column_stack([np.linspace(-1, 1, n), np.zeros(n), np.zeros(n)])
    layer.start(poses, np.array([0]), None)
    layer.begin_measuring(poses, np.array([0]))
    return layer


def _ramp(t: int, n: int) -> np.ndarray:
    """True poses at tick t: a step in x at tick 5, a ramp in y."""
    p = np.zeros((n, 3))
    p[:, 0] = np.linspace(-1, 1, n) + (0.1 if t >= 5 else 0.0)
    p[:, 1] = 0.01 * t
    return p


@pytest.mark.parametrize("k", [0, 1, 3])
def test_pose_delay_shifts_a_step_by_k_ticks(k):
    layer = _layer(pose_delay_ticks=k)
    seen = []
    for t in range(1, 15):
        layer.actuate(np.zeros((4, 2)))
        layer.observe(_ramp(t, 4))
        seen.append(layer.measured.copy())
    for i, t in enumerate(range(1, 15)):
        np.testing.assert_array_equal(seen[i], _ramp(max(t - k, 0), 4))


def test_pose_delay_spread_draws_per_robot_from_the_binomial():
    layer = RealityLayer(
        RealityConfig(pose_delay_spread_ticks=2, pose_per_robot=True), PROFILE, team_layout((400,)), seed=2
    )
    layer.start(np.zeros((400, 3)), np.array([0]), None)
    counts = np.bincount(layer.pose.delay, minlength=3) / 400
    assert np.allclose(counts, [0.25, 0.5, 0.25], atol=0.07)


def _teams_layer(n_teams: int, size: int, **fields) -> RealityLayer:
    layer = RealityLayer(RealityConfig(**fields), PROFILE, team_layout((size,) * n_teams), seed=4)
    layer.start(np.zeros((n_teams * size, 3)), np.arange(n_teams), None)
    layer.begin_measuring(np.zeros((n_teams * size, 3)), np.arange(n_teams))
    return layer


def test_the_pose_message_is_common_to_the_team():
    """One message per tick carries every pose: its age (per episode, binomial across teams) and
    its holds are the team's, not each robot's."""
    layer = _teams_layer(300, 3, pose_delay_spread_ticks=2, pose_hold_prob=0.3)
    delay = layer.pose.delay.reshape(300, 3)
    assert (delay == delay[:, :1]).all()
    assert np.allclose(np.bincount(delay[:, 0], minlength=3) / 300, [0.25, 0.5, 0.25], atol=0.08)
    held = []
    for t in range(1, 40):
        layer.actuate(np.zeros((900, 2)))
        before = layer.measured.copy()
        layer.observe(_ramp(t, 900))
        held.append((layer.measured == before).all(axis=1).reshape(300, 3))
    held = np.array(held)
    assert (held == held[..., :1]).all() and abs(held.mean() - 0.3) < 0.03


def test_jitter_makes_some_ticks_one_older():
    """Tick to tick, the message is sometimes one tick older than the episode's delay, for the whole team."""
    layer = _teams_layer(200, 2, pose_delay_jitter_prob=0.25)
    assert layer.config.pose_delay_max_ticks == 1 and (layer.pose.delay == 0).all()
    ages = []
    for t in range(1, 30):
        layer.actuate(np.zeros((400, 2)))
        layer.observe(_ramp(t, 400))
        ages.append(t - np.rint(layer.measured[:, 1] / 0.01).reshape(200, 2))
    ages = np.array(ages)
    assert set(np.unique(ages)) == {0, 1} and (ages == ages[..., :1]).all()
    assert abs((ages == 1).mean() - 0.25) < 0.03


def test_a_missed_tick_sends_nothing_and_a_stall_brakes_the_team():
    """An overrun: no command that tick (the last stays in force) and the next pose read is stale;
    a stall longer than 0.5 s: every robot of the team brakes, and the robots of other teams not."""
    layer = _teams_layer(400, 2, script_miss_prob=0.1, pose_noise_xy_m=1e-3)
    missed = []
    for t in range(1, 60):
        cmd = np.full((800, 2), [0.1, 0.0]) if t < 30 else np.full((800, 2), [0.05, 0.0])
        out = layer.actuate(cmd)
        missed.append(layer.missed.copy())
        assert np.array_equal(out[~layer.missed & (t < 30)], cmd[~layer.missed & (t < 30)])
        layer.observe(_ramp(t, 800))
    missed = np.array(missed).reshape(-1, 400, 2)
    assert (missed == missed[..., :1]).all() and abs(missed.mean() - 0.1) < 0.01
    stall = _teams_layer(50, 3, script_stall_prob=1.0, script_stall_mean_ticks=1000.0)
    for t in range(1, 25):
        out = stall.actuate(np.full((150, 2), [0.1, 0.0]))
        stall.observe(np.zeros((150, 3)))
    assert stall.missed.all() and (out == 0).all()  # 24 ticks without a command: past the 15-tick brake
    calm = _teams_layer(50, 3, script_stall_prob=0.0, script_miss_prob=1e-9)
    assert (calm.actuate(np.full((150, 2), [0.1, 0.0])) == 0.1 * np.array([1, 0])).all()


def test_the_start_error_is_radial():
    layer = RealityLayer(RealityConfig(start_xy_m=0.05, start_theta_rad=0.2), PROFILE, team_layout((1,) * 3000), seed=1)
    poses = np.column_stack([np.tile([0.0, 0.0], (3000, 1)), np.zeros(3000)])
    out = layer.start(poses, np.arange(3000), None)
    r = np.hypot(out[:, 0], out[:, 1])
    assert r.max() <= 0.05 + 1e-12 and r.max() > 0.049
    assert abs((r < 0.05 / np.sqrt(2)).mean() - 0.5) < 0.03  # uniform in the disc: half the area inside r/√2
    assert np.abs(out[:, 2]).max() <= 0.2 + 1e-12


def test_a_frozen_pose_repeats_exactly_while_the_robot_moves():
    layer = _layer(pose_freeze_prob=1.0, pose_freeze_mean_ticks=1000.0, pose_noise_xy_m=0.01)
    first = layer.measured.copy()
    for t in range(1, 40):
        layer.actuate(np.zeros((4, 2)))
        layer.observe(_ramp(t, 4))
        np.testing.assert_array_equal(layer.measured, first)
    layer = _layer(pose_freeze_prob=0.05, pose_freeze_mean_ticks=3.0, pose_freeze_max_ticks=5)
    same, prev = 0, layer.measured.copy()
    for t in range(1, 400):
        layer.actuate(np.zeros((4, 2)))
        layer.observe(_ramp(t, 4))
        same += int((layer.measured == prev).all(1).sum())
        prev = layer.measured.copy()
    assert 0.05 < same / (399 * 4) < 0.3  # ~ p·mean/(1 + p·mean) of ticks frozen


def test_pose_noise_and_bias_have_the_configured_sd():
    n = 2000
    layer = RealityLayer(
        RealityConfig(pose_noise_xy_m=0.004, pose_noise_theta_rad=0.02, pose_bias_xy_m=0.003),
        PROFILE,
        team_layout((n,)),
        seed=4,
    )
    true = np.zeros((n, 3))
    layer.start(true, np.array([0]), None)
    layer.begin_measuring(true, np.array([0]))
    errs = []
    for _ in range(20):
        layer.actuate(np.zeros((n, 2)))
        layer.observe(true)
        errs.append(layer.measured - true)
    e = np.stack(errs)  # (T, R, 3)
    bias = layer.pose.bias
    np.testing.assert_allclose(bias.std(), 0.003, rtol=0.1)
    np.testing.assert_allclose((e[..., :2] - bias).std(), 0.004, rtol=0.05)
    np.testing.assert_allclose(e[..., 2].std(), 0.02, rtol=0.05)
    assert abs((e[..., :2] - bias).mean()) < 2e-4


@pytest.mark.parametrize("k", [1, 2])
def test_command_delay_shifts_a_step_by_k_ticks(k):
    layer = _layer(n=2, command_delay_ticks=k)
    cmd = np.array([[0.1, 0.5], [0.05, -1.0]])
    out = []
    for t in range(8):
        out.append(layer.actuate(cmd if t >= 2 else np.zeros((2, 2))))
        layer.observe(np.zeros((2, 3)))
    for t in range(8):
        np.testing.assert_array_equal(out[t], cmd if t >= 2 + k else 0.0)


def test_a_lost_command_is_held_then_braked_after_half_a_second():
    path = CommandPath(RealityConfig(command_loss_prob=0.5, command_loss_mean_ticks=1.0), 1)
    path.begin(np.array([0]), np.zeros((1, 0)))
    keep, lose = np.array([[0.99, 0.5]]), np.array([[0.0, 0.5]])
    a = np.array([[0.1, 0.3]])
    assert np.array_equal(path.update(a, np.array([0]), keep), a)
    out = [path.update(np.array([[0.2, -0.1]]), np.array([t]), lose) for t in range(1, 21)]
    brake = RealityConfig().command_brake_after_ticks
    assert brake == 15  # 0.5 s expires during the 15th lost tick of 0.033 s
    for i, o in enumerate(out, start=1):
        np.testing.assert_array_equal(o, a if i < brake else 0.0)
    new = np.array([[0.05, 0.0]])
    np.testing.assert_array_equal(path.update(new, np.array([21]), keep), new)  # the next command drives again


def test_dead_zone_command_does_not_move_the_wheel():
    layer = _layer(n=2, motor_dead_zone_radps=1.9)
    r = PROFILE.wheel_radius_m
    dxu = np.array([[1.5 * r, 0.0], [2.5 * r, 0.0]])  # both wheels at 1.5 and 2.5 rad/s
    for _ in range(5):
        out = layer.actuate(dxu)
        layer.observe(np.zeros((2, 3)))
    np.testing.assert_array_equal(out[0], 0.0)
    np.testing.assert_allclose(out[1], dxu[1], rtol=1e-12)


def test_motor_lag_is_a_first_order_rise_and_the_slew_is_limited():
    tau = 0.06
    layer = _layer(n=1, motor_tau_min_s=tau, motor_tau_max_s=tau)
    dxu = np.array([[0.1, 0.0]])
    target = uni_to_diff(dxu, PROFILE)[0, 0]
    speeds = []
    for _ in range(10):
        speeds.append(uni_to_diff(layer.actuate(dxu), PROFILE)[0, 0])
        layer.observe(np.zeros((1, 3)))
    k = np.arange(1, 11)
    np.testing.assert_allclose(speeds, target * (1 - np.exp(-k * C.CONTROL_DT_S / tau)), rtol=1e-9)
    layer = _layer(n=1, motor_accel_limit_radps2=200.0)
    step = 200.0 * C.CONTROL_DT_S
    first = uni_to_diff(layer.actuate(np.array([[0.2, 0.0]])), PROFILE)[0]
    np.testing.assert_allclose(first, [step, step], rtol=1e-12)


def test_gain_mismatch_curves_an_open_loop_straight_line():
    """A constant straight command through mismatched wheels turns the real (MuJoCo) robot."""
    for spread, turns in ((0.0, False), (0.07, True)):
        teams = SafeTeams(
            [1],
            SimConfig(tier="unicycle"),
            reality=RealityConfig(wheel_gain_spread=spread, pose_noise_xy_m=1e-9),
            batched=False,
        )
        teams.reset(np.array([[-1.0, 0.0, 0.0]]))
        layer = teams.reality
        g = layer.motors.gain[0]
        assert (np.abs(g - 1) <= spread).all() and (g[0] != g[1]) == turns
        if turns:
            layer.motors.gain[0] = [1 - spread, 1 + spread]  # the widest mismatch the range allows
        for _ in range(60):
            teams.world.advance(layer.actuate(np.array([[0.15, 0.0]])), np.zeros(1, bool))
            layer.observe(teams.world.pose_view)
        g = layer.motors.gain[0]
        predicted = 60 * C.CONTROL_DT_S * 0.15 * (g[1] - g[0]) / PROFILE.base_length_m  # r·Δφ̇ / l
        if turns:
            assert abs(predicted) > 0.1
            np.testing.assert_allclose(teams.poses[0, 2], predicted, rtol=0.02)
        else:
            assert abs(teams.poses[0, 2]) < 1e-9 and teams.poses[0, 0] > -0.75


def test_a_failed_motor_runs_at_its_fraction_and_is_reported():
    layer = _layer(n=3, fault_prob=1.0, fault_speed_fraction=0.25, fault_start_min_s=0.1, fault_start_max_s=0.1)
    dxu = np.full((3, 2), [0.1, 0.2])
    want = uni_to_diff(dxu, PROFILE)
    for t in range(6):
        got = uni_to_diff(layer.actuate(dxu), PROFILE)
        faulty = layer.speed_fraction < 1
        if t < 3:  # 0.1 s = tick 3
            assert not faulty.any()
            np.testing.assert_allclose(got, want, rtol=1e-12)
        else:
            assert faulty.sum() == 1
            np.testing.assert_allclose(got[faulty], 0.25 * want[faulty], rtol=1e-12)
            np.testing.assert_allclose(got[~faulty], want[~faulty], rtol=1e-12)
        layer.observe(np.zeros((3, 3)))
    assert layer.config.fault_known is False


def test_start_error_within_bounds_and_the_world_starts_there():
    teams = SafeTeams([6, 3], SimConfig(tier="unicycle"), reality=RealityConfig(start_xy_m=0.05, start_theta_rad=0.2))
    req = np.column_stack([np.linspace(-1.2, 1.2, 9), np.tile([-0.3, 0.3, 0.0], 3), np.zeros(9)])
    teams.reset(req)
    err = teams.poses - req
    assert (np.abs(err[:, :2]) <= 0.05 + 1e-12).all() and (np.abs(err[:, 2]) <= 0.2 + 1e-12).all()
    assert np.abs(err).min(0)[:2].max() < 0.05 and np.abs(err[:, :2]).max() > 0.01


# -- decide on measured, judge on true -------------------------------------------------------------------
def test_the_filter_decides_on_measured_poses_and_collisions_are_judged_on_true_ones():
    """Two robots driven head-on: at off the filter keeps them apart; with a measurement that
    shows them 1 m apart sideways, it lets them collide, and the contacts and Robotarium
    collisions are counted from the true poses."""
    start = np.array([[-0.3, 0.0, 0.0], [0.3, 0.0, np.pi]])
    dxi = np.array([[0.2, 0.0], [-0.2, 0.0]])
    counts = {}
    for name, reality in (("off", None), ("biased", RealityConfig(pose_bias_xy_m=1e-6))):
        teams = SafeTeams([2], SimConfig(tier="unicycle"), reality=reality)
        teams.reset(start)
        if reality is not None:  # a fixed bias instead of the drawn one: robot 0 seen 0.5 m up, robot 1 down
            teams.reality.pose.bias[:] = [[0.0, 0.5], [0.0, -0.5]]
            teams.reality.begin_measuring(teams.world.pose_view, np.array([0]))
        contact = pairs = 0
        for _ in range(120):
            ev, _ = teams.tick(dxi)
            contact += int(ev.robot_contact.any())
            pairs += int(ev.collision_pairs.sum())
        counts[name] = (contact, pairs, teams.poses.copy(), teams.measured_poses.copy())
    assert counts["off"][:2] == (0, 0)
    contact, pairs, true, seen = counts["biased"]
    assert contact > 0 and pairs > 0
    np.testing.assert_allclose(seen[:, 1] - true[:, 1], [0.5, -0.5], atol=1e-4)


def test_env_observes_measured_and_judges_true_poses():
    env = make_vec_env("hmt_v0", 2, seed=0, tier="unicycle", ticks_per_step=4, reality={"pose_bias_xy_m": 0.2})
    obs, _ = env.reset()
    core = env.core
    for _ in range(3):
        obs, *_ = env.step(np.zeros((2, env.max_robots), np.int64))
    mask = core.mask
    np.testing.assert_array_equal(core.poses()[mask], core.safe.world.pose_view[core._flat[mask]])
    seen = core.measured_poses()[mask]
    np.testing.assert_allclose(obs[..., :2][mask], seen[:, :2])  # observations: measured x, y
    off = np.abs(seen[:, :2] - core.poses()[mask][:, :2])
    assert off.max() > 0.05  # the bias is there ...
    np.testing.assert_allclose(seen[:, :2] - core.poses()[mask][:, :2], core.safe.reality.pose.bias, atol=1e-12)


def test_teams_that_keep_their_size_keep_their_layer_state_across_a_relayout():
    teams = SafeTeams([3, 4], SimConfig(tier="unicycle"), reality=RealityConfig(level="nominal"))
    starts = np.column_stack([np.linspace(-1.2, 1.2, 7), np.zeros(7), np.zeros(7)])
    teams.reset(starts)
    for _ in range(5):
        teams.tick(np.full((7, 2), [0.05, 0.0]))
    layer = teams.reality
    before = (
        layer.keys[:3].copy(),
        layer.ticks[:3].copy(),
        layer.pose.measured[:3].copy(),
        layer.motors.speed[:3].copy(),
    )
    teams.set_team_sizes([3, 5])
    new = np.concatenate([teams.poses[:3], np.column_stack([np.linspace(-1.2, 1.2, 5), np.full(5, 0.5), np.zeros(5)])])
    teams.reset(new, teams=[1])
    after = (layer.keys[:3], layer.ticks[:3], layer.pose.measured[:3], layer.motors.speed[:3])
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
    assert (layer.ticks[3:] == 0).all() and layer.keys.shape == (8,)
    teams.tick(np.zeros((8, 2)))


@pytest.mark.parametrize(
    "field, value", [("motor_tau_max_s", 0.2), ("pose_delay_spread_ticks", 3), ("command_delay_spread_ticks", 3)]
)
def test_a_range_from_zero_switches_its_component_on(field, value):
    """A lag drawn from [0, motor_tau_max_s] (or a delay from [0, spread] ticks) is on: with only
    that field set the layer runs and moves the robots differently (it once counted as off: the
    motor-lag sweep of 2026-12-03/04 measured the ideal world)."""
    config = resolve_reality({"level": "off", field: value})
    assert not config.is_off

    def poses(reality):
        env = make_env("pcp_v0", coalitions="test", tier="unicycle", reality=reality)
        env.reset(seed=3)
        for _ in range(4):
            env.step({a: 1 for a in env.agents})
        return env.core.poses()[0]

    assert np.abs(poses(config) - poses("off")).max() > 1e-3


def test_the_docs_levels_table_is_the_codes():
    """docs/reality.md's table of levels is :func:`comat.reality.config.levels_markdown`: one source
    for every field's values, marks and sources."""
    from pathlib import Path

    from comat.reality.config import levels_markdown

    page = (Path(__file__).resolve().parents[1] / "docs" / "reality.md").read_text()
    assert levels_markdown() in page
