"""Evaluation: trained policies on composition sets, the reports, sweeps, campaigns and replays.

===================  ==========================================================================
``comat eval``       :func:`evaluate_policies` (a policy and the reference ladder, :data:`REFERENCES`,
                     on the sets, seed :data:`EVAL_SEED`) → :func:`write_results` /
                     :func:`result_files`, :func:`print_table` (:mod:`comat.eval.evaluate`);
                     ``--reality-sweep``: :func:`run_reality_sweep`, :func:`sweep_values`,
                     :func:`write_sweep`, :func:`sweep_files`, :func:`print_sweep`
                     (:mod:`comat.eval.robustness`)
``comat probe``      :func:`probe_checkpoint`, :func:`write_probe`, :func:`print_probe`: a learner's
                     value estimates beside the returns it earns
``comat report``     :func:`make_report` (Table I, Fig. 4, 5, team size; :data:`REPORT_FILES`, with
                     sweeps :data:`ROBUSTNESS_FILES`); :func:`write_marl_eval`,
                     :func:`marl_eval_name` (marl-eval JSON); :data:`SETS` and :data:`SET_NAMES`,
                     the composition sets in table order and as the reports name them
``comat sweep``      :func:`prepare_sweep`, :func:`run_sweep`, :func:`sweep_status` (Ray Tune grid;
                     its record :data:`RECORD`)
``comat validity``   :func:`run_validity`, :func:`collect`, :func:`write_summary` (seed
                     :data:`VALIDITY_SEED`): does a task demand what it tests?
``comat campaign``   :func:`make_campaign`, :func:`plan_teams`, :func:`declarations`,
                     :func:`parse_sizes`, :func:`parse_sets`, :func:`stand_in_returns`; what comes back:
                     :func:`analyze_campaign`
``comat replay``     :func:`replay_log` (a real run beside its simulated twin; ``replay`` in
                     :mod:`comat.eval.replay`), :func:`check_options`, :func:`check_twin`,
                     :func:`output_names`
===================  ==========================================================================

Outside this package, import these names from ``comat.eval``, not from its modules (an import-linter
contract in pyproject.toml keeps it). They load on first use (:mod:`comat._face`): evaluation loads
torch, and ``comat --help`` reads :data:`VALIDITY_SEED` without it.
"""

from comat._face import lazy_face

__all__, __getattr__, __dir__ = lazy_face(
    __name__,
    {
        "comat.eval.campaign": "declarations make_campaign parse_sets parse_sizes plan_teams stand_in_returns",
        "comat.eval.campaign_returns": "analyze_campaign",
        "comat.eval.evaluate": "EVAL_SEED REFERENCES evaluate_policies print_table result_files write_results",
        "comat.eval.marl_eval": "marl_eval_name write_marl_eval",
        "comat.eval.probe": "print_probe probe_checkpoint write_probe",
        "comat.eval.replay": "check_options check_twin output_names replay_log",
        "comat.eval.report": "REPORT_FILES make_report",
        "comat.eval.robustness": "ROBUSTNESS_FILES print_sweep run_reality_sweep sweep_files sweep_values write_sweep",
        "comat.eval.runs": "SETS SET_NAMES",
        "comat.eval.sweep": "RECORD prepare_sweep run_sweep sweep_status",
        "comat.eval.validity": "VALIDITY_SEED collect run_validity write_summary",
    },
    # the function ``replay`` shares its module's name: once comat.eval.replay is imported, the
    # package's attribute ``replay`` is that module, so the face names the function replay_log
    renamed={"replay_log": "replay"},
)
