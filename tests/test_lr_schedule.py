"""PPO's learning-rate schedule (``ppo.lr_schedule``): linear decay over the run, exact resume."""

import pytest
import torch

from comat.rl import load_checkpoint, train
from tests.test_rl import assert_same, tiny


class _Stopped(Exception):
    pass


def test_linear_schedule_decays_with_the_run_and_resumes_exactly(tmp_path):
    """Six updates of 2 env steps: the last one runs at lr x (1 - 10/12); a run stopped after its
    checkpoint at 6 steps and resumed ends in the same state; a constant schedule keeps lr and
    learns something else."""
    ppo = {"num_envs": 2, "rollout_steps": 1, "epochs": 1, "minibatches": 1, "lr": 1e-3, "lr_schedule": "linear"}
    straight = tmp_path / "straight"
    train(tiny("comat", steps=12, ppo=ppo), straight, quiet=True)
    a = load_checkpoint(straight / "checkpoint.pt")
    assert a["trainer"]["optimizer"]["param_groups"][0]["lr"] == pytest.approx(1e-3 * (1 - 10 / 12))

    def stop_at_6(progress):
        if progress["checkpoint_env_steps"] == 6:
            raise _Stopped

    with pytest.raises(_Stopped):
        train(tiny("comat", steps=12, ppo=ppo), tmp_path / "split", quiet=True, on_update=stop_at_6)
    train(tiny("comat", steps=12, ppo=ppo), tmp_path / "split", resume=True, quiet=True)
    assert_same(a["trainer"], load_checkpoint(tmp_path / "split" / "checkpoint.pt")["trainer"], "trainer")
    train(tiny("comat", steps=12, ppo={**ppo, "lr_schedule": "constant"}), tmp_path / "constant", quiet=True)
    c = load_checkpoint(tmp_path / "constant" / "checkpoint.pt")
    assert c["trainer"]["optimizer"]["param_groups"][0]["lr"] == 1e-3
    assert any(not torch.equal(a["trainer"]["policy"][k], c["trainer"]["policy"][k]) for k in c["trainer"]["policy"])


def test_an_unknown_schedule_is_refused_by_name():
    with pytest.raises(ValueError, match=r"ppo.lr_schedule must be one of \['constant', 'linear'\], got 'cosine'"):
        tiny("mat", ppo={"lr_schedule": "cosine"})
