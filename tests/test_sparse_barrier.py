"""The sparse barrier (comat.safety.sparse): large teams' QPs keep only the rows that can bind, and
their answers equal the all-pairs QP's."""

import numpy as np
import pytest

from comat import constants as C
from comat.config import SafetyConfig
from comat.safety import SafetyFilter
from comat.safety.constraints import (
    binding_distance,
    edge_binding_distance,
    make_layout,
    point_speed_bound,
    row_values,
)
from comat.sim.kinematics import projected_points, uni_to_si, wheel_rhombus

DENSE = 10**9  # sparse_from no team reaches: the all-pairs QP


def _pair_row_holds(e: np.ndarray, ui: np.ndarray, uj: np.ndarray, cfg: SafetyConfig) -> bool:
    return -2 * e @ (ui - uj) <= cfg.barrier_gain * (e @ e - cfg.safety_distance_m**2)


def test_binding_distance_is_a_tight_bound():
    """Beyond D no two commands in the wheel rhombi break a pair row; just inside D the worst pair
    of commands (each at the rhombus vertex farthest out, toward the other robot) does."""
    cfg = SafetyConfig()
    k, v = wheel_rhombus(cfg.projection_distance_m, C.GRITSBOT, cfg.wheel_speed_fraction)
    D, v_bar = binding_distance(cfg, C.GRITSBOT), point_speed_bound(cfg, C.GRITSBOT)
    # v̄: the rhombus's farthest vertex at the true wheel limit (the QP's rhombus is 0.1 % inside it).
    assert 0.2 < D < 0.25 and v_bar == pytest.approx(max(v, v / k) / cfg.wheel_speed_fraction, rel=1e-6)
    # The rhombus vertex farthest out lies along (k >= 1) or across (k < 1) the heading; aim it.
    along = k >= 1
    rng = np.random.default_rng(0)
    for _ in range(200):
        phi = rng.uniform(-np.pi, np.pi)
        direction = np.array([np.cos(phi), np.sin(phi)])
        heading = phi if along else phi - np.pi / 2
        for dist, holds in ((D * (1 + 1e-9), True), (D * (1 - 1e-3), False)):
            e = dist * direction  # p_i - p_j
            worst_i, worst_j = -v_bar * direction, v_bar * direction
            assert _pair_row_holds(e, worst_i, worst_j, cfg) == holds
            # Any commands in the rhombi (random points inside) hold beyond D.
            for _ in range(5):
                a, b = rng.uniform(-1, 1, (2, 2))
                scale = v / (np.abs(a) + k * np.abs(b)).max()
                R = np.array([[np.cos(heading), -np.sin(heading)], [np.sin(heading), np.cos(heading)]])
                ui, uj = R @ np.array([a[0], b[0]]) * scale, R @ np.array([a[1], b[1]]) * scale
                if holds:
                    assert _pair_row_holds(e, ui, uj, cfg)
    assert edge_binding_distance(cfg, C.GRITSBOT) == pytest.approx(v_bar / cfg.boundary_gain)


def _crowd(rng: np.random.Generator, n: int, spacing: float, box=(1.4, 0.85)) -> np.ndarray:
    pts: list[np.ndarray] = []
    while len(pts) < n:
        p = rng.uniform(-np.array(box), box)
        if all(np.hypot(*(p - q)) >= spacing for q in pts):
            pts.append(p)
    return np.column_stack([pts, rng.uniform(-np.pi, np.pi, n)])


def _configurations():
    """(name, team sizes, poses, commands (R, 2) unicycle) over random, crowded and adversarial
    cases of up to 32 robots (several teams per filter; some start outside the safe set)."""
    rng = np.random.default_rng(7)
    out = []
    for n in (10, 16, 32):
        for spacing, name in ((0.3, "random"), (0.21, "crowded"), (0.17, "inside-d_s")):
            sizes = (n, n, 9)
            poses = np.concatenate([_crowd(rng, m, spacing) for m in sizes])
            cmd = np.column_stack([rng.uniform(-0.2, 0.2, sum(sizes)), rng.uniform(-3, 3, sum(sizes))])
            out.append((f"{name}-{n}", sizes, poses, cmd))
    for n in (20, 24):  # a ring driven through its centre (as large as the arena allows), and
        # a corner pile-up pushed into the walls
        radius = 0.21 / (2 * np.sin(np.pi / n))
        a = np.linspace(0, 2 * np.pi, n, endpoint=False)
        out.append(
            (
                f"ring-{n}",
                (n,),
                np.stack([radius * np.cos(a), radius * np.sin(a), a + np.pi], 1),
                np.tile([[0.2, 0.0]], (n, 1)),
            )
        )
        x1, y1 = C.ARENA_BOUNDS_M[1] - 0.2, C.ARENA_BOUNDS_M[3] - 0.2
        g = np.stack(np.meshgrid(np.arange(8), np.arange(n // 8 + 1)), -1).reshape(-1, 2)[:n]
        corner = np.column_stack([x1 - 0.22 * g[:, 0], y1 - 0.22 * g[:, 1], np.full(n, np.pi / 4)])
        out.append((f"corner-{n}", (n,), corner, np.tile([[1e6, 0.0]], (n, 1))))
    g = np.stack(np.meshgrid(np.arange(8), np.arange(4)), -1).reshape(-1, 2)
    x1, y1 = C.ARENA_BOUNDS_M[1] - 0.2, C.ARENA_BOUNDS_M[3] - 0.2
    out.append(
        (
            "corner-32",
            (32,),
            np.column_stack([x1 - 0.22 * g[:, 0], y1 - 0.22 * g[:, 1], np.full(32, np.pi / 4)]),
            np.tile([[1e6, 0.0]], (32, 1)),
        )
    )
    return out


def _worst_row_miss(f: SafetyFilter, poses: np.ndarray, dxu: np.ndarray) -> float:
    """Largest violation of any row of the all-pairs problem by the filtered command (m/s or m²/s)."""
    d = f.config.projection_distance_m
    lay = make_layout(f.team_sizes)
    vals = row_values(lay, projected_points(poses, d), poses[:, 2], f.config, f.profile)
    Au = vals.products(uni_to_si(dxu, poses, d).ravel())
    return float(np.max(np.maximum(Au - vals.upper, vals.lower - Au)))


@pytest.mark.parametrize("name, sizes, poses, cmd", _configurations(), ids=lambda v: v if isinstance(v, str) else "")
def test_sparse_filter_equals_the_all_pairs_filter(name, sizes, poses, cmd):
    """Over 40 ticks of the robots moving (the kept pattern reused, and rebuilt as neighbours
    change): where the all-pairs QP is solved, the sparse filter's commands equal its commands
    within the solver's tolerance (eps, m/s at the projected points; almost always to 1e-9), with
    the same recoveries and brakes. In degenerate pile-ups the all-pairs QP is sometimes not
    solved (iteration limit, "solved inaccurate": 190–496 nearly parallel rows) and its team
    takes the softened problem; there the reduced problem's answer must meet every row of the
    all-pairs problem: a safe command where the dense filter only recovered."""
    sparse, dense = SafetyFilter(sizes), SafetyFilter(sizes, sparse_from=DENSE)
    tol, d = sparse.config.feasibility_tol, sparse.config.projection_distance_m
    poses = poses.copy()
    solved = exact = 0
    for _ in range(40):
        (a, ia), (b, ib) = sparse.filter_unicycle(poses, cmd), dense.filter_unicycle(poses, cmd)
        assert not (ia.recovery & ~ib.recovery).any()  # never worse than the all-pairs QP
        np.testing.assert_array_equal(ia.fallback, ib.fallback)
        if (ib.recovery & ~ia.recovery).any():
            assert _worst_row_miss(sparse, poses, a) <= tol
        else:
            gap = np.abs(uni_to_si(a, poses, d) - uni_to_si(b, poses, d)).max()
            assert gap <= sparse.config.eps
            exact += gap <= 1e-9
            solved += ib.status != "skipped"
        # Kinematic step with the all-pairs filter's command (both filters see the same poses).
        poses[:, 0] += C.CONTROL_DT_S * b[:, 0] * np.cos(poses[:, 2])
        poses[:, 1] += C.CONTROL_DT_S * b[:, 0] * np.sin(poses[:, 2])
        poses[:, 2] += C.CONTROL_DT_S * b[:, 1]
    assert solved > 0 and exact >= 35  # the QP was needed (not vacuous) and the answers agree exactly
    assert sparse._pattern.rebuilds >= 1


def test_rows_grow_with_neighbours_not_with_pairs():
    """32 robots spread >= 0.22 m apart, each driven at its nearest neighbour: the reduced problem
    keeps the few pairs within the binding distance (plus the pattern's slack) of the 496."""
    rng = np.random.default_rng(3)
    poses = _crowd(rng, 32, 0.22)
    f = SafetyFilter(32)
    pts = projected_points(poses, f.config.projection_distance_m)
    # Every robot driven at its nearest neighbour, so the QP is needed.
    d = np.linalg.norm(pts[:, None] - pts[None], axis=-1) + 10 * np.eye(32)
    toward = pts[d.argmin(1)] - pts
    u = 0.2 * toward / np.linalg.norm(toward, axis=1, keepdims=True)
    out, info = f.filter(poses, u)
    assert info.status != "skipped"
    red = f._pattern.current
    close = (d < binding_distance(f.config, f.profile) + 0.05).sum() // 2
    assert red.pair_i.size == close < 496 // 8
    ref, _ = SafetyFilter(32, sparse_from=DENSE).filter(poses, u)
    np.testing.assert_allclose(out, ref, atol=1e-6, rtol=0)


def test_small_teams_keep_the_all_pairs_problem_bit_for_bit(rng):
    """Below sparse_from (default 9 robots) nothing changed: same answers, bit for bit."""
    sizes = (8, 5, 8)
    poses = np.concatenate([_crowd(rng, n, 0.21) for n in sizes])
    cmd = np.column_stack([rng.uniform(-0.2, 0.2, 21), rng.uniform(-3, 3, 21)])
    a, _ = SafetyFilter(sizes).filter_unicycle(poses, cmd)
    b, _ = SafetyFilter(sizes, sparse_from=DENSE).filter_unicycle(poses, cmd)
    np.testing.assert_array_equal(a, b)
    assert not SafetyFilter(sizes)._sparse_team.any()


def test_safe_robots_outside_the_reduced_problem_keep_their_command():
    """A 12-robot team: two robots about to collide, ten far apart and still. Only the pair is in
    the reduced problem; the others' commands come back exactly."""
    poses = np.array(
        [[-0.12, 0.0, 0.0], [0.12, 0.0, np.pi]] + [[-1.2 + 0.5 * (i % 5), 0.6 * (-1) ** i, 0.0] for i in range(10)]
    )
    dxu = np.array([[0.2, 0.0], [0.2, 0.0]] + [[0.05, 0.1]] * 10)
    f = SafetyFilter(12)
    out, info = f.filter_unicycle(poses, dxu)
    assert info.intervention[0] > 0 and f._pattern.current.sizes.tolist() == [2]
    np.testing.assert_array_equal(out[2:], dxu[2:])
    u = uni_to_si(out, poses, f.config.projection_distance_m)
    p = projected_points(poses, f.config.projection_distance_m)
    assert _pair_row_holds(p[0] - p[1], u[0], u[1], f.config)


def test_numpy_reference_path_gives_the_same_sparse_answers():
    """The compiled stages and gathers (comat.kernels) against the numpy reference, on a crowd of
    two 20-robot teams over 20 ticks."""
    from comat import kernels

    rng = np.random.default_rng(11)
    sizes = (20, 20)
    poses = np.concatenate([_crowd(rng, 20, 0.21) for _ in sizes])
    poses[:, 2] = np.arctan2(-poses[:, 1], -poses[:, 0])  # everyone heading for the centre, full speed
    cmd = np.column_stack([np.full(40, 0.2), rng.uniform(-1, 1, 40)])
    compiled, reference = SafetyFilter(sizes), SafetyFilter(sizes)
    for _ in range(20):
        a, ia = compiled.filter_unicycle(poses, cmd)
        with kernels.reference_path():
            b, ib = reference.filter_unicycle(poses, cmd)
        np.testing.assert_allclose(a, b, atol=1e-12, rtol=0)
        np.testing.assert_array_equal(ia.recovery, ib.recovery)
        poses[:, 0] += C.CONTROL_DT_S * a[:, 0] * np.cos(poses[:, 2])
        poses[:, 1] += C.CONTROL_DT_S * a[:, 0] * np.sin(poses[:, 2])
        poses[:, 2] += C.CONTROL_DT_S * a[:, 1]
    assert compiled._pattern.rebuilds >= 1
