"""Shared machines (issue 32): a run sees the CPUs it may use and the other comat trainings."""

import json
import os
import subprocess
import sys

from comat.machine import SPIN_COUNT, RunRegistry, busy_warning, set_thread_waiting, usable_cpus


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


def test_idle_torch_threads_spin_a_little_then_sleep_unless_the_user_chose():
    env = {}
    set_thread_waiting(env)
    assert env == {"OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": str(SPIN_COUNT)}
    env = {}
    set_thread_waiting(env, others_training=True)  # other trainings here: sleep at once
    assert env == {"OMP_WAIT_POLICY": "PASSIVE"}
    for chosen in ({"OMP_WAIT_POLICY": "ACTIVE"}, {"OMP_WAIT_POLICY": "PASSIVE"}, {"GOMP_SPINCOUNT": "300000"}):
        env = dict(chosen)
        set_thread_waiting(env)
        assert env == chosen  # the user's choice, exactly: nothing added


def test_the_comat_command_sets_the_waiting_before_torch_loads(tmp_path):
    code = (
        "import os, sys; import comat.cli.main; sys.modules['comat.cli.main']._single_thread(); "
        "print(os.environ.get('GOMP_SPINCOUNT'), os.environ.get('OMP_WAIT_POLICY'), 'torch' in sys.modules)"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("GOMP_SPINCOUNT", "OMP_WAIT_POLICY")}
    env["TMPDIR"] = str(tmp_path)  # a registry of its own: no other training registered
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.split() == [str(SPIN_COUNT), "PASSIVE", "False"]
    # a training already registered there: this one's threads sleep at once
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        registry = tmp_path / f"comat-runs-{os.getuid()}"  # RunRegistry's folder under TMPDIR
        registry.mkdir()
        (registry / f"{sleeper.pid}.json").write_text(
            json.dumps({"pid": sleeper.pid, "out": "runs/a", "threads": 1, "started": 0})
        )
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
        assert out.stdout.split() == ["None", "PASSIVE", "False"]
    finally:
        sleeper.kill()


def test_a_training_announces_itself_before_it_looks_for_others(tmp_path, monkeypatch):
    """Two runs started together each find the other (and so neither spins): ``comat train`` writes
    its registry entry before the thread settings look for other trainings, and removes it at the end."""
    import tempfile

    import pytest

    from comat.cli.main import main

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    entry = tmp_path / f"comat-runs-{os.getuid()}" / f"{os.getpid()}.json"
    seen = []

    def fake_train(*args, **kwargs):
        seen.append(entry.exists())
        raise KeyboardInterrupt  # stop where training would start

    monkeypatch.setattr("comat.rl.runner.train", fake_train)
    with pytest.raises(KeyboardInterrupt):
        main(["train", "--algo", "mappo", "--task", "pcp", "--preset", "quick", "--out", str(tmp_path / "run")])
    assert seen == [True] and not entry.exists()
