"""``comat train`` and ``comat policy``: train a run, and make or describe its policy file.

``comat/cli.py`` registers them with :func:`add_train_parsers`; each handler returns an exit code
and raises ValueError / TypeError (printed by ``comat.cli.main`` as one line) for bad input.
"""

from __future__ import annotations

import argparse
import sys
import time

from comat.cli.args import TASKS, TIERS, add_force
from comat.learners import learner_entry, learner_names

__all__ = [
    "MEASURED_ENV_STEPS_PER_S",
    "add_train_parsers",
    "cmd_policy",
    "cmd_train",
    "overlap_note",
    "paper_budget_note",
    "print_policy_file",
]


MEASURED_ENV_STEPS_PER_S = {
    ("comat", "pcp"): (190, 686),
    ("comat", "hmt"): (144, 407),
    ("mat", "pcp"): (280, 856),
    ("mat", "hmt"): (179, 447),
}
"""Env steps per second on this project's 2-core machine, (slow, fast): whole 300 k runs with one
torch thread and other work beside them (``wall_s`` of the kept policies' ``progress.csv``,
results/policies/), and training alone with 2 env workers and nothing else running (``comat bench
learn``, 2026-12-06, results/speed/learn_spin.json; evaluations add their own time). What the first
line's time estimate for the paper's budget rests on."""


def paper_budget_note(config) -> str:
    """The first line of ``comat train`` without ``--preset``: the paper's budget and what it costs."""
    low, high = MEASURED_ENV_STEPS_PER_S.get((config.algo, config.task), (150, 350))

    def span(a: float, b: float, unit: str) -> str:
        return f"{a:.0f} {unit}" if round(a) == round(b) else f"{a:.0f}-{b:.0f} {unit}"

    hours = span(config.total_env_steps / high / 3600, config.total_env_steps / low / 3600, "h")
    return (
        f"no --preset: the paper's budget, {config.total_env_steps:,} env steps (about {hours} on a laptop-class "
        f"CPU: {config.algo.upper()} on {config.task.upper()} ran {span(low, high, 'env-steps/s')} here); for a first "
        "look use --preset quick (minutes) or --preset sweep (300 k steps, 15-35 min)"
    )


def overlap_note(config, cpus: int) -> str | None:
    """A note where ``ppo.overlap`` leaves the collection no core of its own: the env workers, the
    collecting thread and the learner's threads together want more than the usable CPUs."""
    if not config.overlap or config.env_workers + 1 + config.torch_threads <= cpus:
        return None
    threads = max(1, cpus - config.env_workers - 1)
    return (
        f"note: ppo.overlap with {config.env_workers} env worker(s), the collecting thread and "
        f"{config.torch_threads} learner thread(s) on {cpus} CPU(s): the collection and the update fight for "
        f"the cores (slower than without overlap on 2 CPUs, docs/speed.md); fewer env workers or "
        f"torch_threads={threads} leave each its own"
    )


def cmd_train(args: argparse.Namespace) -> int:
    from pathlib import Path

    from comat.machine import usable_cpus
    from comat.rl import RunConfig, train

    if args.resume and args.overrides:
        raise ValueError(
            f"--resume continues a run with its own settings; overrides {args.overrides} are for a new run"
        )
    config = _resumed_config(args) if args.resume else _new_config(args)
    # A new folder per run by default, named so it cannot be taken for a kept or shipped policy
    # (results/policies/comat_pcp_s0, pretrained:comat-pcp).
    out = Path(args.out or f"runs/train-{config.algo}-{config.task}-seed{config.seed}-{time.strftime('%Y%m%d-%H%M%S')}")
    cpus = usable_cpus()
    if config.torch_threads > cpus and not args.resume:  # more threads than usable CPUs only contend (a resumed
        # run keeps its recorded count: the reductions, hence the results, depend on it)
        print(
            f"note: torch_threads {config.torch_threads} > the {cpus} CPU(s) this run may use (affinity): using {cpus}",
            file=sys.stderr,
        )
        config = RunConfig.from_dict({**config.to_dict(), "torch_threads": cpus})
    note = overlap_note(config, cpus)
    if note and not args.resume:
        print(note, file=sys.stderr)
    print(
        f"comat train: {config.algo} on {config.task} ({config.tier} tier, reality {config.reality.label}, "
        f"updates on {config.device}), seed {config.seed}, "
        f"{config.total_env_steps:,} env steps -> {out}{' (resuming)' if args.resume else ''}; "
        f"CPUs: {cpus} usable (affinity), torch threads {config.torch_threads}, env workers {config.env_workers}"
        + (", the next rollout collected beside each update (ppo.overlap)" if config.overlap else ""),
        file=sys.stderr,
    )
    record = None
    if args.rrd_every:
        from comat.viz import record_training as record  # Rerun loads only when a run records

    summary = train(
        config,
        out,
        resume=args.resume,
        quiet=args.quiet,
        rrd_every=args.rrd_every,
        overrides=tuple(args.overrides),
        record=record,
    )
    ev = summary["eval_train"]
    result = (
        ""
        if ev is None
        else (
            f"; on the training coalitions (deterministic): return {ev['return']:.2f}, finished "
            f"{ev['finished']:.0%} of episodes (progress {ev['progress']:.0%}), steps {ev['steps']:.1f}, "
            f"collisions {ev['collisions']:.2f}"
        )
    )
    print(f"done: {summary['env_steps']:,} env steps in {summary['wall_s'] / 60:.1f} min{result}; run folder {out}")
    print_policy_file(out / "policy.pt")
    return 0


def _resumed_config(args: argparse.Namespace):
    """The config of the run in ``--out`` to continue (its checkpoint's, or its saved config.yaml when
    it stopped before the first checkpoint), with ``--steps`` applied; flags that would change the run
    are refused."""
    from pathlib import Path

    from comat.rl import RunConfig, load_checkpoint, resolve_device, saved_config

    if args.out is None:
        raise ValueError("--resume needs --out, the folder of the run to continue")
    ckpt = Path(args.out) / "checkpoint.pt"
    config = None if ckpt.exists() else saved_config(args.out)  # stopped before its first checkpoint
    if config is None:
        data = load_checkpoint(ckpt, algo=args.algo, task=args.task)
        config = RunConfig.from_dict(data["config"])
    device = None if args.device is None else resolve_device(args.device)
    for name, given in (
        ("seed", args.seed),
        ("tier", args.tier),
        ("env_workers", args.env_workers),
        ("device", device),
    ):
        if given is not None and given != getattr(config, name):
            raise ValueError(f"--{name} {given!r} does not match the run being resumed ({getattr(config, name)!r})")
    if args.steps is not None:
        config = RunConfig.from_dict({**config.to_dict(), "total_env_steps": args.steps})
    return config


def _new_config(args: argparse.Namespace):
    """A new run's config: the preset (default ``paper``, whose budget is noted) with the overrides and flags."""
    from comat.rl import apply_overrides, load_preset, resolve, resolve_device

    if args.algo is None or args.task is None:
        raise ValueError("--algo and --task are required for a new run")
    config = resolve(
        apply_overrides(load_preset(args.preset or "paper"), args.overrides),
        args.algo,
        args.task,
        args.seed,
        args.tier,
        args.steps,
        args.env_workers,
        resolve_device(args.device or "auto"),
    )
    if args.preset is None and args.steps is None:
        print(paper_budget_note(config), file=sys.stderr)
    return config


def print_policy_file(path) -> None:
    from comat.rl import format_size

    print(
        f"{path} ({format_size(path.stat().st_size)}): weights and config to act; evaluate with "
        f"comat eval --policy {path} (U_train and U_test, the files beside it)"
    )


def cmd_policy(args: argparse.Namespace) -> int:
    from pathlib import Path

    from comat.files import new_outputs
    from comat.rl import (
        POLICY_FILE,
        POLICY_FORMAT,
        describe_policy,
        load_trained,
        policy_file_of,
        policy_from_checkpoint,
    )

    # a run folder: its checkpoint.pt, else its policy.pt
    source = policy_file_of(args.source, flag="RUN_FOLDER|CHECKPOINT|POLICY")
    data = load_trained(source)  # CheckpointError (a ValueError) names a foreign or corrupt file
    if data["format"] == POLICY_FORMAT:
        if args.out is not None:
            raise ValueError(
                f"--out: {str(source)!r} is already a policy file (copy it to move it); give a "
                "checkpoint.pt or a run folder with one to make a policy file"
            )
        print(describe_policy(source, data))
        return 0
    out = Path(args.out) if args.out is not None else source.parent / POLICY_FILE
    if out.is_dir():
        out = out / POLICY_FILE
    elif out.suffix != ".pt":
        raise ValueError(f"--out must be a .pt file or an existing folder, got {str(out)!r}")
    with new_outputs(out.parent, [out.name], force=args.force):
        policy_from_checkpoint(data, out)
    print_policy_file(out)
    return 0


def _task(value: str) -> str:
    """``--task``: a registered task, or an outside env (``outside:MODULE``, checked when resolved)."""
    if value in TASKS or value.startswith("outside:"):
        return value
    raise argparse.ArgumentTypeError(f"invalid choice: {value!r} (choose from {', '.join(TASKS)} or outside:MODULE)")


def add_train_parsers(sub) -> None:
    """Register ``train`` and ``policy`` on the top-level sub-parsers of ``comat``."""
    _add_train_parser(sub)
    _add_policy_parser(sub)


def _add_train_parser(sub) -> None:
    p = sub.add_parser(
        "train",
        help=f"train a learner ({', '.join(learner_entry(n).label for n in learner_names())}) on any registered task",
        description="Train a policy on the task's training coalitions (U_train), with periodic "
        "evaluation, CSV + TensorBoard logs, atomic checkpoints and --resume. Settings come from a "
        "preset (train/configs/ in a checkout, comat/data/presets/ when installed; values only); the resolved "
        "config is written to the run folder.",
    )
    p.add_argument("--algo", choices=learner_names(), help="learner (required for a new run; comat.learners)")
    p.add_argument(
        "--task",
        type=_task,
        metavar="{" + ",".join(TASKS) + "} or outside:MODULE",
        help="task (required for a new run); outside:MODULE trains on an outside PettingZoo env, e.g. "
        "outside:mpe2.simple_spread_v3 (docs/commands.md)",
    )
    p.add_argument(
        "--preset",
        default=None,
        help="preset name (paper, quick, learning, sweep; train/configs/) or a YAML path (default: paper, the "
        "paper's 4 M env steps: hours; the first line says how many)",
    )
    p.add_argument("--seed", type=int, default=None, help="run seed (default: the preset's first seed)")
    p.add_argument("--tier", choices=TIERS, default=None, help="dynamics tier (default: the preset's)")
    p.add_argument("--steps", type=int, default=None, help="total env steps (default: the preset's)")
    p.add_argument(
        "--env-workers",
        type=int,
        default=None,
        help="processes stepping the environments (default: the preset's; results are reproducible for the same value)",
    )
    p.add_argument(
        "--device",
        choices=["auto", "cpu", "cuda"],
        default=None,
        help="where the learner's update runs; acting stays on the CPU (default: auto, cuda where "
        "PyTorch sees one; a resumed run keeps its own)",
    )
    p.add_argument(
        "--out", default=None, help="run folder (default: a new one, runs/train-<algo>-<task>-seed<seed>-<date>-<time>)"
    )
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its checkpoint")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.add_argument(
        "--rrd-every",
        type=int,
        default=0,
        metavar="K",
        help="record 2 evaluation episodes to RUN/rrd/eval_<steps>.rrd every K-th evaluation "
        "(and the last); 0: never (default)",
    )
    p.add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help="settings changed from the preset, dotted as in the YAML (e.g. ppo.lr=3e-4 "
        "models.comat.heads=8 total_env_steps=200000; reality=nominal trains under the reality layer, "
        "drawn afresh every episode, reality.pose_delay_ticks=2 changes one of its fields); typed and "
        "checked like the preset",
    )
    p.set_defaults(func=cmd_train)


def _add_policy_parser(sub) -> None:
    p = sub.add_parser(
        "policy",
        help="write a run's policy file (weights and config to act) from its checkpoint",
        description="Make the policy file of a trained run: policy.pt, the float32 weights "
        "deterministic acting needs (COMAT's and MAT's policy, MAPPO's actors, QMIX's agent network) "
        "with the resolved run config, sizes, versions and env steps; no optimizer state, critic, "
        "mixer or replay buffer, so it is small enough to commit. comat train writes it when a run "
        "finishes; this makes it for a run trained before. Every --policy takes it (eval, rollout, "
        "export, bench viz; probe and --resume need the checkpoint). Given a policy.pt, prints what "
        "it holds and weighs.",
    )
    p.add_argument(
        "source",
        metavar="RUN_FOLDER|CHECKPOINT|POLICY",
        help="a run folder (its checkpoint.pt, else its policy.pt), a checkpoint.pt, or a policy.pt to describe",
    )
    p.add_argument(
        "--out",
        default=None,
        metavar="FILE.pt|FOLDER",
        help="a .pt file to write (its folder created if missing) or an existing folder (default: "
        "policy.pt next to the checkpoint)",
    )
    add_force(p)
    p.set_defaults(func=cmd_policy)
