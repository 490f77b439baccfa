"""``comat bench fidelity``: steady-state tracking and trajectory spread, both tiers (JSON + table)."""

from __future__ import annotations

import numpy as np

from comat.bench.fidelity import steady_state, trajectory_errors
from comat.bench.sim_bench import _write_json
from comat.config import SimConfig

__all__ = ["run_fidelity_bench"]


def run_fidelity_bench(seeds: int = 50, out: str | None = None, progress=print) -> dict:
    """Measure both tiers; print a table; write JSON to ``out``."""
    result: dict = {"benchmark": "fidelity", "seeds": seeds, "tiers": {}}
    for tier in ("unicycle", "wheels"):
        cfg = SimConfig(tier=tier)
        progress(f"  {tier}: steady state over a 9x9 grid of wheel speeds ...")
        st = steady_state(cfg, grid=9)
        progress(f"  {tier}: {seeds} random 10 s command sequences ...")
        err = trajectory_errors(cfg, range(seeds))
        stats = {
            k: {
                "mean_m": float(v.mean()),
                "p90_m": float(np.percentile(v, 90)),
                "max_m": float(v.max()),
                "share_within_1cm": float(np.mean(v < 0.01)),
            }
            for k, v in err.items()
        }
        result["tiers"][tier] = {
            "substeps": cfg.resolved_substeps,
            "steady_state": {
                "rel_error": float(st.rel_error),
                "abs_error": float(st.abs_error),
                "lateral_mps": float(st.lateral_mps),
            },
            "trajectory": stats,
        }
    progress(
        f"{'tier':<10}{'dt ms':>7}{'v,ω rel err':>13}{'lateral mm/s':>14}   trajectory error over {seeds} sequences "
        "(mean / p90 / max mm, share < 1 cm)"
    )
    for tier, r in result["tiers"].items():
        st = r["steady_state"]
        progress(f"{tier:<10}{33.0 / r['substeps']:>7.2f}{st['rel_error']:>13.2e}{st['lateral_mps'] * 1e3:>14.4f}")
        for k, s in r["trajectory"].items():
            progress(
                f"{'':<44}{k:<17} {s['mean_m'] * 1e3:5.1f} / {s['p90_m'] * 1e3:5.1f} / {s['max_m'] * 1e3:5.1f}   "
                f"{s['share_within_1cm']:.0%}"
            )
    if out:
        _write_json(out, result)
        progress(f"wrote {out}")
    return result
