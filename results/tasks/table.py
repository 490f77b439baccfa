"""The learnability check's table (issue 49): results/tasks/README.md between its table markers, from
each kept run's evaluation (runs/NAME/evaluation_unicycle.json) beside the task's reference ladder
(results/sets/validity/<task>/, written by ``comat validity``); no number typed by hand. Only forage's runs
are of the task's current version (navigation, sensors and arctic changed rules in issue 64)."""

from pathlib import Path

from comat.eval import SET_NAMES
from comat.files import replace_block
from comat.measure.metrics import read_results

HERE = Path(__file__).resolve().parent
SETS = ("train", "val", "test", "scale", "size", "capability")
ALGOS = ("comat", "mat", "mappo")
TASKS = ("forage",)
REFERENCES = ("heuristic", "type_only", "blind", "random")


def _progress(rows: list[dict], policy: str) -> dict[str, float]:
    return {r["set"]: 100 * r["metrics"]["progress"]["mean"] for r in rows if r["policy"] == policy}


def main() -> None:
    lines = [
        (
            "Progress % (deterministic policy, 5 episodes per coalition, 20 coalitions per set, reality off, "
            "unicycle; one seed, 300 k env steps, `sweep` preset). References from `results/sets/validity.md` "
            "(their own evaluation seed, 4,000,037; the runs' is 2,000,003). "
            "A run not yet kept shows as —."
        ),
        "",
    ]
    for task in TASKS:
        ladder = HERE.parent / "sets" / "validity" / task / "evaluation_unicycle.json"
        if not ladder.is_file():
            continue
        refs = read_results(ladder, detail=False)
        lines += [f"### {task}", "", "| policy | " + " | ".join(SET_NAMES[s] for s in SETS) + " |"]
        lines.append("|---|" + "---:|" * len(SETS))
        for algo in ALGOS:
            path = HERE / "runs" / f"{algo}_{task}_s100" / "evaluation_unicycle.json"
            got = _progress(read_results(path, detail=False)["rows"], algo) if path.is_file() else {}
            lines.append(f"| {algo} | " + " | ".join(f"{got[s]:.1f}" if s in got else "—" for s in SETS) + " |")
        for ref in REFERENCES:
            got = _progress(refs["rows"], ref)
            lines.append(f"| {ref} (reference) | " + " | ".join(f"{got[s]:.1f}" for s in SETS) + " |")
        lines.append("")
    replace_block(HERE / "README.md", "table", "\n".join(lines))
    print(f"wrote {HERE / 'README.md'}")


if __name__ == "__main__":
    main()
