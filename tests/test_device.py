"""``--device``: the update on a copy of the networks on a device, mirrored to the CPU networks
that act, computes what the update in place computes (the device path run with ``cpu``: there is
no GPU here); ``--device cuda`` without one is a one-line error."""

import pytest
import torch
from test_rl import assert_same, tiny

from comat.cli import main
from comat.learners import learner_entry
from comat.rl import PPOTrainer, QmixTrainer, resolve_device
from comat.rl.algos import Dims, Learner, build_modules, make_run_env
from comat.rl.checkpoint import to_plain


def _learner(config, device):
    env = make_run_env(config, config.trainer.num_envs, config.seed)
    env.reset()
    torch.manual_seed(config.seed)
    modules = build_modules(config.algo, Dims.of(env), config.model)
    if learner_entry(config.algo).family == "qmix":
        trainer = QmixTrainer(modules["agents"], modules["mixer"], env, config.trainer, config.seed, device=device)
    else:
        trainer = PPOTrainer(
            modules["policy"], env, config.trainer, config.seed, learner_entry(config.algo).uses_state, device=device
        )
    return Learner(config.algo, modules, trainer), env


@pytest.mark.parametrize("algo", ["comat", "mappo", "qmix"])
def test_update_on_a_device_copy_equals_the_update_in_place(algo):
    config = tiny(algo)
    runs = []
    for device in (None, "cpu"):
        learner, env = _learner(config, device)
        try:
            stats = [learner.iterate()[1] for _ in range(3)]
        finally:
            env.close()
        runs.append((learner, stats))
    (in_place, stats_a), (copied, stats_b) = runs
    trainer = copied.trainer
    learned = trainer.learner if algo != "qmix" else trainer.learn_agents
    acting = trainer.policy if algo != "qmix" else trainer.agents
    assert learned is not acting  # the device path: a copy learns, the CPU networks act
    assert_same(acting.state_dict(), learned.state_dict(), "mirrored")
    assert_same(to_plain(in_place.state_dict()), to_plain(copied.state_dict()), "trainer")
    assert stats_a == stats_b
    resumed, env = _learner(config, "cpu")  # a checkpoint of the device path loads into one
    try:
        resumed.load_state_dict(copied.state_dict())
        assert_same(to_plain(resumed.state_dict()), to_plain(copied.state_dict()), "loaded")
    finally:
        env.close()


def test_device_cuda_without_a_gpu_is_one_line_and_auto_falls_back(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)  # as on a machine without one
    assert resolve_device("auto") == "cpu"
    out = tmp_path / "run"
    assert (
        main(["train", "--algo", "comat", "--task", "pcp", "--preset", "quick", "--device", "cuda", "--out", str(out)])
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--device cuda: PyTorch" in err[0] and "sees no CUDA device" in err[0], err
    assert (
        main(
            [
                "sweep",
                "--preset",
                "quick",
                "--algos",
                "comat",
                "--tasks",
                "pcp",
                "--device",
                "cuda",
                "--out",
                str(tmp_path / "sw"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--device cuda" in err[0], err
    assert not out.exists() and not (tmp_path / "sw").exists()
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert resolve_device("auto") == "cuda"
