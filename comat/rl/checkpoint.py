"""Checkpoints and policy files: written atomically, checked before use.

A checkpoint is a ``torch.save`` dict loaded with ``weights_only=True`` (tensors and plain data
only, so loading one never runs code):

    format "comat-checkpoint", format_version, algo, task, config (the resolved run config),
    versions (comat, its git commit, torch, mujoco, numpy, python), progress (env steps, updates, …),
    trainer (the trainer's state: weights, optimizer, normalizers, generators, buffers),
    env_rngs (the vector environment's generators), torch_rng.

A policy file (``policy.pt``, :mod:`comat.rl.policy`) is what acting needs and nothing else,
small enough to commit next to a run's results:

    format "comat-policy", format_version, algo, task, config (the resolved run config), dims
    (the sizes the model is built from), versions (of the code that trained it), written_by (of
    the code that wrote the file), env_steps and updates at which it was taken, parameters, and
    weights: module name -> float32 state dict of the modules deterministic acting needs
    (:attr:`comat.learners.LearnerEntry.acts_with`); no optimizer, normalizer, critic, mixer or buffer.

Both load with ``weights_only=True``. Writes go to a temporary file in the same folder, are
flushed to disk, then renamed over the target, so a crash leaves either the old file or the new
one, never half of one.

A checkpoint keeps the config that trained it. Options added to the configs later are absent
from older checkpoints; :data:`EARLIER_DEFAULTS` gives each the value that reproduces what
the older code built (COMAT's paper-form encoder, PPO's TD(0) critic target; a reality layer
``off``: :data:`EARLIER_RUN_DEFAULTS`), so an older checkpoint loads as the model it was,
whatever today's defaults are.
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

from comat import learners
from comat._version import __version__
from comat.envs.outside import is_outside
from comat.models import PAPER_FORM
from comat.tasks import TASKS, env_id, not_registered

__all__ = [
    "POLICY_FORMAT",
    "RENAMED",
    "CheckpointError",
    "current_name",
    "load_checkpoint",
    "load_policy_file",
    "load_trained",
    "save_checkpoint",
    "save_policy_file",
    "to_plain",
    "versions",
]

FORMAT = "comat-checkpoint"
FORMAT_VERSION = 1
POLICY_FORMAT = "comat-policy"
POLICY_FORMAT_VERSION = 1
_VERSIONS = {FORMAT: FORMAT_VERSION, POLICY_FORMAT: POLICY_FORMAT_VERSION}
_NOUN = {FORMAT: "checkpoint", POLICY_FORMAT: "policy file"}
_DIMS = ("obs_dim", "n_types", "n_caps", "state_dim")


EARLIER_DEFAULTS = {
    # root_weight and node_ffn are older than the rest: every checkpoint records them
    "model": {"comat": {k: v for k, v in PAPER_FORM.items() if k not in ("root_weight", "node_ffn")}},
    "trainer": {"comat": {"value_target": "td"}, "mat": {"value_target": "td"}, "mappo": {"value_target": "td"}},
    # (IPPO is newer than value_target: every IPPO checkpoint records it)
}
"""Section -> algo -> option -> the value a checkpoint without that option was trained with."""
EARLIER_RUN_DEFAULTS = {"reality": "off", "loop": "comat", "coalitions": "train"}
"""Run-level key -> the value a checkpoint without it was trained with (before the reality layer
existed, every run trained in the ideal world; before ``loop``, with comat's filter; before
``coalitions``, on U_train)."""


RENAMED = {"cash": ("version", "cash-caps")}
"""Learners whose name a new learner took: stored algo -> (the model option every file of the new
learner records, today's name of the learner that files without it hold). ``cash``: issue 65 made
``--algo cash`` the CASH of the authors' code (its config records ``version``); files and run
folders stored before hold comat's first CASH, now ``cash-caps``, and load and evaluate as it."""


def current_name(algo: str, model: Any) -> str:
    """Today's name of the learner stored as ``algo`` with model options ``model`` (see :data:`RENAMED`)."""
    mark, old = RENAMED.get(algo, (None, None))
    return old if mark is not None and isinstance(model, dict) and mark not in model else algo


def with_earlier_defaults(config: dict) -> dict:
    """A stored run config with every option it predates set to what the older code built."""
    out = dict(config)
    for key, value in EARLIER_RUN_DEFAULTS.items():
        out.setdefault(key, value)
    for section, by_algo in EARLIER_DEFAULTS.items():
        if isinstance(out.get(section), dict):
            out[section] = {**by_algo.get(out.get("algo"), {}), **out[section]}
    return out


class CheckpointError(ValueError):
    """A checkpoint or policy file that cannot be used: missing, corrupt, another format, algo or
    task, or a policy file where the whole learner is needed."""


SOURCE_COMMIT_ENV = "COMAT_SOURCE_COMMIT"
"""The commit of a copy of the source without its ``.git`` (a snapshot that runs a long grid while
the checkout moves on): whoever makes the copy sets it, e.g. ``COMAT_SOURCE_COMMIT=$(git describe
--always --dirty --abbrev=40)``; :func:`source_commit` records it as ``<value> (snapshot)``."""


@functools.cache
def source_commit(root: str | Path | None = None) -> str:
    """Which code made a run: the git commit of the comat source in use (``root``, default the
    folder holding the ``comat`` package), with ``-dirty`` where tracked files have uncommitted
    changes. Where that folder is not a git checkout of its own (an installed wheel, a copy
    without ``.git``): :data:`SOURCE_COMMIT_ENV`'s value where it is set, else ``unknown (...)``
    with the reason. Never raises: a missing git does not stop a run.

    The grid runs of December 2026 say ``unknown``: they ran from a snapshot without ``.git``, and
    this function said no more than that."""
    root = Path(root) if root is not None else Path(__file__).resolve().parents[2]
    root = root.resolve()

    def git(*args: str) -> str:
        # safe.directory: a checkout owned by another user (a shared or mounted tree) is still read
        return subprocess.run(
            ["git", "-c", f"safe.directory={root}", "-C", str(root), *args],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
            env={**os.environ, "GIT_OPTIONAL_LOCKS": "0"},
        ).stdout.strip()

    reason = "not a git checkout"
    try:
        top = git("rev-parse", "--show-toplevel")
        if Path(top).resolve() == root:  # else installed somewhere inside another repository (a venv in one)
            commit = git("rev-parse", "HEAD")
            return commit + ("-dirty" if git("status", "--porcelain", "--untracked-files=no") else "")
    except FileNotFoundError:
        reason = "git not found"
    except subprocess.CalledProcessError as exc:
        first = (exc.stderr or "").strip().splitlines()
        if not first or "not a git repository" not in first[0]:
            reason = f"git failed: {first[0] if first else f'exit status {exc.returncode}'}"
    except (OSError, subprocess.SubprocessError) as exc:
        reason = f"git failed: {exc}"
    snapshot = os.environ.get(SOURCE_COMMIT_ENV, "").strip()
    return f"{snapshot} (snapshot)" if snapshot else f"unknown ({reason})"


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

    return {
        "comat": __version__,
        "commit": source_commit(),
        "torch": str(torch.__version__),
        "mujoco": str(mujoco.__version__),
        "numpy": str(np.__version__),
        "python": platform.python_version(),
        "torch_cpu": str(torch.backends.cpu.get_cpu_capability()),
        "cpu": cpu_model(),
    }


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


def _env_id(task: str) -> str:
    """The env id a file records: a task's current one, an outside task's name."""
    return task if is_outside(task) else env_id(task)


def save_checkpoint(
    path: str | Path, *, algo: str, task: str, config: dict, progress: dict, trainer: dict, env_rngs: list[dict]
) -> Path:
    """Atomically write a checkpoint to ``path``; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "algo": algo,
        "task": task,
        "env_id": _env_id(task),
        "config": config,
        "versions": versions(),
        "progress": progress,
        "trainer": to_plain(trainer),
        "env_rngs": env_rngs,
        "torch_rng": torch.get_rng_state(),
    }
    return _save(path, payload)


def _save(path: Path, payload: dict) -> Path:
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


def save_policy_file(
    path: str | Path,
    *,
    algo: str,
    task: str,
    config: dict,
    dims: dict,
    weights: dict[str, dict[str, torch.Tensor]],
    env_steps: int,
    updates: int,
    trained_by: dict | None = None,
) -> Path:
    """Atomically write a policy file (see the module docstring) to ``path``; returns the path.

    ``weights``: module name -> state dict, copied here into tensors of their own (a view would
    drag its whole storage into the file), values and dtypes unchanged. ``trained_by``: the
    versions of the code that trained the weights (default: this code's)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plain = {
        name: {k: v.detach().to("cpu", copy=True).contiguous() for k, v in state.items()}
        for name, state in weights.items()
    }
    now = versions()
    payload = {
        "format": POLICY_FORMAT,
        "format_version": POLICY_FORMAT_VERSION,
        "algo": algo,
        "task": task,
        "env_id": _env_id(task),
        "config": config,
        "dims": dict(dims),
        "versions": dict(trained_by or now),
        "written_by": now,
        "env_steps": int(env_steps),
        "updates": int(updates),
        "parameters": sum(v.numel() for state in plain.values() for v in state.values() if v.is_floating_point()),
        "weights": plain,
    }
    return _save(path, payload)


def _read(path: str | Path, formats: tuple[str, ...], algo: str | None, task: str | None) -> dict:
    """A checked comat file of one of ``formats``; CheckpointError naming the file and what is wrong."""
    path = Path(path)
    noun = " or ".join(_NOUN[f] for f in formats)
    if path.is_dir():
        names = " or ".join(("checkpoint.pt" if f == FORMAT else "policy.pt") for f in formats)
        raise CheckpointError(f"{noun} {str(path)!r} is a folder; expected a {names} file")
    if not path.is_file():
        raise CheckpointError(f"{noun} {str(path)!r} does not exist")
    size = path.stat().st_size
    if size == 0:
        raise CheckpointError(f"{noun} {str(path)!r} is empty (0 bytes): not a comat {noun}")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises several types (and paragraphs) for foreign files
        raise CheckpointError(
            f"{noun} {str(path)!r} ({size} bytes) is corrupt or not a comat {noun}: "
            f"torch.load could not read it ({type(err).__name__})"
        ) from err
    kind = data.get("format") if isinstance(data, dict) else None
    if kind == POLICY_FORMAT and kind not in formats:
        raise CheckpointError(
            f"{str(path)!r} is a comat policy file (the weights to act and their config; no "
            "optimizer, normalizers, critic or replay buffer): this needs the run's checkpoint.pt"
        )
    if kind == FORMAT and kind not in formats:
        raise CheckpointError(
            f"{str(path)!r} is a comat checkpoint, not a policy file; make its policy file with "
            f"`comat policy {path}`, or load it with load_checkpoint"
        )
    if kind not in formats:
        raise CheckpointError(
            f"{str(path)!r} is not a comat {noun} (expected format {' or '.join(repr(f) for f in formats)})"
        )
    noun = _NOUN[kind]
    if data.get("format_version") != _VERSIONS[kind]:
        raise CheckpointError(
            f"{noun} {str(path)!r} has format_version {data.get('format_version')!r}, "
            f"this comat reads {_VERSIONS[kind]}"
        )
    if isinstance(data.get("config"), dict):
        name = current_name(data.get("algo"), data["config"].get("model"))
        if name != data.get("algo"):  # a learner renamed since (RENAMED): the file's weights are of that one
            data["algo"], data["config"] = name, {**data["config"], "algo": name}
    for key, want in (("algo", algo), ("task", task)):
        if want is not None and data.get(key) != want:
            raise CheckpointError(f"{noun} {str(path)!r} is for {key} {data.get(key)!r}, expected {want!r}")
    made_for = data.get("env_id", f"{data.get('task')}_v0")  # files older than task versions: v0
    # A plug-in task's, read without it (an outside env's name is its env id: comat.envs.outside).
    if isinstance(data.get("task"), str) and data["task"] not in TASKS and not is_outside(data["task"]):
        raise CheckpointError(f"{noun} {str(path)!r} was trained on {made_for}, but {not_registered(data['task'])}")
    if data.get("task") in TASKS and made_for != env_id(data["task"]):
        raise CheckpointError(
            f"{noun} {str(path)!r} was trained on {made_for}, but this comat has {env_id(data['task'])} "
            "(the task's rules changed since): train it again"
        )
    if isinstance(data.get("algo"), str) and data["algo"] not in learners.learner_names():  # a plug-in learner's
        raise CheckpointError(
            f"{noun} {str(path)!r} holds a {data['algo']!r} policy, but {learners.not_registered(data['algo'])}"
        )
    if kind == POLICY_FORMAT:
        _check_policy(path, data)
    if isinstance(data.get("config"), dict):
        data["config"] = with_earlier_defaults(data["config"])
    return data


def _check_policy(path: Path, data: dict) -> None:
    """The keys a policy file must hold, with the types acting reads."""
    where = f"policy file {str(path)!r}"
    for key, kind in (
        ("algo", str),
        ("task", str),
        ("config", dict),
        ("dims", dict),
        ("weights", dict),
        ("env_steps", int),
    ):
        if not isinstance(data.get(key), kind):
            raise CheckpointError(
                f"{where} lacks {key!r} (expected a {kind.__name__}, got {type(data.get(key)).__name__})"
            )
    missing = [k for k in _DIMS if not isinstance(data["dims"].get(k), int)]
    if missing:
        raise CheckpointError(f"{where}: dims lack {missing} (expected integers {list(_DIMS)})")
    for name, state in data["weights"].items():
        if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
            raise CheckpointError(f"{where}: weights[{name!r}] must map parameter names to tensors")


def load_checkpoint(path: str | Path, algo: str | None = None, task: str | None = None) -> dict:
    """Read and check a checkpoint; ``algo``/``task``, if given, must match it.

    Raises:
        CheckpointError: naming the file and what is wrong with it (a policy file included: it
            cannot resume, probe or export a learner).
    """
    return _read(path, (FORMAT,), algo, task)


def load_policy_file(path: str | Path, algo: str | None = None, task: str | None = None) -> dict:
    """Read and check a policy file (``policy.pt``); ``algo``/``task``, if given, must match it.

    Raises:
        CheckpointError: naming the file and what is wrong with it.
    """
    return _read(path, (POLICY_FORMAT,), algo, task)


def load_trained(path: str | Path, algo: str | None = None, task: str | None = None) -> dict:
    """A checkpoint or a policy file, checked (its ``"format"`` says which): what acting reads.

    Raises:
        CheckpointError: naming the file and what is wrong with it.
    """
    return _read(path, (FORMAT, POLICY_FORMAT), algo, task)
