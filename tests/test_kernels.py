"""The compiled per-tick kernels equal their numpy references bit for bit."""

import numpy as np
import pytest

from comat import constants as C
from comat import kernels
from comat.config import SafetyConfig, SimConfig
from comat.control import (
    CompiledPortableBarrier,
    CompiledRobotWatch,
    _portable_qp,
    portable_settings,
    waypoint_controller,
)
from comat.envs.vector import VectorEnv
from comat.mjcf.scene import compiled_scene
from comat.reality import RealityConfig
from comat.reality import random as rr
from comat.reality.motors import Motors
from comat.reality.paths import CommandPath, PosePath
from comat.safety.constraints import make_layout, row_values
from comat.safety.deployed import PortableBarrier, RobotWatch, cvxopt_qp
from comat.safety.filter import SafetyFilter
from comat.safety.qp import BarrierQP, dense_qp
from comat.sim import BatchWorld
from comat.sim.binding import Binding
from comat.sim.kinematics import limit_to_wheels, si_to_uni, threshold_wheels
from comat.sim.layout import team_layout
from comat.sim.violations import Violations, check_tick
from comat.tasks.hmt import HMT
from comat.tasks.pcp import PCP


def _both(fn):
    """fn() with the kernels and with the numpy references."""
    assert kernels.enabled()
    fast = fn()
    with kernels.reference_path():
        slow = fn()
    return fast, slow


def _equal(fast, slow):
    if isinstance(fast, tuple):
        for f, s in zip(fast, slow, strict=True):
            _equal(f, s)
    else:
        np.testing.assert_array_equal(fast, slow)
        assert np.asarray(fast).dtype == np.asarray(slow).dtype


def _poses(rng, R, spread=1.5):
    p = rng.uniform([-spread, -0.9, -4 * np.pi], [spread, 0.9, 4 * np.pi], (R, 3))
    p[:3, 2] = [np.pi, -np.pi, 2 * np.pi]  # wrap edge cases
    return p


def test_kinematics_twins(rng):
    R = 200
    poses = _poses(rng, R)
    cs = (np.cos(poses[:, 2]), np.sin(poses[:, 2]))
    dxi = rng.normal(0, 0.3, (R, 2))  # about half outside the wheel rhombus
    _equal(*_both(lambda: limit_to_wheels(dxi, poses)))
    _equal(*_both(lambda: limit_to_wheels(dxi, None, 0.03, C.DEFAULT_PROFILE, 0.8, cs)))
    _equal(*_both(lambda: si_to_uni(dxi, poses, 0.025)))
    dxu = np.stack([rng.normal(0, 0.2, R), rng.normal(0, 4, R)], axis=1)
    fast, slow = _both(lambda: threshold_wheels(dxu))
    assert slow[1].any() and not slow[1].all()
    _equal(fast, slow)
    small = dxu * 1e-3
    fast, slow = _both(lambda: threshold_wheels(small))
    assert fast[0] is small and slow[0] is small  # nothing clipped: the input itself
    _equal(fast, slow)
    goals = poses[:, :2] + rng.normal(0, 0.2, (R, 2))
    points = poses[:, :2] + rng.normal(0, 0.01, (R, 2))
    for pts in (None, points):
        _equal(*_both(lambda pts=pts: waypoint_controller(pts, goals, poses, 4.0, 0.025, cs)))


def test_filter_rows_products_feasibility_and_interventions(rng):
    sizes = (3, 1, 5, 2, 4)
    R = sum(sizes)
    cfg = SafetyConfig()
    lay = make_layout(sizes)
    qp = BarrierQP(sizes, cfg, C.DEFAULT_PROFILE)
    points = rng.uniform([-1.7, -1.1], [1.7, 1.1], (R, 2))  # some outside the margin
    points[1] = points[0] + 0.05  # a pair inside the safety distance
    th = rng.uniform(-np.pi, np.pi, R)
    u = rng.normal(0, 0.15, 2 * R)
    fast, slow = _both(lambda: row_values(lay, points, th, cfg, C.DEFAULT_PROFILE))
    for name in ("e", "cos", "sin", "lower", "upper"):
        _equal(getattr(fast, name), getattr(slow, name))
    _equal(*_both(lambda: slow.products(u)))
    _equal(*_both(lambda: slow.data()))
    A = qp.matrix(slow.data())
    _equal(*_both(lambda: qp._product(A, u)))
    ok = _both(lambda: qp.feasible(slow, u))
    assert ok[1].any() and not ok[1].all()
    _equal(*ok)
    poses = np.concatenate([points, th[:, None]], axis=1)
    f = SafetyFilter(sizes, cfg)
    for order in ([3, 0, 4], [1, 2], [4, 3, 2, 1, 0]):
        _equal(*_both(lambda order=order: f._sub_indices(np.array(order))))
    fast, slow = _both(lambda: f._filter(poses, u.reshape(-1, 2)))
    _equal(fast[0], slow[0])
    _equal(fast[1].intervention, slow[1].intervention)
    _equal(fast[1].robot_intervened, slow[1].robot_intervened)
    assert slow[1].robot_intervened.any() and slow[1].status != "skipped"  # the QP stage ran


def test_qp_team_selection(rng):
    for sizes in ((3, 1, 5, 2, 4), tuple(rng.integers(1, 7, 20)), tuple(rng.integers(1, 7, 33))):
        f = SafetyFilter(sizes)
        for density in (0.0, 0.05, 0.2, 0.45, 0.7, 1.0):
            need = rng.random(len(sizes)) < density
            fast, slow = _both(lambda need=need, f=f: f._qp_teams(need))
            _equal(fast, slow)
            assert set(np.flatnonzero(need)) <= set(slow.tolist())


def test_filter_sub_problems(rng):
    """Ticks where a few of many teams need the QP: the sub-problem gather and scatter."""
    sizes = tuple(int(n) for n in rng.integers(2, 6, 20))
    t = team_layout(sizes)

    def run():
        r = np.random.default_rng(1)
        f = SafetyFilter(sizes)
        out = []
        for _ in range(12):
            poses = np.concatenate(
                [np.stack([np.linspace(-1.2, 1.2, n), r.uniform(-0.7, 0.7, n), r.uniform(-3, 3, n)], 1) for n in sizes]
            )
            for b in r.choice(t.n_teams, 3, replace=False):  # in three teams, a pair facing each other
                i = t.offsets[b]
                poses[i, 2], poses[i + 1, 2] = 0.0, np.pi
                poses[i + 1, :2] = poses[i, :2] + [C.SAFETY_DISTANCE_M + 2 * C.PROJECTION_DISTANCE_M + 0.01, 0.0]
            dxi = r.normal(0, 0.01, (t.n_robots, 2))
            dxi[t.offsets[:-1]] = [0.15, 0.0]  # the first robot of every team drives along +x
            safe, info = f._filter(poses, dxi)
            assert info.active_pairs.sum() == 3 and not info.fallback.any()
            out += [safe, info.intervention, info._Au, f._duals.copy()]
        return tuple(out), [key[0] for key in f._qps]

    (fast, fast_keys), (slow, slow_keys) = _both(run)
    assert fast_keys == slow_keys and all(len(k) == 4 for k in slow_keys)  # 3 teams padded to 4 of 20
    _equal(fast, slow)


def test_reality_draws_twin(rng):
    keys = rng.integers(0, 2**63, 300, dtype=np.uint64) * np.uint64(2) + np.uint64(1)
    ticks = rng.integers(0, 10**6, 300)
    fast, slow = _both(lambda: rr.tick_draws(keys, ticks, 5, 5))
    _equal(fast, slow)
    words = rr.bits(keys, ticks, 10)  # the reference is the layer's general draw functions
    _equal(slow, (rr.to_uniform(words[:, :5]), rr.to_normal(words[:, 5:])))


_REALITY_CASES = [
    RealityConfig(level="nominal"),
    RealityConfig(level="stress"),
    RealityConfig(
        level="stress",
        pose_delay_ticks=0,
        pose_delay_spread_ticks=0,
        command_delay_ticks=0,
        command_delay_spread_ticks=0,
        motor_accel_limit_radps2=0.0,
        wheel_disturbance_radps=0.0,
    ),
    RealityConfig(
        level="nominal",
        pose_noise_xy_m=0.0,
        pose_noise_theta_rad=0.0,
        command_loss_prob=0.0,
        pose_freeze_prob=0.2,
        pose_hold_prob=0.0,
        fault_prob=1.0,
        fault_start_min_s=0.0,
        fault_start_max_s=0.1,
    ),
]


@pytest.mark.parametrize("cfg", _REALITY_CASES, ids=["nominal", "stress", "stress-no-delay", "freeze-fault"])
def test_reality_paths_and_motors_twins(cfg, rng):
    """Many ticks of the pose path, command path and motors, state included, with and without kernels."""
    R = 200
    true = np.column_stack([rng.uniform(-1, 1, (R, 2)), rng.uniform(-np.pi, np.pi, R)])
    episode = (
        rng.uniform(size=(R, cfg.pose_delay_spread_ticks)),
        rng.normal(size=(R, 2)),
        rng.uniform(size=(R, cfg.command_delay_spread_ticks)),
        rng.uniform(size=(R, 5)),
        rng.normal(size=(R, 2)),
        rng.integers(0, 20, R),
    )
    ticks = [
        (
            true + rng.normal(0, 0.02, (R, 3)) * t,
            rng.normal(size=(R, 5)),
            rng.uniform(size=(R, 5)),
            np.column_stack([rng.normal(0, 0.15, R), rng.normal(0, 3, R)]) * (1e-3 if t % 7 == 0 else 1.0),
        )
        for t in range(1, 60)
    ]
    ticks[4][0][:4, 2] = [np.pi, -np.pi, 3 * np.pi, 0.0]  # heading wrap edge cases

    def run():
        rows = np.arange(R)
        pose, command, motors = PosePath(cfg, R), CommandPath(cfg, R), Motors(cfg, C.DEFAULT_PROFILE, R)
        pose.begin(rows, true, episode[0], episode[1])
        command.begin(rows, episode[2])
        motors.begin(rows, episode[3], episode[4], episode[5])
        out, froze, lost = [], False, False
        for t, (p, normal, u, dxu) in enumerate(ticks, start=1):
            pose.update(p, np.full(R, t), normal[:, 2:5] if pose.noisy else None, u[:, 2:5])
            executed = motors.update_unicycle(
                command.update(dxu, np.full(R, t - 1), u[:, 0:2]), np.full(R, t - 1), normal[:, 0:2]
            )
            out += [executed] + [getattr(part, a).copy() for part in (pose, command, motors) for a in part.ROW_STATE]
            froze, lost = froze or pose.freeze_left.any(), lost or command.lost_run.any()
        # freezes and losses happened (their lengths are drawn in numpy after the kernels)
        assert froze == (cfg.pose_freeze_prob > 0) and lost == (cfg.command_loss_prob > 0)
        return tuple(out)

    _equal(*_both(run))


def test_checks_and_counters(rng):
    sizes = (4, 2, 6)
    t = team_layout(sizes)
    R = t.n_robots
    violations = [Violations(t.robot_team, t.n_teams) for _ in range(2)]
    for tick in range(30):
        poses = _poses(rng, R, spread=1.7)  # some outside the arena
        poses[1, :2] = poses[0, :2] + 0.05  # a Robotarium collision
        poses[2, 1] = -1.01  # outside the arena
        flags = rng.random((3, R)) < 0.3
        fast, slow = _both(
            lambda p=poses, f=flags: check_tick(p, t.pair_i, t.pair_j, t.pair_team, t.n_teams, f[0], f[1], f[2])
        )
        for name in ("collision", "collision_pairs", "boundary", "actuator", "robot_contact", "wall_contact"):
            _equal(getattr(fast, name), getattr(slow, name))
        assert slow.collision_pairs.sum() >= 1 and slow.boundary.any()
        violations[0].add(fast)
        with kernels.reference_path():
            violations[1].add(slow)
        if tick == 10:
            for v in violations:
                v.reset(np.array([1]))
    for name in (
        "collision_pairs",
        "collision_ticks",
        "boundary_ticks",
        "actuator_ticks",
        "contact_ticks",
        "contact_onsets",
        "wall_ticks",
    ):
        _equal(getattr(violations[0], name), getattr(violations[1], name))


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
def test_bindings_twins(tier, rng):
    n, S = 3, 4
    sim = SimConfig(tier=tier)
    model = compiled_scene(n, tier, sim.profile, sim.resolved_substeps)
    b = Binding(model, n, tier, C.PROFILES[sim.profile])
    qpos = rng.normal(0, 1, (S + 2, model.nq))
    qpos[:, b.qadr[0] + 2] = [np.pi, -np.pi, 3 * np.pi, 0.0, -5.0, 7.0]  # unicycle yaw edge cases
    sims = np.array([0, 2, 3, 5])
    rows = np.arange(S * n).reshape(S, n)[::-1].copy()  # robots scattered in reverse order
    record = rng.choice([0.0, 0.0, 1.0, 2.0], (S, sim.resolved_substeps, model.nsensordata))
    poses, robot, wall = np.zeros((S * n, 3)), np.empty(S * n, bool), np.empty(S * n, bool)
    unicycle = tier == "unicycle"
    kernels.group_read(record, qpos, sims, b.qadr, b.sensor_all, b.sensor_wall, rows, unicycle, poses, robot, wall)
    ref_robot, ref_wall = b.contacts_any(record)
    ref_poses = b.poses(qpos[sims])
    np.testing.assert_array_equal(robot[rows], ref_robot)
    np.testing.assert_array_equal(wall[rows], ref_wall)
    np.testing.assert_array_equal(poses[rows][..., :2], ref_poses[..., :2])
    if unicycle:
        np.testing.assert_array_equal(poses[rows][..., 2], ref_poses[..., 2])
    dxu = rng.normal(0, [0.2, 3.0], (S * n, 2))
    ctrl = np.zeros((S + 2, model.nu))
    kernels.group_ctrl(dxu, rows, sims, unicycle, b.half_timestep, b.lateral_gain, *b.wheel_geometry, ctrl)
    np.testing.assert_array_equal(ctrl[sims], b.ctrl(dxu[rows]))
    assert not ctrl[[1, 4]].any()  # other simulations untouched


@pytest.mark.parametrize("tier", ["unicycle", "wheels"])
def test_batch_world_ticks_equal(tier, rng):
    def run():
        r = np.random.default_rng(5)
        world = BatchWorld((3, 5, 3, 2), SimConfig(tier=tier))
        out = []
        for sizes in ((3, 5, 3, 2), (2, 5, 4, 2)):
            world.set_team_sizes(sizes)
            starts = np.concatenate(
                [np.stack([np.linspace(-1.2, 1.2, n), r.uniform(-0.6, 0.6, n), r.uniform(-3, 3, n)], 1) for n in sizes]
            )
            world.reset(starts)
            for _ in range(15):
                ev = world.step(r.uniform([-0.3, -5], [0.3, 5], (sum(sizes), 2)))
                out += [world.poses, ev.actuator, ev.robot_contact, ev.wall_contact, ev.collision, ev.boundary]
        return tuple(out)

    _equal(*_both(run))


@pytest.mark.parametrize(("task", "tier"), [(PCP, "unicycle"), (HMT, "unicycle"), (PCP, "wheels")])
def test_env_rollouts_equal(task, tier):
    def run():
        env = VectorEnv(task(), 5, seed=3, tier=tier)
        obs, _ = env.reset()
        rng = np.random.default_rng(0)
        out, ends = [obs], 0
        for _ in range(90 if task is PCP else 12):
            o, r, term, trunc, info = env.step(rng.integers(0, 5, (5, env.max_robots)))
            out += [o, r, term, trunc, info["agent_mask"]]
            if "episode" in info:
                ends += 1
                out += [info["episode"][k] for k in sorted(info["episode"])]
        return tuple(out), ends

    (fast, ends), (slow, _) = _both(run)
    assert ends > 0 or task is HMT
    _equal(fast, slow)


def test_robot_watch_twin(rng):
    """The deployed loop's watch with its judgement compiled equals the numpy original bit for bit,
    through stale poses, robots that stop and start again, and restarted episodes; and the stream
    does put robots on probation and release them, so the judgement is exercised."""
    n, dt = 64, 0.033
    watches = [cls(n, 0.03, 4) for cls in (RobotWatch, CompiledRobotWatch)]
    true = np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
    measured = true.copy()
    cmd = np.column_stack([rng.uniform(0.05, 0.2, n), rng.uniform(-1, 1, n)])
    gains = rng.uniform(0.05, 0.7, n)
    put_on = released = 0
    for tick in range(600):
        dead = (np.arange(n) % 5 == 0) & (100 <= tick < 220)  # motors stopped, then back
        # the others follow at 5-70 % of the speed asked, so moved/asked crosses both thresholds
        response = np.where(dead, 0.0, gains)
        true[:, 0] += response * cmd[:, 0] * np.cos(true[:, 2]) * dt
        true[:, 1] += response * cmd[:, 0] * np.sin(true[:, 2]) * dt
        true[:, 2] += response * cmd[:, 1] * dt
        fresh = rng.random(n) > 0.2  # a fifth of the poses repeat the last one (a tracker hold)
        measured = np.where(fresh[:, None], true + rng.normal(0, 1e-3, (n, 3)), measured)
        if tick == 150:
            for w in watches:
                w.restart(np.array([1, 2, 3]))
        before = watches[0].unresponsive.copy()
        for w in watches:
            w.observe(measured.copy())
        a, b = watches
        for name in ("unresponsive", "unsure", "probation", "estimate", "anchor", "stale", "_stale_path", "_points"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (tick, name)
        put_on += int((a.unresponsive & ~before).sum())
        released += int((before & ~a.unresponsive).sum())
        if tick % 20 == 0:
            cmd = np.column_stack([rng.uniform(0.05, 0.2, n), rng.uniform(-1, 1, n)])
            gains = np.clip(gains + rng.normal(0, 0.1, n), 0.05, 0.7)
        for w in watches:
            w.sent(cmd)
    assert put_on >= 3 and released >= 3


@pytest.mark.parametrize("n", [1, 2, 5, 16, 20])
def test_portable_problem_twin(rng, n):
    """The portable barrier's rows built by the compiled twin equal the shipped numpy original bit
    for bit (bounds' signs included), with robots on probation (one, several, all, none) and
    extra radii, and with neither given."""
    settings = portable_settings(SafetyConfig(), C.DEFAULT_PROFILE)
    slow, fast = PortableBarrier(settings), CompiledPortableBarrier(settings)
    for trial in range(30):
        poses = _poses(rng, max(n, 3))[:n]
        probation = rng.random(n) < (0.0, 0.3, 1.0)[trial % 3]
        extra = np.where(rng.random(n) < 0.5, rng.uniform(0, 0.1, n), 0.0)
        (A, b), (A0, b0) = fast.problem(poses, probation, extra), slow.problem(poses, probation, extra)
        _equal((A, b), (A0, b0))
        assert np.array_equal(np.signbit(b), np.signbit(b0))
    _equal(fast.problem(poses), slow.problem(poses))


def test_dense_qp_matches_an_interior_point_solver(rng):
    """DAQP's answers (comat's dense solves) against cvxopt's interior point (the export's) on the
    portable barrier's problems of robots on probation: every row met, a cost no higher than the
    interior point's (which stops at its gap tolerance, ~1e-6 m/s away) and the same point to
    1e-5 m/s; infeasible problems reported as such (None, "primal infeasible"), not as an answer."""
    settings = portable_settings(SafetyConfig(), C.DEFAULT_PROFILE)
    barrier = PortableBarrier(settings)
    solved = 0
    for trial in range(40):
        n = int(rng.integers(2, 10))
        poses = _poses(rng, 10, spread=0.4)[:n]  # crowded: rows are active
        probation = rng.random(n) < 0.3
        A, b = barrier.problem(poses, probation)
        vhat = rng.uniform(-0.3, 0.3, 2 * n)
        x, status = dense_qp(vhat, A, b)
        y, other = cvxopt_qp(vhat, A, b)
        assert (x is None) == (y is None), (trial, status, other)
        if x is not None:
            solved += 1
            assert status == "optimal" and np.all(A @ x <= b + 1e-9)
            assert ((x - vhat) ** 2).sum() <= ((y - vhat) ** 2).sum() + 1e-12
            np.testing.assert_allclose(x, y, atol=1e-5)
    assert solved >= 10
    x, status = dense_qp(np.zeros(2), np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([-1.0, -1.0]))  # x <= -1, x >= 1
    assert x is None and status == "primal infeasible"
    assert _portable_qp(np.zeros(2), np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([-1.0, -1.0]))[0] is None
