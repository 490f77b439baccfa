"""The compiled pass over teams with a robot on probation (comat.safety.probation) against the numpy
code it replaces. Not bit for bit, unlike tests/test_kernels.py: its re-solves use their own exact
active-set solver and sum rows in their own order, so the answers differ from DAQP's by rounding
(the optimum of these strictly convex problems is unique); to 1e-9 m/s here."""

import copy

import numpy as np

from comat import constants as C
from comat import control
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams, _portable_qp, _probation_teams, go_to_goal, portable_settings
from comat.reality import resolve_reality
from comat.safety.deployed import PortableBarrier
from comat.safety.probation import GAVE_UP, INFEASIBLE, REFERENCE, SOLVED, SUBSET, TEAM, nearest_in_polytope
from comat.safety.qp import dense_qp


def _start(rng, R):
    """(R, 3) poses on a 9 × 7 grid (0.35 × 0.27 m: none overlap), shuffled, random headings."""
    x, y = np.meshgrid(np.linspace(-1.4, 1.4, 9), np.linspace(-0.8, 0.8, 7))
    cells = rng.permutation(63)[:R]
    return np.column_stack([x.ravel()[cells], y.ravel()[cells], rng.uniform(-np.pi, np.pi, R)])


def test_nearest_in_polytope_matches_daqp(rng):
    """The dual active-set solver against DAQP (comat's dense solves until now), on the portable
    barrier's crowded problems (robots on probation, extra radii) and on random dense ones: the
    same verdict (solved or infeasible, never given up), every row met within 1e-12 of the row
    scale, and the same point to 1e-9 of the distance moved (rounding)."""
    barrier = PortableBarrier(portable_settings(SafetyConfig(), C.DEFAULT_PROFILE))
    solved = infeasible = 0
    for trial in range(400):
        if trial % 2:
            n = int(rng.integers(1, 12))
            poses = np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), rng.uniform(-np.pi, np.pi, n)])
            extra = np.where(rng.random(n) < 0.3, rng.uniform(0, 0.05, n), 0.0)
            A, b = barrier.problem(poses, rng.random(n) < 0.3, extra)
            v = rng.uniform(-0.3, 0.3, 2 * n)
        else:
            n, m = int(rng.integers(1, 10)), int(rng.integers(1, 40))
            A, b, v = rng.normal(size=(m, n)), rng.normal(size=m), 3 * rng.normal(size=n)
        x = np.full(v.size, np.nan)
        verdict = nearest_in_polytope(v, A, b, x)
        y, status = dense_qp(v, A, b)
        assert verdict != GAVE_UP, trial
        assert (verdict == SOLVED) == (y is not None), (trial, status)
        if y is None:
            assert status == "primal infeasible"
            infeasible += 1
            continue
        solved += 1
        assert np.all(A @ x <= b + 1e-12 * np.maximum(1.0, np.abs(A) @ np.abs(x))), trial
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-9 * max(1.0, np.linalg.norm(v - y)))
    assert solved >= 100 and infeasible >= 100
    x = np.empty(2)
    assert (
        nearest_in_polytope(np.zeros(2), np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([-1.0, -1.0]), x) == INFEASIBLE
    )
    assert nearest_in_polytope(np.array([0.3, -0.2]), np.zeros((1, 2)), np.zeros(1), x) == SOLVED
    assert np.array_equal(x, [0.3, -0.2])  # a nominal command that meets every row comes back as it is


def test_probation_pass_matches_the_reference_loop(monkeypatch):
    """comat's loop at ``stress`` with the compiled pass, every tick against the numpy loop
    (:func:`comat.control._probation_teams` with the shipped PortableBarrier and DAQP) on the same
    inputs: the same teams changed, the same fallback and recovery flags and subset count,
    commands and interventions equal to 1e-9 m/s, every command within the portable rows (but a
    recovery's, outside the safe set: the softened problem's); and the
    pass's verdicts include subsets and whole teams, so both of its solves are exercised."""
    sizes = (20, 16, 8, 8, 8, 3)
    teams = SafeTeams(sizes, SimConfig(tier="unicycle"), reality=resolve_reality("stress"), reality_seed=1)
    assert isinstance(teams._portable, control.CompiledPortableBarrier)
    reference = PortableBarrier(teams._portable.s, _portable_qp)
    rng = np.random.default_rng(1)
    R = sum(sizes)
    teams.reset(_start(rng, R))
    verdicts = np.zeros(5, np.int64)
    compiled = control.probation_pass

    def counted(*args):
        compiled(*args)
        verdicts[:] += np.bincount(args[-2], minlength=5)

    monkeypatch.setattr(control, "probation_pass", counted)
    fast = teams._watch_teams
    compared = 0

    def both(dxi, safe, info):
        nonlocal compared
        watch = copy.deepcopy(teams.watch)
        ref_safe, ref_info = safe.copy(), copy.copy(info)
        for name in ("intervention", "fallback", "recovery"):
            setattr(ref_info, name, getattr(info, name).copy())
        subsets = teams.subset_solves
        fast(dxi, safe, info)
        watch.observe(teams.reality.measured)
        if not watch.probation.any():
            return
        poses, extra = watch.obstacles()
        lay, tol = teams.world.layout, teams.filter_config.feasibility_tol
        on = np.unique(lay.robot_team[watch.probation])
        args = (lay.offsets, watch.probation, poses, extra, dxi, ref_safe, ref_info, tol)
        ref_subsets = _probation_teams(reference, on, *args)
        assert teams.subset_solves - subsets == ref_subsets
        np.testing.assert_allclose(safe, ref_safe, rtol=0, atol=1e-9)
        np.testing.assert_allclose(info.intervention, ref_info.intervention, rtol=0, atol=1e-9)
        assert np.array_equal(info.fallback, ref_info.fallback) and np.array_equal(info.recovery, ref_info.recovery)
        for b in on[~(info.recovery | info.fallback)[on]]:  # a recovery is outside the safe set
            rows = slice(lay.offsets[b], lay.offsets[b + 1])
            A, bound = reference.problem(poses[rows], watch.probation[rows], extra[rows])
            assert np.all(A @ safe[rows].ravel() <= bound + tol)
        compared += 1

    monkeypatch.setattr(teams, "_watch_teams", both)
    goals = rng.uniform([-1.4, -0.8], [1.4, 0.8], (R, 2))
    for k in range(120):
        if k % 40 == 39:
            goals = rng.uniform([-1.4, -0.8], [1.4, 0.8], (R, 2))
        teams.tick(go_to_goal(teams.measured_points, goals, max_speed=0.15))
    assert compared >= 60
    assert verdicts[SUBSET] >= 20 and verdicts[TEAM] >= 1, verdicts
    assert verdicts[REFERENCE] <= verdicts[SUBSET] // 10  # the loop is the exception


def test_probation_pass_keeps_the_runs_deterministic():
    """Two runs at ``stress`` with the same seed take the same steps bit for bit with the compiled
    pass (it reads nothing but its arguments)."""

    def run():
        teams = SafeTeams((8,) * 4, SimConfig(tier="unicycle"), reality=resolve_reality("stress"), reality_seed=3)
        rng = np.random.default_rng(3)
        teams.reset(_start(rng, 32))
        goals = rng.uniform([-1.4, -0.8], [1.4, 0.8], (32, 2))
        for _ in range(60):
            teams.tick(go_to_goal(teams.measured_points, goals, max_speed=0.15))
        return teams.poses.copy(), teams.subset_solves

    (a, n), (b, m) = run(), run()
    assert np.array_equal(a, b) and n == m and n > 0


def test_portable_rows_twin(rng):
    """The pass's rows built straight into CSR equal the compiled dense rows (themselves the
    shipped numpy original's, tests/test_kernels.py) bit for bit, nonzeros, norms and bounds, with
    robots on probation (none, some, all) and extra radii."""
    from comat.safety.kernels import portable_problem
    from comat.safety.probation import _sparse, portable_rows

    constants = control.CompiledPortableBarrier(portable_settings(SafetyConfig(), C.DEFAULT_PROFILE)).constants
    for trial in range(60):
        n = int(rng.integers(1, 21))
        poses = np.column_stack([rng.uniform(-1.5, 1.5, (n, 2)), rng.uniform(-4 * np.pi, 4 * np.pi, n)])
        if n >= 2:  # robots 0 and 1 abreast, same heading: their pair rows have exact zeros
            poses[1, 0], poses[1, 2] = poses[0, 0], poses[0, 2]
        probation = rng.random(n) < (0.0, 0.3, 1.0)[trial % 3]
        extra = np.where(rng.random(n) < 0.5, rng.uniform(0, 0.1, n), 0.0)
        A, b = portable_problem(poses, probation, extra, *constants)
        start, cols, vals, norm2 = _sparse(A)
        got = portable_rows(poses, probation, extra, *constants)
        nnz = start[-1]
        for x, y in zip(got, (start, cols[:nnz], vals[:nnz], norm2, b), strict=True):
            np.testing.assert_array_equal(x[: y.size], y)
        assert got[0].size == start.size and got[4].size == b.size and got[0][-1] == nnz
