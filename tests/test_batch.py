import numpy as np
import pytest

from comat.config import SimConfig
from comat.control import SafeTeams, go_to_goal
from comat.sim import BatchWorld, World

TIERS = ["wheels", "unicycle"]


def _starts(rng, sizes):
    out = []
    for n in sizes:
        p = np.zeros((n, 3))
        p[:, 0] = np.linspace(-1.2, 1.2, n) if n > 1 else 0.0
        p[:, 1] = rng.uniform(-0.6, 0.6, n)
        p[:, 2] = rng.uniform(-np.pi, np.pi, n)
        out.append(p)
    return out


@pytest.mark.parametrize("tier", TIERS)
def test_batched_physics_equals_single_worlds_bit_for_bit(tier, rng):
    sizes = [3, 2, 3, 5]
    starts = _starts(rng, sizes)
    batch = BatchWorld(sizes, SimConfig(tier=tier))
    batch.reset(np.concatenate(starts))
    singles = [World(n, SimConfig(tier=tier)) for n in sizes]
    for w, p in zip(singles, starts):
        w.reset(p)
    for _ in range(40):
        cmd = rng.uniform([-0.25, -4], [0.25, 4], (sum(sizes), 2))
        ev = batch.step(cmd)
        single_ev = []
        for w, part in zip(singles, np.split(cmd, np.cumsum(sizes)[:-1])):
            single_ev.append(w.step(part))
        np.testing.assert_array_equal(ev.actuator, np.concatenate([e.actuator for e in single_ev]))
        np.testing.assert_array_equal(ev.robot_contact, np.concatenate([e.robot_contact for e in single_ev]))
    np.testing.assert_array_equal(batch.poses, np.concatenate([w.poses for w in singles]))
    np.testing.assert_array_equal(batch.violations.actuator_ticks, [w.violations.actuator_ticks[0] for w in singles])


def test_batched_contacts_equal_single_world_contacts():
    # Unfiltered crashes: contact flags of the batched sensors equal the reference world's.
    starts = [np.array([[-0.15, 0, 0], [0.15, 0, np.pi]]), np.array([[1.35, 0.5, 0.0], [-0.5, -0.5, 0]])]
    batch = BatchWorld([2, 2])
    batch.reset(np.concatenate(starts))
    singles = [World(2) for _ in starts]
    for w, p in zip(singles, starts):
        w.reset(p)
    cmd = np.array([[0.2, 0.0]] * 4)
    for _ in range(40):
        ev = batch.step(cmd)
        ref = [w.step(c) for w, c in zip(singles, np.split(cmd, 2))]
        np.testing.assert_array_equal(ev.robot_contact, np.concatenate([r.robot_contact for r in ref]))
        np.testing.assert_array_equal(ev.wall_contact, np.concatenate([r.wall_contact for r in ref]))
    assert batch.violations.contact_ticks[:2].sum() > 0 and batch.violations.wall_ticks[2] > 0


def test_reset_of_some_teams_leaves_the_others_running(rng):
    sizes = [2, 3]
    starts = np.concatenate(_starts(rng, sizes))
    batch = BatchWorld(sizes)
    batch.reset(starts)
    for _ in range(10):
        batch.step(np.full((5, 2), [0.1, 0.0]))
    moved = batch.poses
    batch.reset(starts, teams=[0])
    np.testing.assert_allclose(batch.poses[:2], starts[:2], atol=1e-12)
    np.testing.assert_array_equal(batch.poses[2:], moved[2:])
    with pytest.raises(ValueError, match=r"teams must be indices in \[0, 2\), got \[2\]"):
        batch.reset(starts, teams=[2])


def _drive_filtered(sizes, starts, goals, tier, ticks=120):
    """The teams driven to their goals through the filter, batched and each alone."""
    batch = SafeTeams(sizes, SimConfig(tier=tier))
    batch.reset(np.concatenate(starts))
    singles = [SafeTeams([n], SimConfig(tier=tier), batched=False) for n in sizes]
    for s, p in zip(singles, starts):
        s.reset(p)
    g_all = np.concatenate(goals)
    for _ in range(ticks):
        batch.tick(go_to_goal(batch.points, g_all))
        for s, g in zip(singles, goals):
            s.tick(go_to_goal(s.points, g))
    return batch, singles


@pytest.mark.parametrize("tier", TIERS)
def test_filtered_batch_equals_filtered_single_teams(tier, rng):
    """One block-diagonal QP for all teams gives each team the same commands as its own QP."""
    sizes = [4, 4, 3]
    starts = _starts(rng, sizes)
    batch, singles = _drive_filtered(sizes, starts, [-s[:, :2] for s in starts], tier)
    # The 4-robot teams cross paths (the barrier acts); commands beyond the wheels are saturated
    # before the filter (SafeTeams.tick), so a team that never meets a barrier row counts none.
    assert (batch.interventions[:2] > 0).all()
    np.testing.assert_allclose(batch.poses, np.concatenate([s.poses for s in singles]), atol=1e-6)


def test_filtered_sub_problems_equal_filtered_single_teams(rng):
    """Teams needing the QP are solved together in a problem of size-ordered teams (a few of
    many teams in conflict); each team still gets its own QP's commands."""
    sizes = [3, 4, 2, 5, 3, 4, 2, 3, 5, 4, 3, 2, 4, 3, 5, 2]
    starts = _starts(rng, sizes)
    busy = {1, 3, 8, 12, 14}
    goals = [-p[:, :2] if b in busy else p[:, :2] + 0.01 for b, p in enumerate(starts)]
    batch, singles = _drive_filtered(sizes, starts, goals, "unicycle")
    sub_keys = [key for key, _ in batch._qp_cache if len(key) == 8]
    assert sub_keys and all(list(key) == sorted(key) for key in sub_keys)  # sub-problems, size-ordered
    assert sorted(np.flatnonzero(batch.interventions).tolist()) == sorted(busy)
    # Each tick's answer is the optimum to ~1e-5 (qp.py), whatever shares the problem.
    np.testing.assert_allclose(batch.poses, np.concatenate([s.poses for s in singles]), atol=5e-5)


def test_team_sizes_change_between_episodes(rng):
    """Teams that keep their size keep running; a resized team restarts and equals a fresh world."""
    batch = BatchWorld([3, 2, 3])
    starts = _starts(rng, [3, 2, 3])
    batch.reset(np.concatenate(starts))
    for _ in range(5):
        batch.step(np.full((8, 2), [0.1, 0.5]))
    kept = batch.poses[:3].copy(), batch.poses[5:].copy()
    batch.set_team_sizes([3, 4, 3])
    new = _starts(rng, [4])[0]
    full = np.concatenate([kept[0], new, kept[1]])
    batch.reset(full, teams=[1])
    np.testing.assert_array_equal(batch.poses[:3], kept[0])
    np.testing.assert_array_equal(batch.poses[7:], kept[1])
    ref = World(4)
    ref.reset(new)
    cmd = rng.uniform([-0.2, -3], [0.2, 3], (10, 2))
    for _ in range(20):
        batch.step(cmd)
        ref.step(cmd[3:7])
    np.testing.assert_array_equal(batch.poses[3:7], ref.poses)
    with pytest.raises(ValueError, match=r"team_sizes must list 3 teams, got 2"):
        batch.set_team_sizes([3, 3])


def test_physics_threads_do_not_change_results(rng):
    sizes = [3, 5, 3, 4, 2, 5]
    starts = np.concatenate(_starts(rng, sizes))
    cmds = rng.uniform([-0.3, -5], [0.3, 5], (20, sum(sizes), 2))
    poses = []
    for threads in (1, 2):
        world = BatchWorld(sizes, SimConfig(tier="wheels", threads=threads))
        world.reset(starts)
        for cmd in cmds:
            world.step(cmd)
        poses.append(world.poses)
    np.testing.assert_array_equal(poses[0], poses[1])
    with pytest.raises(ValueError, match=r"SimConfig.threads must be a positive integer, got 0"):
        SimConfig(threads=0)


@pytest.mark.parametrize("tier", TIERS)
@pytest.mark.parametrize(
    "sizes, resized", [([3, 5, 3, 4, 2, 5], [3, 3, 5, 4, 5, 2]), ([4, 4, 4], [4, 4, 4])], ids=["mixed", "one-size"]
)
def test_direct_rollout_equals_the_public_wrapper(tier, sizes, resized, rng, monkeypatch):
    """The compiled path's direct call of MuJoCo's batch rollout (mujoco 4.0) and the public
    wrapper step the same simulations: same poses and contact flags, bit for bit — with ids
    (mixed sizes, teams moved to other simulations by a size change) and without (one size,
    simulations in team order)."""
    import comat.sim.batch as batch_module

    starts = np.concatenate(_starts(rng, sizes))
    starts2 = np.concatenate(_starts(rng, resized))
    cmds = rng.uniform([-0.3, -5], [0.3, 5], (30, sum(sizes), 2))
    runs = []
    for direct in (True, False):
        monkeypatch.setattr(batch_module, "_DIRECT_ROLLOUT", direct)
        world = BatchWorld(sizes, SimConfig(tier=tier))
        world.reset(starts)
        contacts = []
        for k, cmd in enumerate(cmds):
            if k == 15:
                world.set_team_sizes(resized)
                world.reset(starts2)
            contacts.append(world.step(cmd).robot_contact)
        runs.append((world.poses, np.array(contacts)))
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
