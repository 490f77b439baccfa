"""The calibrated-training study's table and test (PLAN.md): reads KEEP/runs/<arm>_s<seed>/eval_<layer>/
evaluation_*.json (run.sh writes them) and writes KEEP/results.md.

Per arm, seed, set and layer: the policy's progress (%, mean over the set's coalitions). Per seed and
held-out layer: the gap, progress in the ideal world (off) minus progress under the layer (points).
Per layer and set: Welch's t-test of the calibrated arm's per-seed gaps against the nominal arm's
(comat.measure.stats.welch; the seed is the replicated unit), and the same test on progress under the
layer itself. The primary endpoint is the gap under ``truth`` on U_test; the other layers and sets are
secondary, Holm-adjusted as one family (comat.measure.stats.holm).

    .venv/bin/python results/calibrated_training/analyze.py results/calibrated_training [--arms nominal calibrated]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from comat.measure.stats import holm, welch

LAYERS = ("truth", "refit_s1", "stress", "shifted")
"""The held-out layers (PLAN.md), in the order of the table; ``off`` is the gap's reference."""
PRIMARY = ("truth", "test")
SETS = ("train", "test")


def progress_of(path: Path) -> dict[str, float]:
    """Set -> the learned policy's progress (%) in one evaluation file; ``collisions/<set>``: its
    contacts per episode (the safety guard)."""
    data = json.loads(path.read_text())
    out = {}
    for row in data["rows"]:
        if row["policy"] in ("heuristic", "type_only", "blind", "constant", "random"):
            continue
        out[row["set"]] = 100.0 * float(row["metrics"]["progress"]["mean"])
        out[f"collisions/{row['set']}"] = float(row["metrics"]["collisions"]["mean"])
    return out


def collect(keep: Path, arms: list[str]) -> dict:
    """(arm, seed) -> layer -> set -> progress %, for every kept run of ``arms``."""
    table = {}
    for arm in arms:
        for run in sorted((keep / "runs").glob(f"{arm}_s*")):
            if run.name.endswith(".partial"):
                continue
            seed = int(run.name.rsplit("_s", 1)[1])
            per = {}
            for layer in ("off", *LAYERS):
                files = [f for f in (run / f"eval_{layer}").glob("evaluation_*.json") if ".episodes" not in f.name]
                if len(files) != 1:
                    raise ValueError(f"{run}/eval_{layer}: expected one evaluation file, got {len(files)}")
                per[layer] = progress_of(files[0])
            table[arm, seed] = per
    return table


def _fmt(x: float, digits: int = 1, sign: str = "") -> str:
    """``x`` with ``digits`` decimals (``sign="+"``: always signed); — where undefined."""
    return "—" if not math.isfinite(x) else f"{x:{sign}.{digits}f}"


def markdown(table: dict, arms: list[str], base: str = "nominal", test: str = "calibrated") -> str:
    """The results page: the per-seed table, then the tests."""
    lines = [
        "# Calibrated training: the gap to held-out layers (results; PLAN.md says what was fixed before)",
        "",
        "Progress % (mean over the set's coalitions) per arm, seed, set and layer; gap = off − layer (points).",
        "",
        "| arm | seed | set | off | " + " | ".join(LAYERS) + " | " + " | ".join(f"gap {x}" for x in LAYERS) + " |",
        "|---" * (4 + 2 * len(LAYERS)) + "|",
    ]
    sets = [s for s in SETS if any(s in v["off"] for v in table.values())]
    for (arm, seed), per in sorted(table.items()):
        for s in sets:
            off = per["off"].get(s, math.nan)
            cells = [_fmt(per[x].get(s, math.nan)) for x in LAYERS]
            gaps = [_fmt(off - per[x].get(s, math.nan)) for x in LAYERS]
            lines.append(f"| {arm} | {seed} | U_{s} | {_fmt(off)} | " + " | ".join(cells + gaps) + " |")
    worst = {
        x: max(per[x].get(f"collisions/{s}", 0.0) for per in table.values() for s in sets) for x in ("off", *LAYERS)
    }
    lines += [
        "",
        "Contacts per episode, the largest over runs and sets (the guard): "
        + ", ".join(f"{x} {v:.2f}" for x, v in worst.items())
        + ".",
    ]
    if base not in arms or test not in arms:
        return "\n".join(lines) + "\n"
    lines += [
        "",
        f"## {test} − {base}, Welch over seeds (95 % interval; p two-sided; Holm over the secondary family)",
        "",
        "| layer | set | endpoint | seeds | mean "
        + base
        + " | mean "
        + test
        + " | difference | 95 % interval | p | p Holm |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    rows = []
    for layer in LAYERS:
        for s in sets:
            for endpoint in ("gap", "progress"):

                def value(per, layer=layer, s=s, endpoint=endpoint):
                    v = per[layer].get(s, math.nan)
                    return per["off"].get(s, math.nan) - v if endpoint == "gap" else v

                a = [value(per) for (arm, _), per in sorted(table.items()) if arm == test]
                b = [value(per) for (arm, _), per in sorted(table.items()) if arm == base]
                rows.append((layer, s, endpoint, a, b, welch(a, b)))
    primary = [i for i, r in enumerate(rows) if (r[0], r[1]) == PRIMARY and r[2] == "gap"]
    secondary = [i for i in range(len(rows)) if i not in primary]
    adjusted = dict(zip(secondary, holm([rows[i][5]["p"] for i in secondary]))) if secondary else {}
    for i, (layer, s, endpoint, a, b, w) in enumerate(rows):
        mark = " (primary)" if i in primary else ""
        lines.append(
            f"| {layer} | U_{s} | {endpoint}{mark} | {len(b)} / {len(a)} | {_fmt(float(np.mean(b)))} | "
            f"{_fmt(float(np.mean(a)))} | {_fmt(w['diff'], 1, '+')} | [{_fmt(w['lo'], 1, '+')}, {_fmt(w['hi'], 1, '+')}] | "
            f"{_fmt(w['p'], 3)} | {'—' if i in primary else _fmt(adjusted[i], 3)} |"
        )
    lines += [
        "",
        (
            "A negative gap difference: the calibrated arm loses less to the layer than the nominal arm. "
            "With fewer than 2 seeds in an arm there is no test (—)."
        ),
    ]
    return "\n".join(lines) + "\n"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("keep", type=Path, help="the folder run.sh keeps the runs in (KEEP)")
    p.add_argument("--arms", nargs="+", default=["nominal", "calibrated"])
    args = p.parse_args()
    table = collect(args.keep, args.arms)
    if not table:
        raise SystemExit(f"analyze.py: no kept runs of {args.arms} under {args.keep / 'runs'}")
    (args.keep / "results.md").write_text(markdown(table, args.arms))
    print(f"wrote {args.keep / 'results.md'} ({len(table)} runs)")


if __name__ == "__main__":
    main()
