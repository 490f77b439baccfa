"""Checkpoints: one file per run state, written atomically, checked before use.

A checkpoint is a ``torch.save`` dict loaded with ``weights_only=True`` (tensors and plain data
only, so loading one never runs code):

    format "comat-checkpoint", format_version, algo, task, config (the resolved run config),
    versions (comat, its git commit, torch, mujoco, numpy, python), progress (env steps, updates, …),
    trainer (the trainer's state: weights, optimizer, normalizers, generators, buffers),
    env_rngs (the vector environment's generators), torch_rng.

Writes go to a temporary file in the same folder, are flushed to disk, then renamed over the
target, so a crash leaves either the old checkpoint or the new one, never half of one.

A checkpoint keeps the config that trained it. Options added to the configs later are absent
from older checkpoints; :data:`EARLIER_DEFAULTS` gives each the value that reproduces what
the older code built (COMAT's paper-form encoder, PPO's TD(0) critic target), so an older
checkpoint loads as the model it was, whatever today's defaults are.
"""

from __future__ import annotations

import functools
import os
import platform
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from comat.models.comat import PAPER_FORM

__all__ = ["CheckpointError", "load_checkpoint", "save_checkpoint", "to_plain", "versions"]

FORMAT = "comat-checkpoint"
FORMAT_VERSION = 1


EARLIER_DEFAULTS = {
    # root_weight and node_ffn are older than the rest: every checkpoint records them
    "model": {"comat": {k: v for k, v in PAPER_FORM.items() if k not in ("root_weight", "node_ffn")}},
    "trainer": {"comat": {"value_target": "td"}, "mat": {"value_target": "td"}, "mappo": {"value_target": "td"}},
}
"""Section -> algo -> option -> the value a checkpoint without that option was trained with."""


def with_earlier_defaults(config: dict) -> dict:
    """A stored run config with every option it predates set to what the older code built."""
    out = dict(config)
    for section, by_algo in EARLIER_DEFAULTS.items():
        if isinstance(out.get(section), dict):
            out[section] = {**by_algo.get(out.get("algo"), {}), **out[section]}
    return out


class CheckpointError(ValueError):
    """A checkpoint that cannot be used: missing, corrupt, another format, algo or task."""


@functools.cache
def source_commit() -> str:
    """The git commit of the comat source in use (``-dirty`` with uncommitted changes to tracked
    files), or ``"unknown"`` outside a git checkout: which code made a run."""
    root = Path(__file__).resolve().parents[2]
    try:
        def git(*args: str) -> str:
            return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, check=True,
                                  timeout=10).stdout.strip()

        if Path(git("rev-parse", "--show-toplevel")).resolve() != root:
            return "unknown"  # installed somewhere inside another repository (e.g. a venv in one)
        commit = git("rev-parse", "HEAD")
        return commit + ("-dirty" if git("status", "--porcelain", "--untracked-files=no") else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def cpu_model() -> str:
    """The CPU's model name (Linux /proc/cpuinfo, else the platform's word for it)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def versions() -> dict[str, str]:
    """What a run's numbers depend on besides its config. ``torch_cpu`` is the vector instruction
    level PyTorch's CPU kernels dispatch to (e.g. AVX2, AVX512). The same seed and code gave the
    same run bit for bit on one machine but not across two (the policy loss ~1e-7 apart from update
    1 on, the final policies different), most likely because the learner's sums were ordered by
    different kernels: recorded so that such a difference can be traced."""
    import mujoco

    from comat import __version__

    return {"comat": __version__, "commit": source_commit(), "torch": str(torch.__version__),
            "mujoco": str(mujoco.__version__), "numpy": str(np.__version__), "python": platform.python_version(),
            "torch_cpu": str(torch.backends.cpu.get_cpu_capability()), "cpu": cpu_model()}


def to_plain(obj: Any) -> Any:
    """numpy arrays → tensors, numpy scalars → Python numbers, recursively (what
    ``weights_only`` loading accepts)."""
    if isinstance(obj, dict):
        return {k: to_plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return type(obj)(to_plain(v) for v in obj)
    if isinstance(obj, np.ndarray):
        return torch.from_numpy(np.ascontiguousarray(obj))
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def save_checkpoint(path: str | Path, *, algo: str, task: str, config: dict, progress: dict,
                    trainer: dict, env_rngs: list[dict]) -> Path:
    """Atomically write a checkpoint to ``path``; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "algo": algo, "task": task,
        "config": config, "versions": versions(), "progress": progress,
        "trainer": to_plain(trainer), "env_rngs": env_rngs, "torch_rng": torch.get_rng_state(),
    }
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            torch.save(payload, fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def load_checkpoint(path: str | Path, algo: str | None = None, task: str | None = None) -> dict:
    """Read and check a checkpoint; ``algo``/``task``, if given, must match it.

    Raises:
        CheckpointError: naming the file and what is wrong with it.
    """
    path = Path(path)
    if path.is_dir():
        raise CheckpointError(f"checkpoint {str(path)!r} is a folder; expected a checkpoint.pt file")
    if not path.is_file():
        raise CheckpointError(f"checkpoint {str(path)!r} does not exist")
    size = path.stat().st_size
    if size == 0:
        raise CheckpointError(f"checkpoint {str(path)!r} is empty (0 bytes): not a comat checkpoint")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises several types (and paragraphs) for foreign files
        raise CheckpointError(f"checkpoint {str(path)!r} ({size} bytes) is corrupt or not a comat checkpoint: "
                              f"torch.load could not read it ({type(err).__name__})") from err
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise CheckpointError(f"{str(path)!r} is not a comat checkpoint (expected format {FORMAT!r})")
    if data.get("format_version") != FORMAT_VERSION:
        raise CheckpointError(f"checkpoint {str(path)!r} has format_version {data.get('format_version')!r}, "
                              f"this comat reads {FORMAT_VERSION}")
    for key, want in (("algo", algo), ("task", task)):
        if want is not None and data[key] != want:
            raise CheckpointError(f"checkpoint {str(path)!r} is for {key} {data[key]!r}, expected {want!r}")
    if isinstance(data.get("config"), dict):
        data["config"] = with_earlier_defaults(data["config"])
    return data
