"""COMAT's weights, described once: every array's name and shape, and the decision layer's form.

Three implementations of COMAT read this module: the torch model (``comat.models.comat``, which
checks its parameters against it when built), the compiled acting kernels
(``comat.models.act_kernels``, whose argument tuples are built from these names) and the numpy
runtime of a Robotarium export (``sim2real.runtime``, whose weights file holds these names). An
architecture change is therefore written here and in the torch module; the kernels and the
runtime then fail with the array's name, expected and received shape until they follow.

This module imports numpy and the standard library only: an export ships it verbatim, as
``comat_schema.py`` beside ``runtime.py``, to a Python without torch or numba.

Names are the torch ``state_dict`` keys (``heat.0.node.1.weight``, ``cross_attn.kv.bias``, ...).
Two forms of the decision layer (``heads.*``) exist:

* the trained form (:func:`parameter_shapes`): the parameters the torch model holds, e.g.
  ``decision: adapters`` keeps a shared output layer ``heads.w2_shared`` (H, A) and
  ``heads.b2_shared`` (A,) next to each type's own part ``heads.w2`` (T, H, A), ``heads.b2`` (T, A);
* the acting form (:func:`weight_shapes`): what inference reads, each type's output layer whole
  (the adapters' shared layer added to each type's part), so acting knows only whether the hidden
  layer is one per type or one for all (:attr:`DecisionMode.shared_hidden`).

The config (:data:`CONFIG_KEYS`) is what fixes the shapes: the observation layout (obs_dim D,
n_types T, n_caps C), ``ComatConfig``'s sizes (embed E, heads K, heat_blocks, edge_embed d_e),
its architecture options as 0/1 and the decision mode's name; :func:`weights_config` builds it.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from enum import Enum

import numpy as np

__all__ = [
    "CONFIG_KEYS",
    "DECISIONS",
    "FLAG_KEYS",
    "N_ACTIONS",
    "DecisionMode",
    "check_arrays",
    "decision_shapes",
    "decoder_shapes",
    "encoder_shapes",
    "normalize_config",
    "parameter_shapes",
    "weight_shapes",
    "weights_config",
]

N_ACTIONS = 5
"""A: stay and the four moves of the task's action set."""


class DecisionMode(str, Enum):
    """``ComatConfig.decision``: the decision layer on [h_m ‖ c_m], type-stratified in every mode.

    The value is the config's string, so ``DecisionMode(config.decision)`` converts and
    ``mode == "adapters"`` compares."""

    TYPE_HEADS = "type_heads"
    """One two-layer head per robot type: hidden layer (T·H, in), output layer per type."""
    SHARED_TRUNK = "shared_trunk"
    """A hidden layer shared by all robots (H, in), an output layer per type."""
    ADAPTERS = "adapters"
    """A hidden and an output layer every robot trains, plus a per-type part of the output layer
    that starts at zero."""

    @property
    def shared_hidden(self) -> bool:
        """Whether one hidden layer serves every type (its weight (H, in) instead of (T·H, in)):
        the only difference acting sees, once adapters are folded into each type's output layer."""
        return self is not DecisionMode.TYPE_HEADS

    @property
    def adapters(self) -> bool:
        """Whether the trained layer holds a shared output layer next to the per-type parts."""
        return self is DecisionMode.ADAPTERS


DECISIONS = tuple(m.value for m in DecisionMode)
FLAG_KEYS = ("root_weight", "obs_embed", "node_ffn", "reference_messages", "world_edges")
"""``ComatConfig``'s encoder options as 0/1: ``root_weight``, ``obs_embed``, ``node_ffn``,
``heat_form == "reference"``, ``edge_frame == "world"``."""
CONFIG_KEYS = ("obs_dim", "n_types", "n_caps", "embed", "heads", "heat_blocks", "edge_embed", *FLAG_KEYS, "decision")


def weights_config(layout, config) -> dict:
    """The config of :data:`CONFIG_KEYS` of a COMAT built for ``layout`` (an ``ObsLayout``) and
    ``config`` (a ``ComatConfig``); both are read by attribute only."""
    return normalize_config(
        {
            "obs_dim": layout.obs_dim,
            "n_types": layout.n_types,
            "n_caps": layout.n_caps,
            "embed": config.embed,
            "heads": config.heads,
            "heat_blocks": config.heat_blocks,
            "edge_embed": config.edge_embed,
            "root_weight": config.root_weight,
            "obs_embed": config.obs_embed,
            "node_ffn": config.node_ffn,
            "reference_messages": config.heat_form == "reference",
            "world_edges": config.edge_frame == "world",
            "decision": config.decision,
        }
    )


def normalize_config(config: Mapping) -> dict:
    """``config`` with exactly :data:`CONFIG_KEYS`: sizes and flags as int, ``decision`` as the
    mode's string; ValueError naming a missing key or an unknown decision mode."""
    missing = [k for k in CONFIG_KEYS if k not in config]
    if missing:
        raise ValueError(f"config must have keys {list(CONFIG_KEYS)}, missing {missing}")
    decision = config["decision"]
    if decision not in DECISIONS:
        raise ValueError(f"config decision must be one of {list(DECISIONS)}, got {decision!r}")
    out = {k: int(config[k]) for k in CONFIG_KEYS if k != "decision"}
    out["decision"] = DecisionMode(decision).value
    return out


def _key(config: Mapping) -> tuple:
    return tuple((k, config[k]) for k in CONFIG_KEYS)


def decision_shapes(
    mode, d_in: int, hidden: int, d_out: int, n_types: int, trained: bool = False
) -> dict[str, tuple[int, ...]]:
    """Shapes of the decision layer's arrays (names relative to it): ``first.weight``
    (T·H or H, in), ``first.bias``, ``w2`` (T, H, out), ``b2`` (T, out); ``trained`` with
    ``adapters``: also ``w2_shared`` (H, out) and ``b2_shared`` (out,)."""
    mode = DecisionMode(mode)
    width = hidden if mode.shared_hidden else n_types * hidden
    shapes = {
        "first.weight": (width, d_in),
        "first.bias": (width,),
        "w2": (n_types, hidden, d_out),
        "b2": (n_types, d_out),
    }
    if trained and mode.adapters:
        shapes.update({"w2_shared": (hidden, d_out), "b2_shared": (d_out,)})
    return shapes


@functools.lru_cache(maxsize=64)
def _encoder(key: tuple, critic: bool) -> dict[str, tuple[int, ...]]:
    cfg = dict(key)
    D, T, E, K = cfg["obs_dim"], cfg["n_types"], cfg["embed"], cfg["heads"]
    de = cfg["edge_embed"]
    shapes: dict[str, tuple[int, ...]] = {}
    if cfg["obs_embed"]:
        shapes.update(
            {
                "obs_encoder.0.weight": (D,),
                "obs_encoder.0.bias": (D,),
                "obs_encoder.1.weight": (E, D),
                "obs_encoder.1.bias": (E,),
            }
        )
    for k in range(cfg["heat_blocks"]):
        p = f"heat.{k}."
        for t in range(T):
            shapes[f"{p}node.{t}.weight"] = (E, D if k == 0 and not cfg["obs_embed"] else E)
        shapes.update(
            {
                f"{p}edge_attr.weight": (de, 5),
                f"{p}edge_type.weight": (T * T, de),
                f"{p}att_i.weight": (K, E),
                f"{p}att_attr.weight": (K, de),
                f"{p}att_type.weight": (K, de),
                f"{p}att_j.weight": (K, E),
                f"{p}msg_attr.weight": (E, de),
                f"{p}msg_type.weight": (E, de),
                f"{p}msg_j.weight": (E, E),
                f"heat_norm.{k}.weight": (E,),
                f"heat_norm.{k}.bias": (E,),
            }
        )
        if cfg["reference_messages"]:
            shapes[f"{p}msg_out.weight"] = (E, E)
        if cfg["node_ffn"]:
            shapes.update(
                {
                    f"node_ffn.{k}.0.weight": (E, E),
                    f"node_ffn.{k}.0.bias": (E,),
                    f"node_ffn.{k}.2.weight": (E, E),
                    f"node_ffn.{k}.2.bias": (E,),
                    f"node_ffn_norm.{k}.weight": (E,),
                    f"node_ffn_norm.{k}.bias": (E,),
                }
            )
    if critic:
        shapes.update(
            {"critic.0.weight": (E, E), "critic.0.bias": (E,), "critic.2.weight": (1, E), "critic.2.bias": (1,)}
        )
    return shapes


@functools.lru_cache(maxsize=64)
def _decoder(key: tuple, trained: bool) -> dict[str, tuple[int, ...]]:
    cfg = dict(key)
    T, C, E, A = cfg["n_types"], cfg["n_caps"], cfg["embed"], N_ACTIONS
    shapes: dict[str, tuple[int, ...]] = {"token.0.weight": (E, A + 1)}
    for att in ("self_attn", "cross_attn"):
        shapes.update(
            {
                f"{att}.q.weight": (E, E),
                f"{att}.q.bias": (E,),
                f"{att}.kv.weight": (2 * E, E),
                f"{att}.kv.bias": (2 * E,),
                f"{att}.o.weight": (E, E),
                f"{att}.o.bias": (E,),
            }
        )
    for name in ("ln1", "ln2", "ln3", "ln4"):
        shapes.update({f"{name}.weight": (E,), f"{name}.bias": (E,)})
    for name in ("fc", "fc2"):
        shapes.update(
            {f"{name}.0.weight": (E, E), f"{name}.0.bias": (E,), f"{name}.2.weight": (E, E), f"{name}.2.bias": (E,)}
        )
    heads = decision_shapes(cfg["decision"], E + C, E, A, T, trained=trained)
    shapes.update({f"heads.{n}": s for n, s in heads.items()})
    return shapes


def encoder_shapes(config: Mapping, critic: bool = False) -> dict[str, tuple[int, ...]]:
    """Name -> shape of the encoder's arrays (observation embedding, HEAT blocks, their norms
    and feed-forward sublayers), in a fixed order; ``critic``: the critic's two layers after."""
    return dict(_encoder(_key(normalize_config(config)), critic))


def decoder_shapes(config: Mapping) -> dict[str, tuple[int, ...]]:
    """Name -> shape of the decoder's arrays in acting form (θ¹, θ², the decision layer with
    each type's output layer whole), in a fixed order."""
    return dict(_decoder(_key(normalize_config(config)), False))


def weight_shapes(config: Mapping, critic: bool = False) -> dict[str, tuple[int, ...]]:
    """Name -> shape of every array acting reads (encoder then decoder; see the module
    docstring); the critic's only with ``critic``. The order is fixed: a weights file lists its
    arrays in it."""
    return {**encoder_shapes(config, critic), **decoder_shapes(config)}


def parameter_shapes(config: Mapping, critic: bool = True) -> dict[str, tuple[int, ...]]:
    """Name -> shape of every parameter the torch model holds (its ``state_dict``): the arrays
    of :func:`weight_shapes` with the decision layer in its trained form."""
    key = _key(normalize_config(config))
    return {**_encoder(key, critic), **_decoder(key, True)}


def check_arrays(arrays: Mapping, want: Mapping, what: str) -> None:
    """Raise ValueError ``"{what}: missing [...], unexpected [...], wrong shapes [name: expected
    (…), got (…)]"`` unless ``arrays`` holds exactly the names of ``want`` with its shapes."""
    wrong = [n for n, s in want.items() if n in arrays and _shape(arrays[n]) != tuple(s)]
    if not wrong and len(arrays) == len(want) and all(n in arrays for n in want):
        return
    missing = sorted(set(want) - set(arrays))
    extra = sorted(set(arrays) - set(want))
    wrong = [f"{n}: expected {tuple(want[n])}, got {_shape(arrays[n])}" for n in wrong]
    raise ValueError(
        f"{what}: missing {missing[:5]}{'…' if len(missing) > 5 else ''}, "
        f"unexpected {extra[:5]}{'…' if len(extra) > 5 else ''}, "
        f"wrong shapes {wrong[:5]}{'…' if len(wrong) > 5 else ''}"
    )


def _shape(a) -> tuple[int, ...]:
    # ndarray first: this check runs on every compiled acting call
    return a.shape if isinstance(a, np.ndarray) else tuple(np.shape(a))
