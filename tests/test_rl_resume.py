"""A run resumes exactly: after a stop, a kill -9 at any moment, or with env workers, the resumed run
equals the uninterrupted one; a run stopped before its first checkpoint can be resumed or restarted."""

import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch
import yaml
from test_rl import TINY_MODELS, assert_same, tiny

from comat.cli import main
from comat.learners import learner_entry, learner_names
from comat.rl import load_checkpoint, train


@pytest.mark.parametrize(
    "algo, steps",
    [(name, 320 if learner_entry(name).family == "qmix" else 12) for name in learner_names()],  # QMIX: a few updates
)
def test_resume_continues_exactly(tmp_path, algo, steps):
    straight = train(tiny(algo, steps=steps), tmp_path / "straight", quiet=True)
    train(tiny(algo, steps=steps // 2), tmp_path / "split", quiet=True)
    resumed = train(tiny(algo, steps=steps), tmp_path / "split", resume=True, quiet=True)
    assert straight["env_steps"] == resumed["env_steps"] == steps
    a = load_checkpoint(tmp_path / "straight" / "checkpoint.pt")
    b = load_checkpoint(tmp_path / "split" / "checkpoint.pt")
    assert_same(a["trainer"], b["trainer"], "trainer")
    assert_same(a["env_rngs"], b["env_rngs"], "env_rngs")
    assert torch.equal(a["torch_rng"], b["torch_rng"])
    # the logs read like one run
    rows = (tmp_path / "split" / "progress.csv").read_text().splitlines()
    assert rows[1:] and [r.split(",")[0] for r in rows[1:]] == [
        r.split(",")[0] for r in (tmp_path / "straight" / "progress.csv").read_text().splitlines()[1:]
    ]


def test_resume_keeps_the_earlier_sittings_in_config_yaml(tmp_path):

    train(tiny("mappo", steps=6), tmp_path / "run", quiet=True)
    train(tiny("mappo", steps=12), tmp_path / "run", resume=True, quiet=True)  # 6 env steps per update
    train(tiny("mappo", steps=18), tmp_path / "run", resume=True, quiet=True)
    doc = yaml.safe_load((tmp_path / "run" / "config.yaml").read_text())
    assert doc["resumed_at_env_steps"] == 12
    assert [s["resumed_at_env_steps"] for s in doc["earlier_sittings"]] == [None, 6]
    assert all(s["versions"]["torch"] == doc["versions"]["torch"] for s in doc["earlier_sittings"])


def test_resume_with_env_workers_continues_exactly(tmp_path):
    """Environments in two worker processes: the run is still exactly reproducible and resumable."""
    straight = train(tiny("mappo", env_workers=2), tmp_path / "straight", quiet=True)
    train(tiny("mappo", steps=6, env_workers=2), tmp_path / "split", quiet=True)
    train(tiny("mappo", env_workers=2), tmp_path / "split", resume=True, quiet=True)
    a = load_checkpoint(tmp_path / "straight" / "checkpoint.pt")
    b = load_checkpoint(tmp_path / "split" / "checkpoint.pt")
    assert straight["env_steps"] == 12 and a["config"]["env_workers"] == 2
    assert_same(a["trainer"], b["trainer"], "trainer")
    assert_same(a["env_rngs"], b["env_rngs"], "env_rngs")


def test_a_run_stopped_before_its_first_checkpoint_can_be_resumed_or_restarted(tmp_path):
    """Killed before the first checkpoint (config.yaml written, no checkpoint.pt; a kill during a
    checkpoint write also leaves a temporary file): --resume and a plain restart both start the
    run over and end where an uninterrupted run does; the temporary file is removed; another
    configuration in that folder is refused."""
    straight = tmp_path / "straight"
    train(tiny("comat"), straight, quiet=True)
    for how in ("resume", "restart"):
        run = tmp_path / how
        train(tiny("comat"), run, quiet=True)
        (run / "checkpoint.pt").unlink()
        (run / "policy.pt").unlink()  # written when a run finishes: a run killed this early has none
        (run / ".checkpoint.pt.abc123.tmp").write_bytes(b"")
        if how == "resume":
            assert main(["train", "--resume", "--out", str(run), "--quiet"]) == 0
        else:
            train(tiny("comat"), run, quiet=True)
        assert not list(run.glob(".*.tmp"))
        assert_same(
            load_checkpoint(straight / "checkpoint.pt")["trainer"], load_checkpoint(run / "checkpoint.pt")["trainer"]
        )
    (tmp_path / "restart" / "checkpoint.pt").unlink()
    with pytest.raises(FileExistsError, match="but no checkpoint.pt: it is not trained into again"):
        train(tiny("comat", steps=24), tmp_path / "restart", quiet=True)  # a finished run's policy.pt is kept
    (tmp_path / "restart" / "policy.pt").unlink()
    with pytest.raises(FileExistsError, match="stopped before its first checkpoint"):
        train(tiny("comat", steps=24), tmp_path / "restart", quiet=True)


def test_kill_9_at_random_moments_then_resume_equals_an_uninterrupted_run(tmp_path):
    """``comat train`` killed with SIGKILL at random moments (before its first checkpoint, between
    and during checkpoint writes), then resumed as a user would: the checkpoint on disk always
    loads, the finished run equals an uninterrupted one, and no temporary file remains."""

    import yaml

    preset = tmp_path / "tiny.yaml"
    preset.write_text(
        yaml.safe_dump(
            {
                "total_env_steps": 96,
                "eval_every_steps": 10**9,
                "eval_episodes_per_team": 0,
                "checkpoint_every_steps": 6,
                "ppo": {"num_envs": 2, "rollout_steps": 3, "epochs": 2, "minibatches": 2},
                "models": TINY_MODELS,
            }
        )
    )
    cmd = [
        sys.executable,
        "-m",
        "comat.cli",
        "train",
        "--algo",
        "comat",
        "--task",
        "pcp",
        "--preset",
        str(preset),
        "--seed",
        "3",
        "--quiet",
    ]
    t0 = time.perf_counter()
    subprocess.run([*cmd, "--out", str(tmp_path / "straight")], check=True, capture_output=True, timeout=300)
    whole = time.perf_counter() - t0  # start-up included: kills land at the same phases on a slow, loaded machine
    run = tmp_path / "killed"
    rng = np.random.default_rng(0)
    kills = 0
    for delay in rng.uniform(0.15, 0.95, size=5) * whole:
        resume = ["--resume"] if (run / "config.yaml").exists() else []
        proc = subprocess.Popen(
            [*cmd, "--out", str(run), *resume], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        time.sleep(delay)
        if proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
            kills += 1
        proc.wait(timeout=60)
        if (run / "checkpoint.pt").exists():
            load_checkpoint(run / "checkpoint.pt")  # the one on disk is always a complete one
    assert kills >= 3
    # As a user would: --resume where a run was started (on a loaded machine every kill can land before
    # the run wrote anything, and there is nothing to resume).
    resume = ["--resume"] if (run / "config.yaml").exists() else []
    final = subprocess.run([*cmd, "--out", str(run), *resume], check=False, capture_output=True, text=True, timeout=300)
    assert final.returncode == 0, final.stderr[-2000:]  # what went wrong, if it did
    assert not list(run.glob(".*tmp*"))
    a, b = load_checkpoint(tmp_path / "straight" / "checkpoint.pt"), load_checkpoint(run / "checkpoint.pt")
    assert a["progress"]["env_steps"] == b["progress"]["env_steps"] == 96
    assert_same(a["trainer"], b["trainer"], "trainer")


def _budget_config(steps, every=6, **extra):  # navigation: 22-step episodes, so evaluations are quick
    return tiny("mappo", "navigation", steps, eval_every_steps=every, eval_episodes_per_team=1, **extra)


def test_budget_curves_on_other_sets_and_kept_policies(tmp_path):
    """``eval_sets`` adds eval_<set>.csv beside eval.csv at every evaluation, ``keep_policies_at``
    keeps policy_<steps>.pt (the last one the final policy); bad values are one-line errors; a resumed
    run's eval_<set>.csv is cut back to its checkpoint like eval.csv."""
    from comat.rl.checkpoint import load_policy_file
    from comat.rl.logger import RunLogger

    run = tmp_path / "run"
    train(_budget_config(12, every=12, eval_sets=["val"], keep_policies_at=[6, 12]), run, quiet=True)
    rows = [(run / f).read_text().splitlines() for f in ("eval.csv", "eval_val.csv")]
    assert rows[0][0] == rows[1][0] and [r[1].split(",")[0] for r in rows] == ["12", "12"] and rows[0] != rows[1]
    assert load_policy_file(run / "policy_6.pt")["env_steps"] == 6
    assert_same(load_policy_file(run / "policy_12.pt")["weights"], load_policy_file(run / "policy.pt")["weights"])
    with pytest.raises(ValueError, match=r"eval_sets must be a list of distinct names from \['train'"):
        _budget_config(12, eval_sets=["nope"])
    with pytest.raises(ValueError, match=r"keep_policies_at must be a list of distinct env steps between 1 and"):
        _budget_config(12, keep_policies_at=[13])
    (run / "eval_val.csv").write_text("env_steps,progress\n6,0.5\n12,0.7\n")
    RunLogger(run, resume_step=6, tensorboard=False).close()
    assert (run / "eval_val.csv").read_text().splitlines() == ["env_steps,progress", "6,0.5"]


@pytest.mark.slow
def test_budget_curves_and_kept_policies_resume_exactly(tmp_path):
    """Stopped half way and resumed with a longer budget (and one more policy to keep), the run writes
    the same eval rows on every set and the same kept weights as the uninterrupted run."""
    from comat.rl.checkpoint import load_policy_file

    train(_budget_config(12, eval_sets=["val"], keep_policies_at=[6, 12]), tmp_path / "straight", quiet=True)
    train(_budget_config(6, eval_sets=["val"], keep_policies_at=[6]), tmp_path / "split", quiet=True)
    train(_budget_config(12, eval_sets=["val"], keep_policies_at=[6, 12]), tmp_path / "split", resume=True, quiet=True)
    for name in ("eval.csv", "eval_val.csv"):
        straight = (tmp_path / "straight" / name).read_text()
        assert straight == (tmp_path / "split" / name).read_text(), name
        assert [r.split(",")[0] for r in straight.splitlines()[1:]] == ["6", "12"]
    for n in (6, 12):
        a, b = (load_policy_file(tmp_path / f / f"policy_{n}.pt")["weights"] for f in ("straight", "split"))
        assert_same(a, b, f"policy_{n}")
