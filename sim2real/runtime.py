"""COMAT policy in numpy: the deployment forward pass shipped inside a Robotarium submission.

The Robotarium runs plain Python with numpy but no torch, so this module imports numpy, the
standard library and ``comat_schema`` only (a test parses its imports) and is copied verbatim into
the submission, next to ``comat_schema.py`` (``comat/models/comat_schema.py``, verbatim): the one
description of COMAT's arrays and decision layer, which the torch model and the compiled kernels
read too. In the repository ``import sim2real`` makes ``comat_schema`` name that module.
It computes exactly what ``comat.models.comat.Comat.encode`` and its autoregressive decoder
compute, for one team of real robots (no batch, no padding):

=================  ==========================================================================
Input              obs (N, D) float, one row per robot, the task's layout
                   [x, y, cos θ, sin θ | type one-hot (T) | capabilities (C) | task features]
Encoder            edge features from obs (mirror of ``comat.models.features.edge_features``),
                   optionally a per-robot embedding LN → Linear → GELU (``obs_embed``), then
                   ``heat_blocks`` HEAT blocks (type-specific node transforms, edge-feature and
                   edge-type embeddings, K-head LeakyReLU scores, softmax over neighbours; heads
                   averaged with one linear message, or per-head nonlinear messages concatenated
                   (``reference_messages``)), each followed by LayerNorm with a residual (not
                   after the first block without ``obs_embed``) and optionally a per-robot
                   feed-forward sublayer (``node_ffn``) -> rep (N, E)
Decoder            robot by robot, m = 0..N−1: token (start or a_{m−1}) embedding, causal
                   self-attention over tokens 0..m, action-embedding block, cross-attention of
                   rep_m over embedded actions 0..m, per-type actor head on [h_m ‖ c_m]
                   (``decision``: its hidden layer one per type or shared by the types)
Output             ``action_probs(obs)`` -> actions (N,) int64 (argmax, deterministic) and the
                   probability vectors (N, A) they were chosen from, A = 5
Not included       the critic (deployment needs no values); sampling (argmax only)
Arithmetic         float64 throughout (weights are stored as float32, as trained)
=================  ==========================================================================

Weights file: ONE ``.npy`` readable with ``np.load(path, allow_pickle=False)``. It holds a 0-d
structured array with two fields:

* ``manifest``: uint8 (L,), UTF-8 JSON ``{"format": "comat-numpy-weights", "version": 2,
  "config": {obs_dim, n_types, n_caps, embed, heads, heat_blocks, edge_embed, root_weight,
  obs_embed, node_ffn, reference_messages, world_edges, decision},
  "arrays": [[name, shape, offset], ...]}`` (``comat_schema.CONFIG_KEYS``: the options as 0/1,
  ``decision`` the ``ComatConfig.decision`` string);
* ``params``: float32 (P,), every array flattened (C order) and concatenated; array ``name``
  is ``params[offset : offset + prod(shape)].reshape(shape)``.

Names and shapes are ``comat_schema.weight_shapes(config)``: the torch ``state_dict`` keys
(``heat.0.node.1.weight``, ``cross_attn.kv.bias``, ...), critic excluded, the decision layer in
acting form (each type's whole output layer), so every array can be traced back to the module
that trained it. The manifest lives in the data rather than in the .npy header: the header stays
a few hundred bytes, under numpy's ``max_header_size`` on every version, and no pickle is ever
needed. ``pack_weights`` /
``save_weights`` write the format, ``load_weights`` reads and checks it;
``sim2real.weights`` turns a torch model into the arrays.

Version history: v1 — first format; the architecture flags after ``edge_embed`` were added
later and read as 0 (the paper form) when absent; its decision layer was the flag
``shared_trunk`` (1: one hidden layer for all types). v2 — ``decision`` names the mode instead.
Both are read.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

import numpy as np
from comat_schema import (
    CONFIG_KEYS,
    FLAG_KEYS,
    N_ACTIONS,
    DecisionMode,
    check_arrays,
    normalize_config,
    weight_shapes,
)

__all__ = [
    "CONFIG_KEYS",
    "FLAG_KEYS",
    "FORMAT",
    "N_ACTIONS",
    "VERSION",
    "ComatRuntime",
    "edge_features",
    "expected_shapes",
    "load_weights",
    "pack_weights",
    "save_weights",
    "unpack_weights",
]

FORMAT, VERSION = "comat-numpy-weights", 2
READ_VERSIONS = (1, VERSION)
OPTIONAL_KEYS = dict.fromkeys(FLAG_KEYS, 0)
"""Config keys added to version 1 later, with the value files written before them mean."""


def _config(config: Mapping) -> dict:
    """``config`` in today's form (``comat_schema.normalize_config``), from any version's: absent
    flags are 0, and a version-1 config's ``shared_trunk`` flag gives the decision layer's form
    (in acting form ``adapters`` is ``shared_trunk``: its output layers are stored folded)."""
    config = {**OPTIONAL_KEYS, **config}
    if "decision" not in config:
        shared = config.get("shared_trunk", 0)
        config["decision"] = (DecisionMode.SHARED_TRUNK if shared else DecisionMode.TYPE_HEADS).value
    return normalize_config(config)


LN_EPS = 1e-5  # torch.nn.LayerNorm's default, which every LayerNorm in COMAT uses
SLOPE = 0.2  # LeakyReLU negative slope of the HEAT blocks


# -- weights file ----------------------------------------------------------------------------------
def expected_shapes(config: Mapping) -> dict[str, tuple[int, ...]]:
    """Name -> shape of every array the runtime needs, for a COMAT ``config`` (see CONFIG_KEYS;
    ``comat_schema.weight_shapes``, in the file's order)."""
    return weight_shapes(_config(config))


def _check_arrays(arrays: Mapping[str, np.ndarray], config: Mapping, source: str) -> None:
    """Raise ValueError naming every missing, unexpected or misshapen array."""
    check_arrays(arrays, expected_shapes(config), f"{source} does not match a COMAT model with config {dict(config)}")


def pack_weights(arrays: Mapping[str, np.ndarray], config: Mapping[str, int]) -> np.ndarray:
    """The 0-d structured array of the weights file (see module docstring); arrays are checked."""
    _check_arrays(arrays, config, "arrays")
    config = _config(config)
    names = list(expected_shapes(config))  # a fixed order, so equal models give equal files
    entries, offset = [], 0
    for n in names:
        entries.append([n, list(np.shape(arrays[n])), offset])
        offset += int(np.size(arrays[n]))
    params = np.concatenate([np.asarray(arrays[n], dtype=np.float32).ravel() for n in names])
    manifest = json.dumps(
        {"format": FORMAT, "version": VERSION, "config": config, "arrays": entries}, separators=(",", ":")
    ).encode()
    record = np.zeros((), dtype=[("manifest", np.uint8, (len(manifest),)), ("params", np.float32, (offset,))])
    record["manifest"] = np.frombuffer(manifest, dtype=np.uint8)
    record["params"] = params
    return record


def unpack_weights(record: np.ndarray, source: str = "record") -> tuple[dict[str, int], dict[str, np.ndarray]]:
    """(config, name -> float32 array) from a structured array made by :func:`pack_weights`."""
    names = record.dtype.names or ()
    if record.shape != () or set(names) != {"manifest", "params"}:
        raise ValueError(
            f"{source} is not a {FORMAT} file: expected a 0-d record with fields "
            f"('manifest', 'params'), got shape {record.shape} and fields {names}"
        )
    try:
        manifest = json.loads(record["manifest"].tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ValueError(f"{source}: unreadable manifest ({err})") from err
    if manifest.get("format") != FORMAT or manifest.get("version") not in READ_VERSIONS:
        raise ValueError(
            f"{source}: expected format {FORMAT!r} version {' or '.join(map(str, READ_VERSIONS))}, "
            f"got {manifest.get('format')!r} version {manifest.get('version')}"
        )
    params = record["params"]
    arrays = {}
    for name, shape, offset in manifest["arrays"]:
        size = math.prod(shape)
        if offset + size > params.size:
            raise ValueError(
                f"{source}: array {name} {tuple(shape)} at offset {offset} runs past "
                f"the {params.size} stored parameters"
            )
        arrays[name] = params[offset : offset + size].reshape(shape)
    config = manifest["config"]
    _check_arrays(arrays, config, source)
    return _config(config), arrays


def save_weights(path, arrays: Mapping[str, np.ndarray], config: Mapping[str, int]) -> None:
    """Write the weights file (one ``.npy``, no pickle) at ``path``."""
    np.save(path, pack_weights(arrays, config), allow_pickle=False)


def load_weights(path) -> tuple[dict[str, int], dict[str, np.ndarray]]:
    """(config, arrays) from a weights file written by :func:`save_weights`."""
    return unpack_weights(np.load(path, allow_pickle=False), source=f"weights file {path}")


# -- building blocks (mirrors of comat.models.layers) --------------------------------------------
def _leaky(x: np.ndarray) -> np.ndarray:
    return np.where(x >= 0, x, SLOPE * x)


def _relu(x: np.ndarray) -> np.ndarray:
    return np.maximum(x, 0.0)


def _softmax(x: np.ndarray, axis: int = -1) -> np.ndarray:
    e = np.exp(x - x.max(axis=axis, keepdims=True))
    return e / e.sum(axis=axis, keepdims=True)


def _gelu(x: np.ndarray) -> np.ndarray:
    """Exact (erf) GELU, as torch's default; math.erf per element (numpy has no erf)."""
    return 0.5 * x * (1.0 + _erf(x / math.sqrt(2.0)))


_erf = np.vectorize(math.erf, otypes=[np.float64])


def _layer_norm(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    mu = x.mean(-1, keepdims=True)
    var = ((x - mu) ** 2).mean(-1, keepdims=True)  # biased, as torch's LayerNorm
    return (x - mu) / np.sqrt(var + LN_EPS) * w + b


def edge_features(obs: np.ndarray, n_types: int, world: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Dense team graph with self-loops (mirror of ``comat.models.features.edge_features``).

    Returns edge_attr (N, N, 5): for [i, j], robot j seen from robot i — position in i's frame
    (2; ``world``: p_j − p_i), distance (1), relative heading cos, sin (2); and edge_type (N, N):
    type_i · T + type_j.
    """
    xy, c, s = obs[:, 0:2], obs[:, 2], obs[:, 3]
    d = xy[None, :, :] - xy[:, None, :]  # [i, j] = p_j − p_i
    ci, si = c[:, None], s[:, None]
    if world:
        local_x, local_y = d[..., 0], d[..., 1]
    else:
        local_x = ci * d[..., 0] + si * d[..., 1]
        local_y = -si * d[..., 0] + ci * d[..., 1]
    # The 1e-12 keeps torch's sqrt differentiable at 0; kept so the numbers match it.
    dist = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2 + 1e-12) * (1 - np.eye(len(obs)))
    cj, sj = c[None, :], s[None, :]
    edge_attr = np.stack([local_x, local_y, dist, ci * cj + si * sj, ci * sj - si * cj], axis=-1)
    types = obs[:, 4 : 4 + n_types].argmax(-1)
    return edge_attr, types[:, None] * n_types + types[None, :]


class _Attention:
    """Multi-head scaled dot-product attention, incremental: keys/values appended per step."""

    def __init__(self, w: Mapping[str, np.ndarray], prefix: str, heads: int) -> None:
        self.heads = heads
        self.wq, self.bq = w[f"{prefix}.q.weight"], w[f"{prefix}.q.bias"]
        self.wkv, self.bkv = w[f"{prefix}.kv.weight"], w[f"{prefix}.kv.bias"]
        self.wo, self.bo = w[f"{prefix}.o.weight"], w[f"{prefix}.o.bias"]

    def query(self, x: np.ndarray) -> np.ndarray:
        """x (L, E) -> per-head queries (L, H, E/H)."""
        return (x @ self.wq.T + self.bq).reshape(len(x), self.heads, -1)

    def kv(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x (E,) -> key and value (H, E/H) each (head h = features h·dh .. (h+1)·dh, as torch)."""
        k, v = np.split(self.wkv @ x + self.bkv, 2)
        return k.reshape(self.heads, -1), v.reshape(self.heads, -1)

    def attend(self, q: np.ndarray, keys: np.ndarray, values: np.ndarray) -> np.ndarray:
        """q (H, dh) over keys, values (L, H, dh) -> (E,) after the output projection."""
        scores = np.einsum("hd,lhd->hl", q, keys) * q.shape[-1] ** -0.5
        return np.einsum("hl,lhd->hd", _softmax(scores), values).reshape(-1) @ self.wo.T + self.bo


# -- the policy -----------------------------------------------------------------------------------
class ComatRuntime:
    """A trained COMAT policy, evaluated in numpy (see module docstring).

    ``ComatRuntime(config, arrays)`` or ``ComatRuntime.from_file(path)``; then
    ``actions, probs = policy.action_probs(obs)`` with obs (N, D).
    """

    def __init__(self, config: Mapping[str, int], arrays: Mapping[str, np.ndarray]) -> None:
        _check_arrays(arrays, config, "arrays")
        self.config = _config(config)
        self.decision = DecisionMode(self.config["decision"])
        self.w = {k: np.asarray(v, dtype=np.float64) for k, v in arrays.items()}
        self.self_attn = _Attention(self.w, "self_attn", self.config["heads"])
        self.cross_attn = _Attention(self.w, "cross_attn", self.config["heads"])

    @classmethod
    def from_file(cls, path) -> ComatRuntime:
        return cls(*load_weights(path))

    # -- encoder --------------------------------------------------------------------------------
    def _heat(self, k: int, x: np.ndarray, types: np.ndarray, attr: np.ndarray, etype: np.ndarray) -> np.ndarray:
        """HEAT block k: x (N, d_in) -> (N, E); see Comat's HEATBlock for the algebra."""
        w, p = self.w, f"heat.{k}."
        node = np.stack([w[f"{p}node.{t}.weight"] for t in range(self.config["n_types"])])  # (T, E, d_in)
        xt = _leaky(np.einsum("ni,nei->ne", x, node[types]))  # each robot through its type's W
        ea = _leaky(attr @ w[f"{p}edge_attr.weight"].T)  # (N, N, de)
        et = _leaky(w[f"{p}edge_type.weight"])  # (T², de): one row per ordered type pair
        score = (
            (xt @ w[f"{p}att_i.weight"].T)[:, None]
            + ea @ w[f"{p}att_attr.weight"].T
            + (et @ w[f"{p}att_type.weight"].T)[etype]
            + (xt @ w[f"{p}att_j.weight"].T)[None]
        )
        # All robots are real and every robot has its self-loop, so no edge is masked.
        alpha = _softmax(_leaky(score), axis=1)  # (N, N, K): softmax over j per head
        root = xt if self.config["root_weight"] else 0.0
        if self.config["reference_messages"]:
            msg = _leaky(
                ea @ w[f"{p}msg_attr.weight"].T
                + (et @ w[f"{p}msg_type.weight"].T)[etype]
                + (xt @ w[f"{p}msg_j.weight"].T)[None]
            )  # (N, N, E): one message per edge
            N, K = len(x), alpha.shape[-1]
            out = np.einsum("ijk,ijkd->ikd", alpha, msg.reshape(N, N, K, -1)).reshape(N, -1)  # heads concatenated
            return out @ w[f"{p}msg_out.weight"].T + root
        alpha = alpha.mean(-1)  # (N, N): heads averaged
        return (
            (alpha[..., None] * ea).sum(1) @ w[f"{p}msg_attr.weight"].T
            + (alpha[..., None] * et[etype]).sum(1) @ w[f"{p}msg_type.weight"].T
            + (alpha @ xt) @ w[f"{p}msg_j.weight"].T
            + root
        )

    def encode(self, obs: np.ndarray) -> np.ndarray:
        """Robot representations rep (N, E) from obs (N, D)."""
        cfg, w = self.config, self.w
        T = cfg["n_types"]
        attr, etype = edge_features(obs, T, world=bool(cfg["world_edges"]))
        types = obs[:, 4 : 4 + T].argmax(-1)
        h = obs
        if cfg["obs_embed"]:
            h = _gelu(self._ln("obs_encoder.0", obs) @ w["obs_encoder.1.weight"].T + w["obs_encoder.1.bias"])
        for k in range(cfg["heat_blocks"]):
            out = self._heat(k, h, types, attr, etype)
            h = self._ln(f"heat_norm.{k}", h + out if k or cfg["obs_embed"] else out)
            if cfg["node_ffn"]:
                h = self._ln(f"node_ffn_norm.{k}", h + self._mlp(f"node_ffn.{k}", h))
        return h

    # -- decoder --------------------------------------------------------------------------------
    def _mlp(self, name: str, x: np.ndarray) -> np.ndarray:
        w = self.w
        return _relu(x @ w[f"{name}.0.weight"].T + w[f"{name}.0.bias"]) @ w[f"{name}.2.weight"].T + w[f"{name}.2.bias"]

    def _ln(self, name: str, x: np.ndarray) -> np.ndarray:
        return _layer_norm(x, self.w[f"{name}.weight"], self.w[f"{name}.bias"])

    def _actor(self, h: np.ndarray, obs_m: np.ndarray) -> np.ndarray:
        """Logits (A,) of the actor head of robot m's type, on [h_m ‖ c_m]."""
        T, C, E = self.config["n_types"], self.config["n_caps"], self.config["embed"]
        x = np.concatenate([h, obs_m[4 + T : 4 + T + C]])
        hidden = _relu(self.w["heads.first.weight"] @ x + self.w["heads.first.bias"])
        if self.decision.shared_hidden:  # one hidden layer, every type's output layer
            out = np.einsum("h,tha->ta", hidden, self.w["heads.w2"]) + self.w["heads.b2"]
        else:
            out = np.einsum("th,tha->ta", hidden.reshape(T, E), self.w["heads.w2"]) + self.w["heads.b2"]
        return (out * obs_m[4 : 4 + T, None]).sum(0)  # its own type's, by the one-hot as in torch

    def action_probs(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Deterministic decoding robot by robot.

        Args:
            obs: (N, D) observations of one team, N >= 1, all robots real.

        Returns:
            actions (N,) int64, each the argmax of its row of probs (N, A), the action
            distributions robot m's choice was made from (given the actions of robots 0..m−1).
        """
        obs = np.asarray(obs, dtype=np.float64)
        D = self.config["obs_dim"]
        if obs.ndim != 2 or obs.shape[0] < 1 or obs.shape[1] != D:
            raise ValueError(f"obs must have shape (N, {D}) with N >= 1, got {obs.shape}")
        if not np.isfinite(obs).all():
            raise ValueError("obs must be finite, got NaN or inf")
        N, A = len(obs), N_ACTIONS
        rep = self.encode(obs)
        cross_q = self.cross_attn.query(rep)  # queries of every robot in one matmul
        heads, dh = self.config["heads"], self.config["embed"] // self.config["heads"]
        # Keys/values of the tokens and of the embedded actions decoded so far (causal masks).
        self_k, self_v, cross_k, cross_v = (np.empty((N, heads, dh)) for _ in range(4))
        actions = np.zeros(N, dtype=np.int64)
        probs = np.zeros((N, A))
        token = 0  # index 0 = start token, a + 1 = action a
        for m in range(N):
            e = _relu(self.w["token.0.weight"][:, token])  # a one-hot token picks one column
            self_k[m], self_v[m] = self.self_attn.kv(e)
            att = self.self_attn.attend(self.self_attn.query(e[None])[0], self_k[: m + 1], self_v[: m + 1])
            x = self._ln("ln1", e + att)
            a_hat = self._ln("ln2", x + self._mlp("fc", x))
            cross_k[m], cross_v[m] = self.cross_attn.kv(a_hat)
            att = self.cross_attn.attend(cross_q[m], cross_k[: m + 1], cross_v[: m + 1])
            h = self._ln("ln3", rep[m] + att)
            h = self._ln("ln4", h + self._mlp("fc2", h))
            probs[m] = _softmax(self._actor(h, obs[m]))
            actions[m] = int(probs[m].argmax())
            token = actions[m] + 1
        return actions, probs
