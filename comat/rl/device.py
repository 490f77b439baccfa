"""Where a learner's update runs: ``--device auto|cpu|cuda``.

Acting (rollouts, evaluation) always runs on the CPU, through the compiled decoding kernels; only
the update — the teacher-forced pass, the losses and the optimizer — moves to the device. A trainer
given a device keeps a copy of its networks there, learns on the copy, and copies the weights back
to the CPU networks after every update, so rollouts see exactly the weights the update produced.
"""

from __future__ import annotations

import copy
from typing import Any

import torch

__all__ = ["DEVICES", "learner_copy", "resolve_device", "to_cpu"]

DEVICES = ("auto", "cpu", "cuda")


def resolve_device(name: str) -> str:
    """``"cpu"`` or ``"cuda"`` for a ``--device`` value (``auto``: cuda where PyTorch sees one)."""
    if name not in DEVICES:
        raise ValueError(f"--device must be one of {list(DEVICES)}, got {name!r}")
    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" and not torch.cuda.is_available():
        raise ValueError(
            f"--device cuda: PyTorch {torch.__version__} sees no CUDA device here "
            f"(built with CUDA {torch.version.cuda}); use --device cpu or auto"
        )
    return name


def learner_copy(module: torch.nn.Module, device: str | None) -> torch.nn.Module:
    """The module the update trains: ``module`` itself (``device`` None: learn in place on the CPU), or
    its copy on ``device``."""
    return module if device is None else copy.deepcopy(module).to(device)


def to_cpu(obj: Any) -> Any:
    """Tensors moved to the CPU inside nested dicts, lists and tuples (checkpoints load anywhere)."""
    if isinstance(obj, torch.Tensor):
        return obj.cpu()
    if isinstance(obj, dict):
        return {k: to_cpu(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(to_cpu(v) for v in obj)
    return obj
