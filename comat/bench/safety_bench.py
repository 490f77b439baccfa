"""``comat bench safety``: the safety battery at reality levels, judged on true poses.

Every scenario of :data:`comat.bench.scenarios.SCENARIOS` (safe starts),
:data:`~comat.bench.scenarios.FAULTS` (safe starts with a fault: a robot that stops, Wi-Fi
dropouts, a stopped robot whose pose freezes, repeats without noise) and
:data:`~comat.bench.scenarios.UNSAFE_STARTS`, ``--episodes`` each, through each loop (comat's own
filter, and the loops an export runs: ``SafetyConfig.loop``), in each tier and at each reality
level. Per scenario: episodes, those that really started inside the loop's safe set
(the start error can move a requested safe start out of it), MuJoCo robot–robot contacts,
Robotarium-style collisions (pair-ticks), boundary exits, wall contacts, actuator errors (each
for safe starts and for all episodes), the closest true projected points, recovery and fallback
ticks, interventions, and the median distance left to the goals. The check: zero
contacts and zero Robotarium collisions over the safe-start episodes of every safe-start
scenario, per loop and level.

Liveness beside safety (:mod:`comat.bench.liveness`), in every scenario whose goals can all be
held at once — the swaps, ``ring20`` and the dense crossings of
:data:`~comat.bench.scenarios.CROSSINGS` (antipodal swaps of 16 and 20, lanes, a doorway): the
share of robots at their goal within 1× and 2× the time the same episodes need at ``off`` (so
``off`` runs first, and a level's live scenarios run at least 2 × that time), team freezes and
recovery ticks.
"""

from __future__ import annotations

import json
import time

import numpy as np

from comat.bench.liveness import arrival_lists, row_liveness
from comat.bench.scenarios import FAULTS, SCENARIOS, make_scenario, run_scenario
from comat.config import SafetyConfig, SimConfig
from comat.control import SafeTeams
from comat.files import write_atomic
from comat.reality.config import RealityConfig, resolve_reality

__all__ = [
    "CROSSING_NAMES",
    "DEFAULT_LOOPS",
    "MISMATCHES",
    "SCENARIO_NAMES",
    "liveness_table",
    "loops_table",
    "mismatch_table",
    "run_mismatch",
    "run_safety_bench",
]

SCENARIO_NAMES = (
    "head_on",
    "swap4",
    "swap8",
    "converge16",
    "converge32",
    "walls",
    "ring20",
    "bangbang16",
    "corner",
    "stop_swap4",
    "stop_converge16",
    "dropout_swap4",
    "frozen_stop_swap4",
    "exact_swap4",
    "exact_bangbang16",
    "stall_converge16",
    "stall_bangbang16",
    "inside",
)
"""The battery's scenarios (those of comat.bench.scenarios, named here so that the command line
is built without importing the simulator; a test keeps the two equal)."""
CROSSING_NAMES = ("antipodal16", "antipodal20", "lanes12", "pinch12")
"""The dense crossings (:data:`comat.bench.scenarios.CROSSINGS`), run after the battery's own."""
DEFAULT_LOOPS = ("comat", "robotarium_v2", "shipped_v2")
SLOW_2X = {
    "pose_delay_ticks": 3,
    "pose_delay_spread_ticks": 2,
    "command_delay_ticks": 2,
    "command_delay_spread_ticks": 1,
    "motor_tau_min_s": 0.15,
    "motor_tau_max_s": 0.25,
}
"""A plant about twice as slow as ``nominal`` (the 2026-12b review's probe): pose delay 3 + Bin(2),
command delay 2–3 ticks, motor lag τ 0.15–0.25 s."""
MISMATCHES = {
    "nominal_in_stress": ("nominal", {"level": "stress"}, None),
    "nominal_in_slow2x": ("nominal", {"level": "nominal", **SLOW_2X}, None),
    "nominal_wrong_way": ("nominal", {"level": "nominal"}, 30),
    "nominal_speed25": (
        "nominal",
        {"level": "nominal", "fault_prob": 1.0, "fault_speed_fraction": 0.25, "fault_start_min_s": 0.5,
         "fault_start_max_s": 4.0},
        None,
    ),
    "stress_in_nominal": ("stress", {"level": "nominal"}, None),
}  # fmt: skip
""""Built for X, run in Y": name → (the level the filter is made for, the world's reality fields,
the tick from which each team's first robot drives the wrong way or None). The 25 %-speed robot
is one per team (``fault_prob`` 1), from 0.5–4 s on; ``stress_in_nominal`` shows what caution costs."""
MISMATCH_SCENARIOS = ("swap4", "converge16", "bangbang16", "antipodal16", "lanes12")
"""comat's filter, the export's main.py with the Robotarium's V2 barrier, and with comat's shipped filter."""


def _row(
    name: str,
    tier: str,
    level,
    episodes: int,
    seed: int,
    loop: str = "comat",
    ticks: int | None = None,
    **mismatch,
) -> dict:
    """One scenario at one level (a name or a config) through one loop (``ticks``: at least this
    many, for liveness; ``mismatch``: :func:`run_scenario`'s ``filter_reality``, ``wrong_way_tick``)."""
    scn = make_scenario(name, episodes, seed=seed)
    if ticks is not None and ticks > scn.ticks:
        scn.ticks = ticks
    t0 = time.perf_counter()
    r = run_scenario(scn, SimConfig(tier=tier), SafetyConfig(loop=loop), reality=level, seed=seed, **mismatch)
    level = level if isinstance(level, str) else level.level + "+fields"
    s = r.safe_start

    def both(x: np.ndarray) -> dict:
        return {"safe_starts": int(x[s].sum()), "all": int(x.sum())}

    return {
        "scenario": name,
        "loop": loop,
        "tier": tier,
        "reality": level,
        "episodes": episodes,
        "seed": seed,
        "fault": FAULTS[name][1] if name in FAULTS else None,
        "safe_start_scenario": name in SCENARIOS or name in FAULTS,
        "safe_starts": int(s.sum()),
        "episodes_hit": int(((r.robot_contacts + r.robotarium_collisions)[s] > 0).sum()),
        "per_episode_hits": (r.robot_contacts + r.robotarium_collisions).astype(int).tolist(),
        "first_collision": next(
            (
                {"episode": b, "tick": c[0], "robots": [c[1], c[2]]}
                for b, c in enumerate(r.first_collision)
                if c is not None and s[b]
            ),
            None,
        ),
        "min_centre_distance_m": float(r.min_centre_distance[s].min()) if s.any() else None,
        "robot_contacts": both(r.robot_contacts),
        "robotarium_collisions": both(r.robotarium_collisions),
        "boundary_exits": both(r.boundary_exits),
        "wall_contacts": both(r.wall_contacts),
        "actuator_errors": both(r.actuator_errors),
        "min_point_distance_m": {
            "safe_starts": float(r.min_point_distance[s].min()) if s.any() else None,
            "all": float(r.min_point_distance.min()),
        },
        "recovery_ticks": int(r.recoveries.sum()),
        "fallback_ticks": int(r.fallbacks.sum()),
        "interventions": int(r.interventions.sum()),
        "team_ticks": int(s.size * scn.ticks),
        "median_goal_error_m": float(np.median(r.goal_error)),
        "ticks": scn.ticks,
        "live": scn.live,
        "arrival": arrival_lists(r.arrival, r.movers, scn.team_sizes) if scn.live else None,
        "freezes": int(r.freezes.sum()) if scn.live else None,
        "freeze_episodes": int((r.freezes > 0).sum()) if scn.live else None,
        "frozen_team_ticks": int(r.frozen_ticks.sum()) if scn.live else None,
        "seconds": round(time.perf_counter() - t0, 1),
    }


def run_safety_bench(
    levels: tuple[str, ...],
    tiers: tuple[str, ...],
    episodes: int,
    seed: int,
    out: str,
    scenarios: tuple[str, ...] | None = None,
    loops: tuple[str, ...] = ("comat",),
) -> dict:
    # long: the battery's loop and the result() it rebuilds from the shared rows after each scenario
    """Run the battery, print a table row per scenario and loop, write ``out`` (JSON) and return it.

    ``out`` is rewritten after every row, so an interrupted run keeps what it measured."""

    names = scenarios or SCENARIO_NAMES + CROSSING_NAMES
    levels = tuple(sorted(levels, key=lambda lv: lv != "off"))  # off first: the liveness reference
    rows: list[dict] = []
    print(
        f"{'level':8s} {'tier':9s} {'scenario':18s} {'loop':18s} {'safe':>7s} {'hit':>4s} {'contacts':>9s} "
        f"{'rob.coll':>9s} {'exits':>6s} {'min d (m)':>9s} {'recov':>6s} {'brake':>6s} {'goal (m)':>8s} "
        f"{'live 1x':>7s} {'2x':>5s} {'frz':>4s}"
    )
    filters = {lv: _filter_settings(lv) for lv in levels}

    def result() -> dict:
        checks = {}
        for level in levels:
            for loop in loops:
                safe = [r for r in rows if r["reality"] == level and r["loop"] == loop and r["safe_start_scenario"]]
                bad = sum(r["robot_contacts"]["safe_starts"] + r["robotarium_collisions"]["safe_starts"] for r in safe)
                hit = [
                    f"{r['scenario']} (episode {r['first_collision']['episode']}, robots "
                    f"{r['first_collision']['robots'][0]} and {r['first_collision']['robots'][1]}, tick "
                    f"{r['first_collision']['tick']})"
                    if r["first_collision"]
                    else r["scenario"]
                    for r in safe
                    if r["episodes_hit"]
                ]
                checks[f"safe_starts_clean_{level}" + ("" if loop == "comat" else f"_{loop}")] = {
                    "contacts_plus_collisions": bad,
                    "scenarios_hit": hit,
                    "pass": bad == 0,
                }
        targets = {}
        for loop in loops:
            live = [r for r in rows if r["loop"] == loop and r.get("liveness")]
            for r in live:
                off = _off_row(rows, r["scenario"], r["tier"], loop)
                r["liveness"]["ratio_2x"] = (
                    r["liveness"]["2x"] / off["liveness"]["2x"] if off and off["liveness"]["2x"] > 0 else None
                )
            nominal = [r for r in live if r["reality"] == "nominal"]
            stress = [r for r in live if r["reality"] == "stress"]
            suffix = "" if loop == "comat" else f"_{loop}"
            if nominal:
                low = [
                    r["scenario"]
                    for r in nominal
                    if r["liveness"]["ratio_2x"] is not None and r["liveness"]["ratio_2x"] < 0.9
                ]
                none = [r["scenario"] for r in nominal if r["liveness"]["ratio_2x"] is None]
                targets["live_nominal_2x_at_least_90pct_of_off" + suffix] = {
                    "below": low,
                    "no_off_arrival": none,
                    "met": not low,
                }
            if stress:
                frozen = [r["scenario"] for r in stress if r["freezes"]]
                targets["no_team_freezes_stress" + suffix] = {"frozen": frozen, "met": not frozen}
        return {
            "levels": list(levels),
            "tiers": list(tiers),
            "loops": list(loops),
            "episodes": episodes,
            "seed": seed,
            "filter": filters,
            "rows": rows,
            "checks": checks,
            "liveness_targets": targets,
        }

    for level in levels:
        for tier in tiers:
            for name in names:
                for loop in loops:
                    off = _off_row(rows, name, tier, loop)
                    ticks = None
                    if off is not None and off["live"] and level != "off":
                        ticks = 2 * max(_t_off(off)) + 1
                    row = _row(name, tier, level, episodes, seed, loop, ticks)
                    off = row if level == "off" else off
                    if row["live"] and off is not None:
                        row["liveness"] = row_liveness(row["arrival"], off["arrival"], off["ticks"], row["ticks"])
                    rows.append(row)
                    d = row["min_point_distance_m"]["safe_starts"]
                    lv = row.get("liveness")
                    live = (
                        f"{lv['1x']:>7.2f} {lv['2x']:>5.2f} {row['freezes']:>4d}"
                        if lv
                        else f"{'—':>7s} {'—':>5s} {'—':>4s}"
                    )
                    print(
                        f"{level:8s} {tier:9s} {name:18s} {loop:18s} {row['safe_starts']:>3d}/{episodes:<3d} "
                        f"{row['episodes_hit']:>4d} "
                        f"{row['robot_contacts']['safe_starts']:>4d}|{row['robot_contacts']['all']:<4d} "
                        f"{row['robotarium_collisions']['safe_starts']:>4d}|{row['robotarium_collisions']['all']:<4d} "
                        f"{row['boundary_exits']['all']:>6d} {d if d is not None else float('nan'):>9.4f} "
                        f"{row['recovery_ticks']:>6d} {row['fallback_ticks']:>6d} {row['median_goal_error_m']:>8.3f} "
                        + live,
                        flush=True,
                    )
                    write_atomic(out, json.dumps(result(), indent=1) + "\n")
    final = result()
    write_atomic(out, json.dumps(final, indent=1) + "\n")
    for name, c in final["checks"].items():
        where = f"; hit: {', '.join(c['scenarios_hit'])}" if c["scenarios_hit"] else ""
        print(
            f"{name}: {'pass' if c['pass'] else 'FAIL'} ({c['contacts_plus_collisions']} contacts + collisions{where})"
        )
    for name, t in final["liveness_targets"].items():
        miss = t.get("below") or t.get("frozen")
        print(f"{name}: {'met' if t['met'] else 'NOT met'}" + (f" ({', '.join(miss)})" if miss else ""))
    print(f"wrote {out}")
    return final


def loops_table(result: dict, level: str, tier: str = "unicycle") -> str:
    """Markdown: a row per scenario, the loops side by side (episodes with a contact or a
    Robotarium collision / safe-start episodes, closest true projected points, median distance left
    to the goals), at ``level`` in ``tier``, from :func:`run_safety_bench`'s result."""
    rows = [r for r in result["rows"] if r["reality"] == level and r["tier"] == tier]
    loops = [lp for lp in result["loops"] if any(r["loop"] == lp for r in rows)]
    head = "| scenario | " + " | ".join(f"{lp}: hit / safe, closest (m), goal (m)" for lp in loops) + " |"
    lines = [head, "|---|" + "---|" * len(loops)]
    for name in dict.fromkeys(r["scenario"] for r in rows):
        cells = []
        for lp in loops:
            r = next((x for x in rows if x["scenario"] == name and x["loop"] == lp), None)
            if r is None:
                cells.append("")
                continue
            d = r["min_point_distance_m"]["safe_starts"]
            hit = r["episodes_hit"] if r["safe_start_scenario"] else "—"
            cells.append(
                f"{hit} / {r['safe_starts']}, {'—' if d is None else f'{d:.3f}'}, {r['median_goal_error_m']:.2f}"
            )
        lines.append(f"| `{name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def run_mismatch(
    episodes: int,
    seed: int,
    out: str,
    scenarios: tuple[str, ...] = MISMATCH_SCENARIOS,
    loops: tuple[str, ...] = ("comat",),
    tier: str = "unicycle",
) -> dict:
    """The mismatch battery (:data:`MISMATCHES`): each scenario at ``off`` (the liveness reference),
    then in each mismatch; collisions (episodes with a MuJoCo contact or a Robotarium collision, over
    all episodes: the world's start error, not the filter, decides which started in its safe set),
    the closest true points, recoveries, fallbacks and liveness. Writes ``out`` after every row."""
    rows: list[dict] = []

    def result() -> dict:
        return {"mismatches": {k: [v[0], v[1], v[2]] for k, v in MISMATCHES.items()}, "rows": rows,
                "episodes": episodes, "seed": seed, "tier": tier, "loops": list(loops)}  # fmt: skip

    print(f"{'case':18s} {'scenario':12s} {'loop':10s} {'hit':>4s} {'min d (m)':>9s} {'recov':>6s} {'brake':>6s} "
          f"{'live 1x':>7s} {'2x':>5s} {'frz':>4s}")  # fmt: skip
    for name in scenarios:
        for loop in loops:
            off = _row(name, tier, "off", episodes, seed, loop)
            off["case"] = "off"
            if off["live"]:
                off["liveness"] = row_liveness(off["arrival"], off["arrival"], off["ticks"], off["ticks"])
            rows.append(off)
            for case, (design, world, wrong) in MISMATCHES.items():
                ticks = 2 * max(_t_off(off)) + 1 if off["live"] else None
                row = _row(name, tier, resolve_reality(world), episodes, seed, loop, ticks,
                           filter_reality=design, wrong_way_tick=wrong)  # fmt: skip
                row["case"] = case
                if row["live"]:
                    row["liveness"] = row_liveness(row["arrival"], off["arrival"], off["ticks"], row["ticks"])
                rows.append(row)
                lv = row.get("liveness")
                hit = int(((np.array(row["per_episode_hits"])) > 0).sum())
                live = f"{lv['1x']:>7.2f} {lv['2x']:>5.2f} {row['freezes']:>4d}" if lv else f"{'—':>7s} {'—':>5s}"
                print(f"{case:18s} {name:12s} {loop:10s} {hit:>4d} {row['min_point_distance_m']['all']:>9.4f} "
                      f"{row['recovery_ticks']:>6d} {row['fallback_ticks']:>6d} " + live, flush=True)  # fmt: skip
                write_atomic(out, json.dumps(result(), indent=1) + "\n")
    final = result()
    write_atomic(out, json.dumps(final, indent=1) + "\n")
    print(f"wrote {out}")
    return final


def mismatch_table(result: dict, loop: str = "comat") -> str:
    """Markdown: a row per mismatch case and scenario: episodes with a contact or collision (all
    episodes), closest true points, recovery / brake ticks, at goal within 1× / 2× the ``off`` time."""
    lines = [
        "| case | scenario | hit / episodes | closest (m) | recoveries / brakes | at goal 1× / 2× off time | freezes |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        if r["loop"] != loop or r["case"] == "off":
            continue
        lv = r.get("liveness")
        live = f"{100 * lv['1x']:.0f} % / {100 * lv['2x']:.0f} %" if lv else "—"
        hit = int((np.array(r["per_episode_hits"]) > 0).sum())
        lines.append(
            f"| {r['case']} | `{r['scenario']}` | {hit} / {r['episodes']} | {r['min_point_distance_m']['all']:.3f} | "
            f"{r['recovery_ticks']} / {r['fallback_ticks']} | {live} | {r['freezes'] if lv else '—'} |"
        )
    return "\n".join(lines) + "\n"


def _off_row(rows: list[dict], name: str, tier: str, loop: str) -> dict | None:
    return next(
        (
            r
            for r in rows
            if r["reality"] == "off" and r["scenario"] == name and r["tier"] == tier and r["loop"] == loop
        ),
        None,
    )


def _t_off(off: dict) -> list[int]:
    """Per episode of an ``off`` row, the tick its last arriving mover arrived (its horizon if none)."""
    return [max((t for t in ep if t is not None and t >= 0), default=off["ticks"]) for ep in off["arrival"]]


def liveness_table(result: dict, loop: str = "comat", tier: str = "unicycle") -> str:
    """Markdown: a row per live scenario, per level the share of movers at their goal within 1× / 2×
    the ``off`` time, team freezes (episodes with one / onsets) and recovery ticks."""
    rows = [r for r in result["rows"] if r["loop"] == loop and r["tier"] == tier and r.get("liveness")]
    levels = [lv for lv in result["levels"] if any(r["reality"] == lv for r in rows)]
    head = "| scenario | off time (median s) | " + " | ".join(
        f"{lv}: at goal 1× / 2×, freezes (episodes / onsets), recoveries" for lv in levels
    )
    lines = [head + " |", "|---|---|" + "---|" * len(levels)]
    for name in dict.fromkeys(r["scenario"] for r in rows):
        cells, t_off = [], ""
        for lv in levels:
            r = next((x for x in rows if x["scenario"] == name and x["reality"] == lv), None)
            if r is None:
                cells.append("")
                continue
            x = r["liveness"]
            t_off = f"{x['t_off_median_s']:.1f}"
            cap = f" ({x['capped']} capped)" if x["capped"] and lv != "off" else ""
            cells.append(
                f"{100 * x['1x']:.0f} % / {100 * x['2x']:.0f} %{cap}, {r['freeze_episodes']} / {r['freezes']}, "
                f"{r['recovery_ticks']}"
            )
        lines.append(f"| `{name}` | {t_off} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _filter_settings(level: str) -> dict:
    """The filter's distance, gains and boundary margin at ``level`` (one robot, for the record)."""

    cfg = SafeTeams((1,), reality=RealityConfig(level=level)).filter_config
    return {k: getattr(cfg, k) for k in ("safety_distance_m", "barrier_gain", "boundary_gain", "boundary_margin_m")}
