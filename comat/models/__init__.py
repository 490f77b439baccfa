"""The learners' networks (torch): COMAT and the baselines, and what they read of an observation.

Every model takes ``obs`` (B, N, D) and ``mask`` (B, N) (True for real robots) and gives actions
(B, N) over the 5 waypoint actions; each learner's registry entry (:mod:`comat.learners`) names its
config and ``build`` by module path (``comat.models.mat:build``, …), so the learners themselves
are not on this face.

===================  ==========================================================================
COMAT                :class:`Comat` / :class:`ComatConfig` (HEAT encoder, capability-oriented
                     autoregressive decoder; :data:`PAPER_FORM`, the paper's encoder options);
                     :class:`AutoregressivePolicy`, the decode-robot-by-robot base of COMAT and MAT
observations         :class:`ObsLayout`: where type, capabilities and task features sit in an
                     observation (:mod:`comat.models.features`)
building blocks      :func:`mlp`, :func:`choose_actions`, :func:`score_actions`, for a learner of
                     one's own (docs/write-a-learner.md)
COMAT's weights      :func:`weights_config`, :func:`parameter_shapes`, :func:`check_arrays`,
                     :data:`DECISIONS` (:mod:`comat.models.comat_schema`: numpy only, shipped
                     verbatim inside exports, where it is ``comat_schema``)
===================  ==========================================================================

Outside this package, import these names from ``comat.models``, not from its modules (an
import-linter contract in pyproject.toml keeps it; the export, which copies comat_schema.py as a
file, is the one exception). They load on first use (:mod:`comat._face`): ``import sim2real`` and
``comat --help`` read comat_schema without loading torch.
"""

from comat._face import lazy_face

__all__, __getattr__, __dir__ = lazy_face(
    __name__,
    {
        "comat.models.autoregressive": "AutoregressivePolicy",
        "comat.models.comat": "PAPER_FORM Comat ComatConfig",
        "comat.models.comat_schema": "DECISIONS check_arrays parameter_shapes weights_config",
        "comat.models.features": "ObsLayout",
        "comat.models.layers": "choose_actions mlp score_actions",
    },
)
