"""Usage: python benchmarks/diag/osqp_live_in_env.py  (issue 21)

A U_scale PCP vector env (32 envs), scripted episodes: OSQP setups so far and live BarrierQP
objects after each batch (~95 setups per batch, one live BarrierQP, here).
"""

import gc

import osqp

from comat.envs import make_vec_env
from comat.envs.base import resolve_coalitions
from comat.envs.heuristics import heuristic_actions
from comat.measure.episodes import run_episodes
from comat.safety.qp import BarrierQP

made = [0]
real_setup = osqp.OSQP.setup


def counted_setup(self, *args, **kwargs):
    made[0] += 1
    return real_setup(self, *args, **kwargs)


osqp.OSQP.setup = counted_setup
env = make_vec_env("pcp_v0", 32, seed=0, tier="unicycle", coalitions="scale")
teams = resolve_coalitions("scale", "pcp")
for k in range(4):
    run_episodes(env, lambda obs, mask, state: heuristic_actions(env.core), teams, 1000 * k)
    gc.collect()
    live = sum(isinstance(o, BarrierQP) for o in gc.get_objects())
    print(k, "setups so far", made[0], "live BarrierQP", live, flush=True)
