"""Policy files: a trained policy small enough to commit, loadable wherever ``--policy`` is.

``comat train`` writes ``policy.pt`` into the run folder when the run finishes (and again when a
finished run is resumed); ``comat policy RUN`` makes one from an existing checkpoint. It holds the
float32 weights deterministic acting needs (:attr:`comat.learners.LearnerEntry.acts_with`: COMAT's and
MAT's policy module, MAPPO's actors, QMIX's agent network), the resolved run config and the sizes
to rebuild the model, the versions of the code that trained it and the env steps it was taken at
(format: :mod:`comat.rl.checkpoint`). It cannot resume a run or be probed: those need the
checkpoint (optimizer, normalizers, critic or mixer, replay buffer, generators).

A policy loaded from ``policy.pt`` acts bit for bit as the one loaded from the checkpoint it was
taken from (tested for every registered learner).
"""

from __future__ import annotations

from pathlib import Path

import torch

from comat.learners import learner_names
from comat.rl.algos import Dims, build_modules, make_run_env, policy_act
from comat.rl.checkpoint import (
    FORMAT,
    POLICY_FORMAT,
    CheckpointError,
    load_checkpoint,
    load_trained,
    save_policy_file,
)
from comat.rl.config import RunConfig, load_preset, resolve
from comat.tasks import task_names

__all__ = [
    "CHECKPOINT_FILE",
    "POLICY_FILE",
    "PREFIX",
    "PRETRAINED",
    "PRETRAINED_DIR",
    "acting_weights",
    "describe_policy",
    "ensure_policy",
    "format_size",
    "load_policy",
    "policy_file_of",
    "policy_from_checkpoint",
    "policy_modules",
    "policy_weights",
    "pretrained_path",
    "save_policy",
]

POLICY_FILE = "policy.pt"
CHECKPOINT_FILE = "checkpoint.pt"

PRETRAINED_DIR = Path(__file__).parent.parent / "data" / "pretrained"
PRETRAINED: dict[str, dict[str, str]] = {
    "comat-pcp": {
        "file": "comat_pcp_s0.pt",
        "what": "COMAT on PCP, seed 0, 302 k env steps (sweep preset); "
        "U_train progress 99.5 %, finished 97 %; U_test 96.5 % / 85 % (results/policies/comat_pcp_s0)",
    },
    "comat-hmt": {
        "file": "comat_hmt_s0.pt",
        "what": "COMAT on HMT, seed 0, 300 k env steps (sweep preset); "
        "U_train progress 97.9 %, finished 52 %; U_test 96.4 % / 41 % (results/policies/comat_hmt_s0)",
    },
    "mat-pcp": {
        "file": "mat_pcp_s1.pt",
        "what": "MAT (20 robot slots) on PCP, seed 1, 300 k env steps; "
        "U_train progress 100 %, finished 100 %; U_test 99.0 % / 94 % (results/policies/mat_pcp_s1)",
    },
    "mat-hmt": {
        "file": "mat_hmt_s1.pt",
        "what": "MAT (20 robot slots) on HMT, seed 1, 300 k env steps; "
        "U_train progress 97.7 %, finished 68 %; U_test 97.9 % / 65 % (results/policies/mat_hmt_s1)",
    },
}
"""The policies that ship with comat (``pretrained:NAME`` wherever a policy is taken): copies of the
kept policy files under ``results/policies/`` (their READMEs say how each was trained and what it
scores; ``comat policy pretrained:NAME`` prints what a file holds)."""

PREFIX = "pretrained:"


def pretrained_path(name: str, flag: str = "--policy") -> Path:
    """The file of ``pretrained:NAME`` (or ``NAME``); ValueError naming ``flag`` and the known names."""
    key = name.removeprefix(PREFIX)
    if key not in PRETRAINED:
        raise ValueError(f"{flag} must be one of {[PREFIX + k for k in PRETRAINED]}, got {name!r}")
    return PRETRAINED_DIR / PRETRAINED[key]["file"]


def shipped_name(path: str | Path) -> str | None:
    """``pretrained:NAME`` when ``path`` is the file of a policy that ships with comat, else None
    (recordings and videos name a shipped policy as such, not by its file)."""
    resolved = Path(path).resolve()
    return next(
        (PREFIX + key for key, entry in PRETRAINED.items() if resolved == (PRETRAINED_DIR / entry["file"]).resolve()),
        None,
    )


def format_size(n_bytes: int) -> str:
    """``371 KB`` / ``2.4 MB`` (1 KB = 1000 bytes)."""
    if n_bytes < 1_000_000:
        return f"{max(n_bytes / 1000, 1):.0f} KB"
    return f"{n_bytes / 1e6:.1f} MB"


def acting_weights(algo: str, dims: Dims, model_config, state: dict) -> dict[str, dict[str, torch.Tensor]]:
    """The entries of a learner's module state dicts (``state``: module name -> state dict, as a
    checkpoint's ``trainer`` holds them) that deterministic acting loads: those of the modules
    :func:`build_modules` makes with ``acting_only``."""
    with torch.random.fork_rng(devices=[]):  # building draws initial weights: leave the caller's stream alone
        keep = build_modules(algo, dims, model_config, acting_only=True)
    out = {}
    for name, module in keep.items():
        if name not in state:
            raise CheckpointError(f"the {algo} learner's state has no {name!r} module (has {sorted(state)})")
        wanted = module.state_dict().keys()
        missing = [k for k in wanted if k not in state[name]]
        if missing:
            raise CheckpointError(f"the {algo} learner's {name!r} weights lack {missing[:3]}")
        out[name] = {k: state[name][k] for k in wanted}
    return out


def save_policy(
    path: str | Path, config: RunConfig, dims: Dims, state: dict, progress: dict, trained_by: dict | None = None
) -> Path:
    """Write the policy file of a learner (``state``: module name -> state dict) at ``progress``
    (``env_steps``, ``updates``) to ``path``, atomically; returns the path."""
    weights = acting_weights(config.algo, dims, config.model, state)
    return save_policy_file(
        path,
        algo=config.algo,
        task=config.task,
        config=config.to_dict(),
        dims=dims.to_dict(),
        weights=weights,
        env_steps=progress["env_steps"],
        updates=progress.get("updates", 0),
        trained_by=trained_by,
    )


def policy_from_checkpoint(checkpoint: str | Path | dict, out: str | Path) -> Path:
    """Write the policy file of a checkpoint (a path, or what :func:`load_checkpoint` read) to ``out``."""
    data = checkpoint if isinstance(checkpoint, dict) else load_checkpoint(checkpoint)
    config = RunConfig.from_dict(data["config"])
    return save_policy(
        out,
        config,
        Dims(**data["progress"]["dims"]),
        data["trainer"],
        data["progress"],
        trained_by=data.get("versions"),
    )


def ensure_policy(run: str | Path) -> Path | None:
    """``run/policy.pt``, made from ``run/checkpoint.pt`` where it is missing (runs trained before
    policy files existed); None where the folder has neither."""
    run = Path(run)
    if (run / POLICY_FILE).is_file():
        return run / POLICY_FILE
    if (run / CHECKPOINT_FILE).is_file():
        return policy_from_checkpoint(run / CHECKPOINT_FILE, run / POLICY_FILE)
    return None


def policy_file_of(path: str | Path, need_checkpoint: str | None = None, flag: str = "--policy") -> Path:
    """The file ``--policy PATH`` names: the file itself, a shipped policy's (``pretrained:NAME``,
    :data:`PRETRAINED`), or in a run folder its ``checkpoint.pt``, else its ``policy.pt`` (a folder of committed
    small files has only that). ``need_checkpoint``:
    why the caller needs the checkpoint (then a folder's ``policy.pt`` is not taken); ``flag``: the
    argument named in errors.

    Raises:
        ValueError: a folder with neither file, or a path that does not exist.
    """
    if str(path).startswith("pretrained:"):  # a policy that ships with comat
        return pretrained_path(str(path), flag)
    path = Path(path)
    if path.is_dir():
        if (path / CHECKPOINT_FILE).is_file():
            return path / CHECKPOINT_FILE
        if need_checkpoint and (path / POLICY_FILE).is_file():
            raise ValueError(
                f"{flag} {str(path)!r} holds a policy.pt but no checkpoint.pt: {need_checkpoint}, which "
                "a policy file (the weights to act only) does not keep"
            )
        if not need_checkpoint and (path / POLICY_FILE).is_file():
            return path / POLICY_FILE
        files = "a checkpoint.pt" + ("" if need_checkpoint else " or a policy.pt")
        raise ValueError(
            f"{flag} {str(path)!r} is a folder without {files} (not a run folder, or its run has not saved one yet)"
        )
    if not path.is_file():
        raise ValueError(f"{flag} {str(path)!r}: no such file or folder")
    return path


def policy_modules(data: dict, path: str | Path = "policy") -> tuple[dict[str, torch.nn.Module], RunConfig]:
    """The modules (in eval mode) and run config of a checkpoint or policy file that
    :func:`comat.rl.checkpoint.load_trained` read from ``path``: a checkpoint's full learner
    modules, a policy file's acting modules.

    Raises:
        CheckpointError: weights that do not fit the model the stored config builds.
    """
    config = RunConfig.from_dict(data["config"])
    if data["format"] == POLICY_FORMAT:
        dims, state, acting_only = Dims(**data["dims"]), data["weights"], True
    elif data["format"] == FORMAT:
        dims, state, acting_only = Dims(**data["progress"]["dims"]), data["trainer"], False
    else:
        raise CheckpointError(f"{str(path)!r} is neither a comat checkpoint nor a policy file")
    modules = build_modules(config.algo, dims, config.model, acting_only=acting_only)
    for name, module in modules.items():
        if name not in state:
            raise CheckpointError(
                f"{str(path)!r} has no weights for the {config.algo} {name!r} module (has {sorted(state)})"
            )
        try:
            module.load_state_dict(state[name])
        except RuntimeError as err:
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise CheckpointError(
                f"{str(path)!r}: the {name!r} weights do not fit the {config.algo} model its config builds ({first})"
            ) from err
        module.eval()
    return modules, config


def describe_policy(path: str | Path, data: dict) -> str:
    """One line: what a policy file holds and what it weighs."""
    size = Path(path).stat().st_size
    return (
        f"{path} ({format_size(size)}): {data['algo']} on {data['task']}, {data['env_steps']:,} env steps, "
        f"{data.get('parameters', 0):,} parameters ({', '.join(data['weights'])}), trained by comat "
        f"{data['versions'].get('comat', '?')} ({data['versions'].get('commit', '?')})"
    )


def policy_weights(
    preset: str = "sweep", algos=None, tasks=None, folder: str | Path | None = None, seed: int = 0
) -> list[dict]:
    """What one policy file weighs per learner (default: every registered one) and task with a
    preset's model config: each model built (seeded, untrained: the size does not depend on the
    values) for the task's environments, its policy file written to ``folder`` (a temporary one if
    None) and measured.

    Rows: ``algo``, ``task``, ``parameters`` (kept in the policy file), ``learner_parameters``
    (all the learner's modules, critic and mixer included), ``bytes`` (the file)."""
    tasks = task_names() if tasks is None else tuple(tasks)
    algos = learner_names() if algos is None else tuple(algos)
    import tempfile

    settings = load_preset(preset)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(folder) if folder is not None else Path(tmp)
        for task in tasks:
            for algo in algos:
                config = resolve(settings, algo, task, seed=seed)
                env = make_run_env(config, 1, seed)
                try:
                    env.reset()  # as a run does before taking its sizes
                    dims = Dims.of(env)
                finally:
                    env.close()
                torch.manual_seed(seed)
                modules = build_modules(algo, dims, config.model)
                state = {name: m.state_dict() for name, m in modules.items()}
                path = save_policy(
                    where / f"{algo}_{task}" / POLICY_FILE, config, dims, state, {"env_steps": 0, "updates": 0}
                )
                data = torch.load(path, map_location="cpu", weights_only=True)
                rows.append(
                    {
                        "algo": algo,
                        "task": task,
                        "parameters": data["parameters"],
                        "learner_parameters": sum(p.numel() for m in modules.values() for p in m.parameters()),
                        "bytes": path.stat().st_size,
                    }
                )
    return rows


def load_policy(path: str | Path, algo: str | None = None, task: str | None = None):
    """A trained policy from a checkpoint or a policy file (``policy.pt``): ``(act, config)``
    with ``act(obs, mask, state) -> actions`` deterministic (numpy in and out).

    Raises:
        CheckpointError: naming the file and what is wrong with it.
    """
    modules, config = policy_modules(load_trained(path, algo=algo, task=task), path)
    return policy_act(config.algo, modules), config
