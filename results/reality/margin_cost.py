"""What the filter's reality margin costs the tasks (issue 29 part 2): the scripted heuristic on
U_train and U_test of both tasks, 5 episodes per coalition, unicycle tier, at off, at nominal
with the robust filter (the default) and at nominal with SafetyConfig(robust=False), paired
episodes (same teams and requested starts). Writes margin_cost.json and prints a table.

    python results/reality/margin_cost.py
"""

import json
import sys
from pathlib import Path

from comat.config import SafetyConfig
from comat.eval import evaluate_policies

# progress: share of the task done; finished: share of episodes that finished it.
ENDPOINTS = ("progress", "finished", "steps", "interventions", "collisions", "violations", "recoveries")
rows = []
for task in ("pcp", "hmt"):
    for label, reality, safety in (
        ("off", "off", None),
        ("nominal", "nominal", None),
        ("nominal, no margin", "nominal", SafetyConfig(robust=False)),
    ):
        res = evaluate_policies(
            None,
            task=task,
            sets=("train", "test"),
            episodes=5,
            tier="unicycle",
            references=("heuristic",),
            reality=reality,
            safety=safety,
            progress=lambda *a: None,
        )
        for r in res["rows"]:
            m = r["metrics"]
            row = {
                "task": task,
                "filter": label,
                "set": r["set"],
                "episodes": len(r["per_episode"]),
                **{k: m[k]["mean"] for k in ENDPOINTS},
                **{f"{k}_ci95": m[k]["ci95"] for k in ENDPOINTS},
                "robotarium_collisions_total": sum(e["robotarium_collisions"] for e in r["per_episode"]),
                "contacts_total": sum(e["collisions"] for e in r["per_episode"]),
            }
            rows.append(row)
            print(
                f"{task} {r['set']:6s} {label:19s} progress {row['progress']:.3f} finished {row['finished']:.2f} "
                f"steps {row['steps']:.1f} interventions {row['interventions']:.0f} contacts "
                f"{row['contacts_total']:.0f} robotarium collisions {row['robotarium_collisions_total']:.0f}",
                flush=True,
            )
Path(__file__).with_name("margin_cost.json").write_text(json.dumps(rows, indent=1) + "\n")
sys.exit(0)
