import os
import sys

import numpy as np
import pytest

os.environ.setdefault("OMP_NUM_THREADS", "1")
# Idle OpenMP threads sleep at once instead of spinning (libgomp's default spins between torch ops):
# a spinning helper thread of one pytest-xdist worker takes the core of the other worker. Read when
# torch loads, which is after this file.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
TEST_TORCH_THREADS = int(os.environ["OMP_NUM_THREADS"])


@pytest.fixture(autouse=True)
def _torch_threads_back_after_each_test():
    """A test that trains in this process leaves torch at the run's ``torch_threads`` (2,
    comat/rl/runner.py): every later test of the worker would then run torch on two threads beside
    the other worker's, which made tests/test_models.py cost 17 times its CPU time."""
    yield
    torch = sys.modules.get("torch")
    if torch is not None and torch.get_num_threads() != TEST_TORCH_THREADS:
        torch.set_num_threads(TEST_TORCH_THREADS)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
