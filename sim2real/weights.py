"""Torch COMAT model -> the numpy weights file of ``sim2real.runtime`` (the format lives there).

``comat_arrays(model)`` gives ``(config, arrays)``: the runtime's config (layout and
``ComatConfig`` sizes) and every ``state_dict`` entry the deployed policy needs, as float32
numpy arrays under their torch names (the critic is left out). ``export_weights(model, path)``
writes them as one ``.npy`` (see ``sim2real.runtime`` for the layout). torch is only touched
through the model's own tensors, so this module imports no torch itself.
"""

from __future__ import annotations

import numpy as np

from sim2real.runtime import CONFIG_KEYS, expected_shapes, save_weights

__all__ = ["comat_arrays", "export_weights"]


def comat_arrays(model) -> tuple[dict[str, int], dict[str, np.ndarray]]:
    """(config, name -> float32 array) of a ``comat.models.comat.Comat``, critic excluded."""
    layout, cfg = getattr(model, "layout", None), getattr(model, "config", None)
    if layout is None or cfg is None or not hasattr(model, "state_dict"):
        raise TypeError(f"model must be a comat Comat (with .layout, .config, .state_dict), got {type(model).__name__}")
    config = {"obs_dim": layout.obs_dim, "n_types": layout.n_types, "n_caps": layout.n_caps,
              "embed": cfg.embed, "heads": cfg.heads, "heat_blocks": cfg.heat_blocks, "edge_embed": cfg.edge_embed,
              "root_weight": int(cfg.root_weight), "obs_embed": int(cfg.obs_embed), "node_ffn": int(cfg.node_ffn),
              "reference_messages": int(cfg.heat_form == "reference"), "world_edges": int(cfg.edge_frame == "world"),
              "shared_trunk": int(cfg.decision in ("shared_trunk", "adapters"))}
    assert set(config) == set(CONFIG_KEYS)
    # Only the critic is dropped: any other entry the runtime does not know (a changed model)
    # must fail the shape check below rather than vanish from the export.
    arrays = {k: v.detach().cpu().numpy().astype(np.float32)
              for k, v in model.state_dict().items() if not k.startswith("critic.")}
    if cfg.decision == "adapters":  # folded into each type's output layer: the shared-trunk form
        w2, b2 = (t.detach().cpu().numpy().astype(np.float32) for t in model.heads.output_layer())
        arrays.update({"heads.w2": w2, "heads.b2": b2})
        del arrays["heads.w2_shared"], arrays["heads.b2_shared"]
    missing = sorted(set(expected_shapes(config)) - set(arrays))
    extra = sorted(set(arrays) - set(expected_shapes(config)))
    if missing or extra:
        raise ValueError(f"model does not match the numpy runtime: missing {missing}, unexpected {extra}")
    return config, arrays


def export_weights(model, path) -> None:
    """Write ``model``'s deployment weights to ``path`` (one ``.npy``, loadable without pickle)."""
    config, arrays = comat_arrays(model)
    save_weights(path, arrays, config)
