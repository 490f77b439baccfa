"""Torch COMAT model -> the numpy weights file of ``sim2real.runtime`` (the format lives there).

``comat_arrays(model)`` gives ``(config, arrays)``: the weights config (``comat_schema``'s
layout and ``ComatConfig`` sizes and options) and every array the deployed policy needs, named and
shaped as ``comat_schema.weight_shapes`` describes them (the critic left out, the decision layer
in acting form), as float32 numpy arrays. ``export_weights(model, path)`` writes them as one
``.npy`` (see ``sim2real.runtime`` for the layout). torch is only touched through the model's own
tensors, so this module imports no torch itself.
"""

from __future__ import annotations

import numpy as np

from comat.models import check_arrays, parameter_shapes, weights_config
from sim2real.runtime import save_weights

__all__ = ["comat_arrays", "export_weights"]


def comat_arrays(model) -> tuple[dict, dict[str, np.ndarray]]:
    """(config, name -> float32 array) of a ``comat.models.comat.Comat``, critic excluded."""
    layout, cfg = getattr(model, "layout", None), getattr(model, "config", None)
    if layout is None or cfg is None or not hasattr(model, "state_dict") or not hasattr(model, "acting_arrays"):
        raise TypeError(
            f"model must be a comat Comat (with .layout, .config, .state_dict, .acting_arrays), "
            f"got {type(model).__name__}"
        )
    config = weights_config(layout, cfg)
    # Only the critic is dropped: any other entry the description does not know (a changed model)
    # must fail here rather than vanish from the export.
    trained = {k: v for k, v in model.state_dict().items() if not k.startswith("critic.")}
    check_arrays(trained, parameter_shapes(config, critic=False), "model does not match the numpy runtime")
    arrays = {k: v.detach().cpu().numpy().astype(np.float32) for k, v in model.acting_arrays().items()}
    return config, arrays


def export_weights(model, path) -> None:
    """Write ``model``'s deployment weights to ``path`` (one ``.npy``, loadable without pickle)."""
    config, arrays = comat_arrays(model)
    save_weights(path, arrays, config)
