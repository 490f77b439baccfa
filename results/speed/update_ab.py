"""One PPO update (``trainer.update``) of an earlier commit's learner and of this checkout's, in one
process, alternating, on the same rollout from the same weights and optimizer state: a before/after
that this VM's drift between processes (MAT's unchanged update 0.84 against 1.17 s in two runs of
``update_time.py`` minutes apart) does not swamp.

    python results/speed/update_ab.py BEFORE TASK ALGOS ROUNDS THREADS >> out.jsonl

BEFORE is a worktree of the earlier commit (``git worktree add ../before REV``); its ``comat``
package is copied to a temporary folder as ``comat_before``, with its imports renamed, so both load
side by side. The rollout is collected once by this checkout's learner (paper preset, unicycle
tier, one env worker, seed 0); each round runs both updates, the order alternating; the first
round is the warm-up (``median_*`` leaves it out).
"""

import copy
import json
import re
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import torch
from update_time import timed_update  # beside this script

from comat.rl import make_run_env


def load_before(worktree: Path):
    """The earlier commit's ``comat.rl.algos`` and ``comat.rl.config``, imported as comat_before."""
    root = Path(tempfile.mkdtemp(prefix="comat_before_"))
    shutil.copytree(worktree / "comat", root / "comat_before")
    for path in (root / "comat_before").rglob("*.py"):
        text = path.read_text()
        text = re.sub(r"\bfrom comat(\.| import)", r"from comat_before\1", text)
        text = re.sub(r"\bimport comat\b", "import comat_before", text)
        path.write_text(re.sub(r'"comat\.([a-z_]+)', r'"comat_before.\1', text))
    sys.path.insert(0, str(root))
    from comat_before.rl import algos, config

    return algos, config


def trainer(algos, config_module, algo: str, task: str, env):
    config = config_module.resolve(
        config_module.load_preset("paper"), algo, task, seed=0, tier="unicycle", env_workers=1
    )
    torch.manual_seed(0)
    return algos.make_learner(config, env, algos.Dims.of(env)).trainer


def main(before: Path, task: str, algo_list: list[str], rounds: int, threads: int) -> None:
    import comat.rl.algos as algos_after
    import comat.rl.config as config_after

    algos_before, config_before = load_before(before)
    torch.set_num_threads(threads)
    for algo in algo_list:
        config = config_after.resolve(
            config_after.load_preset("paper"), algo, task, seed=0, tier="unicycle", env_workers=1
        )
        env = make_run_env(config, config.trainer.num_envs, 0)
        try:
            env.reset()
            sides = {
                "after": trainer(algos_after, config_after, algo, task, env),
                "before": trainer(algos_before, config_before, algo, task, env),
            }
            sides["before"].learner.load_state_dict(sides["after"].learner.state_dict())
            rollout = sides["after"].collect()
        finally:
            env.close()
        start = {
            k: (copy.deepcopy(t.learner.state_dict()), copy.deepcopy(t.optimizer.state_dict()))
            for k, t in sides.items()
        }
        seconds: dict[str, list[float]] = {"before": [], "after": []}
        for r in range(rounds):
            for side in ("before", "after") if r % 2 == 0 else ("after", "before"):
                seconds[side].append(timed_update(sides[side], *start[side], rollout))
        row = {"task": task, "algo": algo, "threads": threads, "before_rev": before.name}
        row.update({f"{k}_s": [round(x, 3) for x in v] for k, v in seconds.items()})
        row.update({f"median_{k}_s": round(float(np.median(v[1:])), 3) for k, v in seconds.items()})
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]), sys.argv[2], sys.argv[3].split(","), int(sys.argv[4]), int(sys.argv[5]))
