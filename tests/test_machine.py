"""Shared machines (issue 32): a run sees the CPUs it may use and the other comat trainings."""

import json
import os
import subprocess
import sys

from comat.machine import RunRegistry, busy_warning, usable_cpus


def test_usable_cpus_follow_the_affinity():
    assert usable_cpus() == len(os.sched_getaffinity(0))
    one = subprocess.run(
        ["taskset", "-c", "0", sys.executable, "-c", "from comat.machine import usable_cpus; print(usable_cpus())"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert one.stdout.strip() == "1"


def test_the_registry_sees_live_runs_and_forgets_dead_ones(tmp_path):
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        (tmp_path / f"{sleeper.pid}.json").write_text(
            json.dumps({"pid": sleeper.pid, "out": "runs/a", "threads": 1, "started": 0})
        )
        dead = subprocess.run(
            [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True, check=True
        )
        pid = int(dead.stdout)
        (tmp_path / f"{pid}.json").write_text(json.dumps({"pid": pid, "out": "runs/b", "threads": 1, "started": 0}))
        with RunRegistry("runs/me", 2, root=tmp_path) as others:
            assert [o["out"] for o in others] == ["runs/a"]
            assert (tmp_path / f"{os.getpid()}.json").is_file()
            assert not (tmp_path / f"{pid}.json").exists()  # the ended run's file is gone
            warning = busy_warning(others, 2)
            assert warning.startswith("warning: 1 other comat training(s) on this machine: pid")
            assert "runs/a" in warning and "about 1/2" in warning
        assert not (tmp_path / f"{os.getpid()}.json").exists()
    finally:
        sleeper.kill()
    assert busy_warning([], 10_000) is None
