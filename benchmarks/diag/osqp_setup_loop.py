"""Usage: python benchmarks/diag/osqp_setup_loop.py {plain,warm,info,sol,settings}  (issue 21)

Does an OSQP problem that is set up, used the way comat.safety.qp uses it (warm start, solve,
info, solution, settings) and dropped leave memory behind? Prints RSS after every 3,000
problems; flat (52.6 MiB here, osqp 1.1.3) for every mode.
"""

import gc
import sys

import numpy as np
import osqp
import scipy.sparse as sp

from comat.bench.soak import _rss_bytes
from comat.heap import release_free_heap

rng = np.random.default_rng(0)
n, m = 80, 200
A = sp.random(m, n, density=0.05, random_state=0, format="csc")
mode = sys.argv[1]


def once():
    s = osqp.OSQP()
    s.setup(
        sp.identity(n, format="csc"),
        -rng.normal(size=n),
        A,
        -np.ones(m),
        np.ones(m),
        verbose=False,
        polishing=True,
        warm_starting=True,
        check_termination=10,
    )
    ext = s._solver
    if mode == "warm":
        ext.warm_start(np.zeros(n), np.zeros(m))
    ext.solve()
    if mode == "info":
        _ = ext.info.status_val
    if mode == "sol":
        _ = np.array(ext.solution.x)
    if mode == "settings":
        s.update_settings(eps_abs=1e-5, eps_rel=1e-5)


for k in range(4):
    for _ in range(3000):
        once()
    gc.collect()
    release_free_heap()
    print(mode, k, round(_rss_bytes() / 2**20, 1), flush=True)
