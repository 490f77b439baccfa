import numpy as np
import pytest

from comat.config import SimConfig
from comat.sim import World

TIERS = ["wheels", "unicycle"]


def _line(n, spacing=0.3):
    p = np.zeros((n, 3))
    p[:, 0] = np.arange(n) * spacing - (n - 1) * spacing / 2
    return p


@pytest.mark.parametrize("tier", TIERS)
def test_reset_places_robots_exactly(tier, rng):
    w = World(3, SimConfig(tier=tier))
    poses = _line(3)
    poses[:, 2] = [0.3, -2.0, 3.0]
    w.reset(poses)
    np.testing.assert_allclose(w.poses, poses, atol=1e-12)
    assert w.ticks == 0 and w.time == 0.0


@pytest.mark.parametrize("tier", TIERS)
def test_straight_drive_covers_v_times_t(tier):
    w = World(1, SimConfig(tier=tier))
    w.reset(np.array([[-1.0, 0.0, 0.0]]))
    for _ in range(60):
        w.step(np.array([[0.1, 0.0]]))
    # 60 ticks * 0.033 s * 0.1 m/s = 0.198 m, less the motor response (< 2 mm).
    assert w.poses[0, 0] + 1.0 == pytest.approx(0.198, abs=2e-3)
    assert abs(w.poses[0, 1]) < 1e-4 and abs(w.poses[0, 2]) < 1e-4


@pytest.mark.parametrize("tier", TIERS)
def test_wheel_clipping_and_actuator_counter(tier):
    w = World(1, SimConfig(tier=tier))
    w.reset(np.zeros((1, 3)))
    ev = w.step(np.array([[0.2, 2.0]]))  # right wheel would need 19 rad/s
    assert ev.actuator.tolist() == [True]
    assert w.violations.actuator_ticks.tolist() == [1]
    w.step(np.array([[0.05, 0.0]]))
    assert w.violations.actuator_ticks.tolist() == [1]


@pytest.mark.parametrize("tier", TIERS)
def test_unfiltered_head_on_crash_is_detected(tier):
    w = World(2, SimConfig(tier=tier))
    w.reset(np.array([[-0.15, 0.0, 0.0], [0.15, 0.0, np.pi]]))
    for _ in range(30):
        ev = w.step(np.array([[0.2, 0.0], [0.2, 0.0]]))
    assert ev.robot_contact.all() and ev.collision.all()
    assert (w.violations.contact_onsets >= 1).all()
    assert w.violations.collision_pairs[0] > 0
    # Bodies are pushed together but do not pass through each other.
    assert np.linalg.norm(w.poses[0, :2] - w.poses[1, :2]) > 0.1


@pytest.mark.parametrize("tier", TIERS)
def test_wall_contact_and_boundary(tier):
    w = World(1, SimConfig(tier=tier))
    w.reset(np.array([[1.4, 0.0, 0.0]]))
    for _ in range(60):
        ev = w.step(np.array([[0.2, 0.0]]))
    assert ev.wall_contact.all()
    assert not ev.boundary.any()  # the wall stops the centre inside the arena
    assert w.poses[0, 0] < 1.6 - 0.05


def test_same_inputs_same_trajectory():
    def run():
        w = World(4, SimConfig(tier="wheels"))
        w.reset(_line(4))
        r = np.random.default_rng(0)
        for _ in range(50):
            w.step(r.uniform([-0.2, -3], [0.2, 3], (4, 2)))
        return w.poses

    np.testing.assert_array_equal(run(), run())


@pytest.mark.parametrize(
    "poses, match",
    [
        (np.zeros((2, 2)), r"poses must have shape \(2, 3\), got shape \(2, 2\)"),
        (np.array([[0.0, 0.0, np.nan], [0.5, 0.0, 0.0]]), r"poses must be finite, got nan at index \(0, 2\)"),
        (np.array([[1.58, 0.0, 0.0], [0.0, 0.0, 0.0]]), r"robot 0 at \(1.580, 0.000\) is outside the arena"),
        (
            np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]]),
            r"robots 0 and 1 overlap \(centres 0.050 m apart, need >= 0.110 m\)",
        ),
    ],
)
def test_bad_reset_poses(poses, match):
    w = World(2)
    with pytest.raises(ValueError, match=match):
        w.reset(poses)


def test_bad_commands():
    w = World(2)
    w.reset(_line(2))
    with pytest.raises(ValueError, match=r"dxu must have shape \(2, 2\), got shape \(3, 2\)"):
        w.step(np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"dxu must be finite, got inf at index \(1, 0\)"):
        w.step(np.array([[0.0, 0.0], [np.inf, 0.0]]))
    with pytest.raises(TypeError, match="dxu must be a float array"):
        w.step([["a", 0.0], [0.0, 0.0]])


def test_bad_config():
    with pytest.raises(ValueError, match=r"timestep_s must divide the 0.033 s control tick .* got 0.01"):
        SimConfig(timestep_s=0.01)
    with pytest.raises(ValueError, match="SimConfig.tier must be one of"):
        SimConfig(tier="hover")
    with pytest.raises(ValueError, match="n_robots must be a positive integer, got 0"):
        World(0)
    assert SimConfig(timestep_s=0.033 / 6).resolved_substeps == 6


def test_the_world_is_reached_through_its_seams_only():
    """Outside comat/sim/ the world's poses and ticks are read and driven through its public seams
    (``pose_view``, ``poses``, ``advance``, ``step_points``), never its private ``_poses`` or
    ``_advance`` (issue 67): a private attribute reached from elsewhere fails here with its place."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    private = re.compile(r"(?<!self)\.(_poses|_advance|_step_points|_set_poses|_run_physics)\b")
    reached = [
        f"{path.relative_to(root)}:{k}"
        for top in ("comat", "sim2real")
        for path in sorted((root / top).rglob("*.py"))
        if "sim" not in path.relative_to(root / top).parts[:1]
        for k, line in enumerate(path.read_text().splitlines(), 1)
        if private.search(line)
    ]
    assert reached == []
    w = World(2)
    w.reset(_line(2))
    view = w.pose_view
    np.testing.assert_array_equal(view, w.poses)
    with pytest.raises(ValueError, match="read-only"):
        view[0, 0] = 1.0
