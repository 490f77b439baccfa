"""Training: run configs, the trainers, checkpoints and policy files (``comat train``, ``comat policy``).

===================  ==========================================================================
run config           :func:`load_preset` (a preset of ``comat/data/presets``) → :func:`apply_overrides`
                     (``key=value``) → :func:`resolve` (one algo, task, seed) → :class:`RunConfig`
                     (:mod:`comat.rl.config`; :data:`TASKS`, the task names a run accepts)
a run                :func:`train` (config, out folder; ``resume``) writes config.yaml, checkpoints,
                     ``policy.pt``, progress and evaluation tables (:mod:`comat.rl.runner`);
                     :func:`saved_config` reads a folder's config back
learners             :func:`make_run_env`, :func:`make_learner` and :func:`build_modules` from
                     :class:`Dims`; :func:`act_with` / :func:`policy_act` act;
                     :func:`robot_slots` (``BASELINE_ROBOTS``) (:mod:`comat.rl.algos`);
                     :func:`check_learner`: what every registered learner must do
trainers             :class:`PPOTrainer` / :class:`PPOConfig` (COMAT, MAT, MAPPO, …; paper eq. 6–9),
                     :class:`QmixTrainer` / :class:`QmixConfig`
checkpoints          :func:`load_checkpoint`, :func:`load_trained` (a checkpoint or a policy file),
                     :class:`CheckpointError`, ``POLICY_FORMAT``; :func:`versions` and
                     :func:`source_commit` (what a run's numbers depend on), :func:`current_name`
policy files         :func:`load_policy` → ``(act, config)``; :func:`policy_file_of` (what ``--policy``
                     names), :data:`PRETRAINED` (``pretrained:NAME``, ``PREFIX``) and
                     :func:`pretrained_path`, :func:`policy_from_checkpoint`, :func:`ensure_policy`,
                     :func:`policy_modules`, :func:`describe_policy`, :func:`shipped_name`,
                     :func:`policy_weights`, :func:`format_size`, ``POLICY_FILE``
update device        :func:`resolve_device` (``--device``, one of :data:`DEVICES`)
===================  ==========================================================================

Outside this package, import these names from ``comat.rl``, not from its modules (an import-linter
contract in pyproject.toml keeps it). They load on first use (:mod:`comat._face`): most of the
modules import torch, and the command line's parser must not.
"""

from comat._face import lazy_face

__all__, __getattr__, __dir__ = lazy_face(
    __name__,
    {
        "comat.rl.algos": (
            "BASELINE_ROBOTS Dims act_with build_modules make_learner make_run_env policy_act robot_slots"
        ),
        "comat.rl.checkpoint": (
            "CheckpointError POLICY_FORMAT current_name load_checkpoint load_trained source_commit versions"
        ),
        "comat.rl.config": "RunConfig TASKS apply_overrides load_preset resolve",
        "comat.rl.contract": "check_learner",
        "comat.rl.device": "DEVICES resolve_device",
        "comat.rl.policy": (
            "POLICY_FILE PREFIX PRETRAINED describe_policy ensure_policy format_size load_policy policy_file_of "
            "policy_from_checkpoint policy_modules policy_weights pretrained_path shipped_name"
        ),
        "comat.rl.ppo": "PPOTrainer",
        "comat.rl.ppo_config": "PPOConfig",
        "comat.rl.qmix": "QmixConfig QmixTrainer",
        "comat.rl.runner": "EVAL_SEED_OFFSET saved_config train",
    },
)
