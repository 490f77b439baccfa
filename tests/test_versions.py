"""What every run records about the code and machine that made it (``comat.rl.checkpoint.versions``)."""

import subprocess
from pathlib import Path

import pytest
import torch

from comat.rl import versions


def test_versions_record_the_source_commit():
    """Every run's config.yaml and checkpoint name the git commit of the code that made it."""
    root = Path(__file__).resolve().parents[1]
    head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, check=False)
    if head.returncode != 0:
        pytest.skip("not a git checkout")
    from comat.rl.checkpoint import source_commit

    source_commit.cache_clear()  # cached once per process: a commit made since (another run's) moved HEAD
    commit = versions()["commit"]
    assert commit.removesuffix("-dirty") == head.stdout.strip()


def test_versions_record_the_cpu_the_learner_ran_on():
    """Runs of one seed are equal bit for bit only on machines whose PyTorch CPU kernels dispatch
    alike, so every run records that level and the CPU model."""
    recorded = versions()
    assert recorded["torch_cpu"] == torch.backends.cpu.get_cpu_capability() and recorded["torch_cpu"]
    assert recorded["cpu"] and recorded["cpu"] != "unknown"
