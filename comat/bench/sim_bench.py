"""``comat bench sim``: cost of a control tick, ours vs the Robotarium simulator's own loop.

Workload (identical for both): every robot drives its projected point toward a random goal
with a proportional controller (gain 1, ≤ 0.15 m/s; rps ``si_position_controller``), goals
re-drawn every 150 ticks, barrier filter at every tick. Ours: :class:`comat.control.SafeTeams`
(MuJoCo physics with contacts + OSQP barrier) for B teams at once. Robotarium: the PyPI
``rps`` legacy loop ``get_poses → controller → si_to_uni → unicycle barrier with boundary →
set_velocities → step`` (cvxopt QP, Euler unicycle, no contacts), one team (it has no batching).

Rows at reality level ``nominal`` (:mod:`comat.reality`: measured poses for the controller and
filter, command path and motors before the physics) stand next to the ``off`` ones for the team
sizes in ``reality_sizes``; the check ``reality_overhead_<tier>_B64_N8`` is their tick ratio.

Reported per configuration: median µs per tick split into physics (MuJoCo's stepping calls),
filter (OSQP's update/solve calls) and rest (everything else: Python), µs per robot-tick, and
simulated robot-seconds per wall-second.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from comat import constants as C
from comat.config import SimConfig
from comat.control import SafeTeams, go_to_goal
from comat.files import write_atomic
from comat.reality import resolve_reality

__all__ = ["SimBenchRow", "bench_ours", "bench_rps", "run_sim_bench"]

_REDRAW = 150


@dataclass
class SimBenchRow:
    """One measured configuration (times in µs, medians over the measured ticks)."""

    system: str
    tier: str
    n_robots: int
    batch: int
    tick_us: float
    physics_us: float
    filter_us: float
    rest_us: float
    per_robot_tick_us: float
    robot_s_per_wall_s: float
    ticks: int
    reality: str = "off"
    """Reality level the row was measured at (:data:`comat.reality.REALITY_LEVELS`)."""


def _spread(rng: np.random.Generator, n: int, spacing: float = 0.3) -> np.ndarray:
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    pts: list[np.ndarray] = []
    while len(pts) < n:
        p = rng.uniform([x0 + 0.2, y0 + 0.2], [x1 - 0.2, y1 - 0.2])
        if all(np.hypot(*(p - q)) >= spacing for q in pts):
            pts.append(p)
    return np.array(pts)


def _goals(rng: np.random.Generator, count: int) -> np.ndarray:
    x0, x1, y0, y1 = C.ARENA_BOUNDS_M
    return rng.uniform([x0 + 0.3, y0 + 0.3], [x1 - 0.3, y1 - 0.3], (count, 2))


def bench_ours(
    tier: str, n: int, batch: int, ticks: int, seed: int = 0, warmup: int = 10, reality: Any = "off"
) -> SimBenchRow:
    """Time ``ticks`` control ticks of ``batch`` teams of ``n`` robots in one tier, at a reality level
    (the controller then reads the measured points, as the envs' does)."""

    rng = np.random.default_rng(seed)
    teams = SafeTeams((n,) * batch, SimConfig(tier=tier), reality=resolve_reality(reality), reality_seed=seed)
    starts = [np.column_stack([_spread(rng, n), rng.uniform(-np.pi, np.pi, n)]) for _ in range(batch)]
    teams.reset(np.concatenate(starts))
    goals = _goals(rng, n * batch)
    tot, phy, sol = [], [], []
    for k in range(warmup + ticks):
        if k % _REDRAW == _REDRAW - 1:
            goals = _goals(rng, n * batch)
        teams.tick(go_to_goal(teams.measured_points, goals, max_speed=0.15))
        if k >= warmup:
            tot.append(teams.timing.total)
            phy.append(teams.timing.physics)
            sol.append(teams.timing.solver)
    total, physics, solver = (float(np.median(x)) * 1e6 for x in (tot, phy, sol))
    rest = float(np.median(np.array(tot) - np.array(phy) - np.array(sol))) * 1e6
    return SimBenchRow(
        system="comat",
        tier=tier,
        n_robots=n,
        batch=batch,
        tick_us=total,
        physics_us=physics,
        filter_us=solver,
        rest_us=rest,
        per_robot_tick_us=total / (n * batch),
        robot_s_per_wall_s=n * batch * C.CONTROL_DT_S / (total * 1e-6),
        ticks=ticks,
        reality=reality if isinstance(reality, str) else resolve_reality(reality).level + "+overrides",
    )


def rps_available() -> bool:
    try:
        import rps.robotarium  # noqa: F401
        from rps.utilities.barrier_certificates import create_unicycle_barrier_certificate_with_boundary  # noqa: F401
    except Exception:  # noqa: BLE001 — any import failure means "not installed here"
        return False
    return True


def bench_rps(n: int, ticks: int, seed: int = 0, warmup: int = 10) -> SimBenchRow:
    """Time the Robotarium simulator's loop with its unicycle barrier at every step."""
    import matplotlib

    matplotlib.use("Agg")
    from rps import robotarium
    from rps.utilities.barrier_certificates import create_unicycle_barrier_certificate_with_boundary
    from rps.utilities.controllers import create_si_position_controller
    from rps.utilities.misc import generate_initial_conditions
    from rps.utilities.transformations import create_si_to_uni_mapping

    rng = np.random.default_rng(seed)
    np.random.seed(seed)  # rps draws its initial conditions from the global generator
    x0 = generate_initial_conditions(n, spacing=0.3, width=3.0, height=1.8)
    r = robotarium.Robotarium(number_of_robots=n, show_figure=False, initial_conditions=x0, sim_in_real_time=False)
    controller = create_si_position_controller(velocity_magnitude_limit=0.15)
    si_to_uni, uni_to_si_states = create_si_to_uni_mapping()
    barrier = create_unicycle_barrier_certificate_with_boundary()
    goals = _goals(rng, n).T
    times = []
    for k in range(warmup + ticks):
        if k % _REDRAW == _REDRAW - 1:
            goals = _goals(rng, n).T
        t0 = time.perf_counter()
        x = r.get_poses()
        xi = uni_to_si_states(x)
        dxi = controller(xi, goals)
        dxu = barrier(si_to_uni(dxi, x), x)
        r.set_velocities(np.arange(n), dxu)
        r.step()
        if k >= warmup:
            times.append(time.perf_counter() - t0)
    total = float(np.median(times)) * 1e6
    return SimBenchRow(
        system="robotarium-rps",
        tier="euler",
        n_robots=n,
        batch=1,
        tick_us=total,
        physics_us=float("nan"),
        filter_us=float("nan"),
        rest_us=float("nan"),
        per_robot_tick_us=total / n,
        robot_s_per_wall_s=n * C.CONTROL_DT_S / (total * 1e-6),
        ticks=ticks,
    )


def _table(rows: list[SimBenchRow], rps: dict[int, SimBenchRow]) -> str:
    head = (
        f"{'system':<15}{'tier':<9}{'reality':<9}{'N':>4}{'B':>4}{'tick µs':>11}{'physics':>10}{'filter':>9}{'rest':>8}"
        f"{'rest %':>8}{'µs/robot-tick':>15}{'robot-s/s':>11}{'vs rps':>8}"
    )
    lines = [head, "-" * len(head)]
    for r in rows:
        ratio = (
            rps[r.n_robots].per_robot_tick_us / r.per_robot_tick_us
            if r.n_robots in rps and r.system == "comat" and r.reality == "off"
            else float("nan")
        )
        rest_pct = 100 * r.rest_us / r.tick_us if r.system == "comat" else float("nan")
        lines.append(
            f"{r.system:<15}{r.tier:<9}{r.reality:<9}{r.n_robots:>4}{r.batch:>4}{r.tick_us:>11.0f}{r.physics_us:>10.0f}"
            f"{r.filter_us:>9.0f}{r.rest_us:>8.0f}{rest_pct:>8.1f}{r.per_robot_tick_us:>15.1f}"
            f"{r.robot_s_per_wall_s:>11.1f}{ratio:>8.1f}"
        )
    return "\n".join(lines)


def run_sim_bench(
    sizes: tuple[int, ...] = (2, 4, 8, 16, 32),
    batches: tuple[int, ...] = (1, 64),
    tiers: tuple[str, ...] = ("wheels", "unicycle"),
    ticks: int = 100,
    rps_ticks: int = 100,
    out: str | None = None,
    progress=print,
    reality_sizes: tuple[int, ...] = (8,),
) -> dict:
    """Run the grid, print a table, write JSON to ``out``; return the JSON dict. Team sizes in
    ``reality_sizes`` get a ``nominal`` row next to each ``off`` one."""
    rows: list[SimBenchRow] = []
    rps_rows: dict[int, SimBenchRow] = {}
    have_rps = rps_available()
    for n in sizes:
        for tier in tiers:
            for b in batches:
                progress(f"  comat {tier:<8} N={n:<3} B={b:<3} ...")
                rows.append(bench_ours(tier, n, b, ticks))
                if n in reality_sizes:
                    progress(f"  comat {tier:<8} N={n:<3} B={b:<3} reality=nominal ...")
                    rows.append(bench_ours(tier, n, b, ticks, reality="nominal"))
        if have_rps:
            progress(f"  rps            N={n:<3} B=1   ...")
            rps_rows[n] = bench_rps(n, rps_ticks)
    all_rows = rows + list(rps_rows.values())
    checks = _checks(rows, rps_rows)
    result = {
        "benchmark": "sim",
        "machine": {"platform": platform.platform(), "python": platform.python_version(), "cpus": os.cpu_count()},
        "threads": "1 (OMP/MKL/OpenBLAS), MuJoCo batch nthread=1, OSQP single-threaded",
        "rps": "robotarium-python-simulator 0.0.0 (PyPI, legacy 2020 rps)" if have_rps else "not installed",
        "rows": [asdict(r) for r in all_rows],
        "checks": checks,
    }
    progress(_table(all_rows, rps_rows))
    if not have_rps:
        progress("  (rps not installed: `pip install -e .[robotarium]` for the Robotarium comparison)")
    return finish(result, checks, out, progress)


def _checks(rows: list[SimBenchRow], rps: dict[int, SimBenchRow]) -> dict:
    def find(tier, n, b, reality="off"):
        return next(
            (r for r in rows if r.tier == tier and r.n_robots == n and r.batch == b and r.reality == reality), None
        )

    checks = {}
    for tier in ("wheels", "unicycle"):
        r = find(tier, 8, 64)
        if r:
            checks[f"python_overhead_share_{tier}_B64_N8"] = {
                "value": r.rest_us / r.tick_us,
                "target": "<= 0.25",
                "pass": r.rest_us / r.tick_us <= 0.25,
            }
    w, u = find("wheels", 8, 64), find("unicycle", 8, 64)
    if w and u:
        checks["unicycle_cheaper_than_wheels_B64_N8"] = {
            "value": w.tick_us / u.tick_us,
            "target": ">= 4",
            "pass": w.tick_us / u.tick_us >= 4,
        }
    if 8 in rps:
        for tier in ("wheels", "unicycle"):
            r = find(tier, 8, 64)
            if r:
                ratio = rps[8].per_robot_tick_us / r.per_robot_tick_us
                checks[f"faster_than_rps_per_robot_tick_{tier}_B64_N8"] = {
                    "value": ratio,
                    "target": ">= 5",
                    "pass": ratio >= 5,
                }
    # The reality layer's cost (issue 29): at most 15 % on the tick.
    for tier in ("wheels", "unicycle"):
        off, nominal = find(tier, 8, 64), find(tier, 8, 64, "nominal")
        if off and nominal:
            ratio = nominal.tick_us / off.tick_us
            checks[f"reality_overhead_{tier}_B64_N8"] = {"value": ratio, "target": "<= 1.15", "pass": ratio <= 1.15}
    # The barrier scales (comat.safety.sparse): 4x the robots may cost at most 6x the tick and 8x
    # the filter (all-pairs QP: 12.2x and 37x).
    small, large = find("unicycle", 8, 64), find("unicycle", 32, 64)
    if small and large:
        for part, attr, limit in (("tick", "tick_us", 6.0), ("filter", "filter_us", 8.0)):
            ratio = getattr(large, attr) / max(getattr(small, attr), 1e-9)
            checks[f"{part}_N32_over_N8_unicycle_B64"] = {
                "value": ratio,
                "target": f"<= {limit}",
                "pass": ratio <= limit,
            }
    return checks


def finish(result: dict, checks: dict, out: str | None, progress=print) -> dict:
    """Print every check as PASS/FAIL and write ``result`` as JSON to ``out`` (if given)."""
    for name, c in checks.items():
        progress(f"  {'PASS' if c['pass'] else 'FAIL'}  {name}: {c['value']:.3g} (target {c['target']})")
    if out:
        _write_json(out, result)
        progress(f"wrote {out}")
    return result


def _write_json(path: str, data: dict) -> None:
    from pathlib import Path

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(p, json.dumps(data, indent=2, default=float) + "\n")
