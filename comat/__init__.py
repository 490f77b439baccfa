"""comat: a MuJoCo Sim2Real testbed for heterogeneous robot teams on the Robotarium, and COMAT.

``comat.make_env(env_id, **options)`` gives a PettingZoo parallel environment (``"pcp_v0"``,
``"hmt_v0"``, …; ``comat.ENV_IDS`` lists those of the registered tasks) and
``comat.make_vec_env(env_id, num_envs, **options)`` the batched one;
``comat.load_policy(path_or_name)`` a trained policy that acts on their observation dicts
(:mod:`comat.policy_api`; ``"pretrained:comat-pcp"`` and the others of
:data:`comat.rl.policy.PRETRAINED` ship with the package). Subpackages: :mod:`comat.tasks` (the
tasks), :mod:`comat.mjcf` (MJCF generation), :mod:`comat.sim` (MuJoCo worlds),
:mod:`comat.safety` (barrier filter), :mod:`comat.envs` (the environments). Importing ``comat``
itself is light: the envs load on first use, and nothing here imports torch or rerun.
"""

from typing import Any

from comat._version import __version__

__all__ = ["ENV_IDS", "__version__", "load_policy", "make_env", "make_vec_env"]


def __getattr__(name: str) -> Any:
    if name in ("make_env", "make_vec_env"):
        from comat import envs

        return getattr(envs, name)
    if name == "ENV_IDS":  # the registered tasks' (comat.tasks: numpy only, light)
        from comat.tasks import TASKS

        return tuple(sorted(e.env_id for e in TASKS.values()))
    if name == "load_policy":
        from comat.policy_api import load_policy

        return load_policy
    raise AttributeError(f"module 'comat' has no attribute {name!r}")
