"""``ppo.overlap`` on this 2-core VM with the learner on one torch thread: the best sequential
setting (2 env workers, 2 learner threads) against the overlap with 1 env worker and 1 learner
thread (one core collects — the worker and the acting take turns —, the other updates), and the
sequential run with that same setting, one sitting (``bench_train``, 3 iterations):

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 GOMP_SPINCOUNT=10000 OMP_WAIT_POLICY=PASSIVE \\
        python results/speed/overlap_threads.py > results/speed/overlap_threads.jsonl

(the environment variables are what ``comat``'s command line sets for a lone run).
"""

import json
import tempfile
from pathlib import Path

from comat.bench import bench_train

if __name__ == "__main__":  # env workers are spawned processes: they import this file
    with tempfile.TemporaryDirectory() as tmp:
        one_thread = Path(tmp) / "one_thread.yaml"
        one_thread.write_text("base: paper\ntorch_threads: 1\n")
        for task in ("pcp", "hmt"):
            for algo in ("comat", "mat"):
                for preset, workers, overlap in (("paper", 2, False), (one_thread, 1, True), (one_thread, 1, False)):
                    row = bench_train(algo, 3, env_workers=workers, task=task, preset=str(preset), overlap=overlap)
                    print(json.dumps({**row, "preset": "paper" if preset == "paper" else "paper, torch_threads 1"}))
