"""Benchmarks behind ``comat bench``, and the safety scenarios the tests and the demo share.

===================  ==========================================================================
``bench sim``        :func:`run_sim_bench`: a control tick's cost, ours vs the Robotarium simulator's
``bench env``        :func:`run_env_bench` (env-steps/s per task, tier, batch, team size),
                     :func:`run_rollout_bench` (where a rollout's time goes)
``bench learn``      :func:`run_learn_bench` (decoding and training throughput),
                     :func:`bench_train` (one learner's env-steps/s); the rows it can time beside
                     the defaults: :data:`COMAT_VARIANTS`, :data:`WIDE_SLOTS`,
                     :data:`OVERLAP_CHOICES`, :func:`learn_rows` (importable without torch)
``bench safety``     :func:`run_safety_bench` (the battery at reality levels, judged on true poses:
                     :data:`SCENARIO_NAMES`, :data:`CROSSING_NAMES`, loops :data:`DEFAULT_LOOPS`),
                     :func:`run_mismatch` (:data:`MISMATCH_SCENARIOS`)
``bench fidelity``   :func:`run_fidelity_bench`: the MuJoCo robot against the unicycle model
``bench soak``       :func:`run_soak`: many reference episodes, checking that nothing drifts
scenarios            :data:`SCENARIOS` (safe starts), :data:`CROSSINGS` (dense crossings),
                     :data:`FAULTS`, :data:`UNSAFE_STARTS`; :func:`make_scenario` draws a batch of
                     episodes (R robots: poses (R, 3), goals (R, 2)), :func:`run_scenario` runs it,
                     :func:`swap_scenario` (``comat demo``'s swap)
===================  ==========================================================================

Outside this package, import these names from ``comat.bench``, not from its modules (an
import-linter contract in pyproject.toml keeps it). They load on first use (:mod:`comat._face`):
``bench learn`` loads torch, and ``comat --help`` reads the scenario and variant names without it.
"""

from comat._face import lazy_face

__all__, __getattr__, __dir__ = lazy_face(
    __name__,
    {
        "comat.bench.env_bench": "run_env_bench run_rollout_bench",
        "comat.bench.fidelity_bench": "run_fidelity_bench",
        "comat.bench.learn_bench": "bench_train run_learn_bench",
        "comat.bench.safety_bench": (
            "CROSSING_NAMES DEFAULT_LOOPS MISMATCH_SCENARIOS SCENARIO_NAMES run_mismatch run_safety_bench"
        ),
        "comat.bench.scenarios": "CROSSINGS FAULTS SCENARIOS UNSAFE_STARTS make_scenario run_scenario swap_scenario",
        "comat.bench.sim_bench": "run_sim_bench",
        "comat.bench.soak": "run_soak",
        "comat.bench.variants": "COMAT_VARIANTS OVERLAP_CHOICES WIDE_SLOTS learn_rows",
    },
)
