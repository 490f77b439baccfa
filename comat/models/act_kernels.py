"""Compiled (numba) acting: COMAT's and MAT's whole robot-by-robot decoder in one call, and
COMAT's HEAT encoder with its critic in another.

Why: a cached decoder step in torch is ~56 PyTorch calls on tensors of a few thousand numbers, so at the
rollout batch (32) dispatch, not arithmetic, decides its cost. Here all N steps of one ``act``
run in a single compiled call: matrix products through BLAS (``np.dot``), LayerNorm, softmax,
the key/value caches and the action choice in loops.

The torch step (``decode_step``) and ``Comat.encode`` stay the references: these kernels repeat
their arithmetic in float32 but not its summation order, so logits and values agree to ~1e-6,
not bit for bit (tests/test_models.py). The encoder kernel pays at small batches, where the
torch HEAT pass (~60 calls on (B, N, N, ·) tensors) is dispatch-bound: ~4× for one team of 8,
~1.2× at batch 32, even at 256 (`comat bench learn`). ``AutoregressivePolicy.act`` uses them when no gradient is
recorded,
on CPU float32 tensors, with ``comat.kernels.enabled()``. Matrix products go to scipy's
OpenBLAS, which should run on one thread (the ``comat`` command sets ``OPENBLAS_NUM_THREADS=1``
before loading it): threads cost more than they save on these sizes, and the cores are the
environments'.

Arguments (B batch, N robots, E embedding, A actions, T types):

* ``mats``: float32 weights of two or more dimensions as torch stores them, (out, in): views of
  the parameters, so nothing is copied or cached per call;
* ``vecs``: 1-D float32 biases and LayerNorm parameters;
* ``mask`` (B, N) bool; ``noise`` (N, B, A) Gumbel noise, ignored if ``deterministic``;
* returns actions (B, N) int64 (0 for padded robots) and logits (B, N, A).

COMAT's ``mats`` and ``vecs`` are built by name from its weight description
(``comat.models.comat_schema``) by :func:`comat_decode_args` and :func:`comat_encode_args`, which
check every shape first, and its decision layer's form comes as an explicit flag.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numba import njit

from comat.models.comat_schema import DecisionMode, check_arrays, decoder_shapes, encoder_shapes

__all__ = [
    "COMAT_DECODE_MATS",
    "COMAT_DECODE_VECS",
    "comat_decode",
    "comat_decode_args",
    "comat_encode",
    "comat_encode_args",
    "mat_decode",
]

_jit = njit(cache=True, nogil=True)
_EPS = 1e-5  # torch.nn.LayerNorm's default


@_jit
def _layer_norm(x, w, b):
    B, E = x.shape
    out = np.empty_like(x)
    for i in range(B):
        mean = np.float32(0.0)
        for j in range(E):
            mean += x[i, j]
        mean /= E
        var = np.float32(0.0)
        for j in range(E):
            d = x[i, j] - mean
            var += d * d
        inv = np.float32(1.0) / np.sqrt(var / E + np.float32(_EPS))
        for j in range(E):
            out[i, j] = (x[i, j] - mean) * inv * w[j] + b[j]
    return out


@_jit
def _linear(x, w, b):
    """x (B, in) through a torch-layout weight w (out, in) and bias b (out,)."""
    return np.dot(x, w.T) + b


@_jit
def _relu(x):
    return np.maximum(x, np.float32(0.0))


@_jit
def _gelu(x):
    out = np.empty_like(x)
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            v = x[i, j]
            out[i, j] = np.float32(0.5 * v * (1.0 + math.erf(v / math.sqrt(2.0))))
    return out


@_jit
def _attend(q, keys, values, length, heads):
    """Row i's query q[i] (E,), already scaled by 1/√dh, over keys/values[i, :length] (L, E)."""
    B, E = q.shape
    dh = E // heads
    out = np.zeros_like(q)
    scores = np.empty(length, dtype=np.float32)
    for i in range(B):
        for h in range(heads):
            lo = h * dh
            top = np.float32(-np.inf)
            for j in range(length):
                s = np.float32(0.0)
                for d in range(lo, lo + dh):
                    s += q[i, d] * keys[i, j, d]
                scores[j] = s
                top = max(top, s)
            total = np.float32(0.0)
            for j in range(length):
                scores[j] = np.exp(scores[j] - top)
                total += scores[j]
            for j in range(length):
                a = scores[j] / total
                for d in range(lo, lo + dh):
                    out[i, d] += a * values[i, j, d]
    return out


@_jit
def _choose(logits, mask_m, noise_m, deterministic):
    B, A = logits.shape
    actions = np.zeros(B, dtype=np.int64)
    for i in range(B):
        if not mask_m[i]:
            continue
        best, arg = -np.inf, 0
        for a in range(A):
            v = logits[i, a] if deterministic else logits[i, a] + noise_m[i, a]
            if v > best:
                best, arg = v, a
        actions[i] = arg
    return actions


COMAT_DECODE_MATS = (
    "token.0.weight",
    "self_attn.q.weight",
    "self_attn.kv.weight",
    "self_attn.o.weight",
    "fc.0.weight",
    "fc.2.weight",
    "cross_attn.q.weight",
    "cross_attn.kv.weight",
    "cross_attn.o.weight",
    "fc2.0.weight",
    "fc2.2.weight",
    "heads.first.weight",
    "heads.w2",
    "heads.b2",
)
"""The arrays :func:`comat_decode` unpacks from ``mats``, in its order (names of the schema)."""
COMAT_DECODE_VECS = (
    "self_attn.q.bias",
    "self_attn.kv.bias",
    "self_attn.o.bias",
    "fc.0.bias",
    "fc.2.bias",
    "cross_attn.q.bias",
    "cross_attn.kv.bias",
    "cross_attn.o.bias",
    "fc2.0.bias",
    "fc2.2.bias",
    "heads.first.bias",
    "ln1.weight",
    "ln1.bias",
    "ln2.weight",
    "ln2.bias",
    "ln3.weight",
    "ln3.bias",
    "ln4.weight",
    "ln4.bias",
)
"""The arrays :func:`comat_decode` unpacks from ``vecs``, in its order."""


def comat_decode_args(arrays: Mapping[str, np.ndarray], config: Mapping) -> tuple[tuple, tuple, bool]:
    """(mats, vecs, shared_hidden) of :func:`comat_decode` from the decoder's arrays in acting form
    (name -> float32 C-contiguous array, exactly ``decoder_shapes(config)``); ValueError naming any
    missing, unexpected or misshapen array."""
    want = decoder_shapes(config)
    check_arrays(arrays, want, "COMAT decoder weights do not match the compiled kernel's config")
    if set(want) != set(COMAT_DECODE_MATS) | set(COMAT_DECODE_VECS):  # the schema changed, the kernel did not
        raise ValueError(
            f"comat_decode takes {sorted(COMAT_DECODE_MATS + COMAT_DECODE_VECS)}, "
            f"the weight description lists {sorted(want)}"
        )
    mats = tuple(arrays[n] for n in COMAT_DECODE_MATS)
    vecs = tuple(arrays[n] for n in COMAT_DECODE_VECS)
    return mats, vecs, DecisionMode(config["decision"]).shared_hidden


@_jit
def comat_decode(mats, vecs, rep, obs, mask, noise, deterministic, heads, n_types, shared_hidden):
    # long: a numba kernel: the autoregressive decode as one compiled loop nest (a call out per robot costs)
    """COMAT (``Comat.decode_step`` for m = 0..N−1) from its parameters, as stored by torch.

    ``mats``, ``vecs``: :data:`COMAT_DECODE_MATS`, :data:`COMAT_DECODE_VECS` in acting form
    (:func:`comat_decode_args`): the actor's first layer (T·H, E + C), or (H, E + C) with
    ``shared_hidden`` (one hidden layer for every type, ``DecisionMode.shared_hidden``); each
    type's output layer (T, H, A) and biases (T, A). ``rep`` (B, N, E) encoder output; ``obs``
    (B, N, D) for type one-hots and capabilities (the task layout: [x, y, cos, sin | types (T) |
    capabilities (C) | …])."""
    tok, sa_q, sa_kv, sa_o, fc_a, fc_b, ca_q, ca_kv, ca_o, fc2_a, fc2_b, act1, act2, act2b = mats
    (
        sa_qb,
        sa_kvb,
        sa_ob,
        fc_ab,
        fc_bb,
        ca_qb,
        ca_kvb,
        ca_ob,
        fc2_ab,
        fc2_bb,
        act1b,
        ln1w,
        ln1b,
        ln2w,
        ln2b,
        ln3w,
        ln3b,
        ln4w,
        ln4b,
    ) = vecs
    B, N, E = rep.shape
    T = n_types
    H = act2.shape[1]
    A = act2.shape[2]
    C = act1.shape[1] - E
    scale = np.float32((E // heads) ** -0.5)
    # θ¹'s embedding, query, key and value depend on the token alone: one row per token.
    e_tab = _relu(np.ascontiguousarray(tok.T))
    q_tab = _linear(e_tab, sa_q, sa_qb) * scale
    kv_tab = _linear(e_tab, sa_kv, sa_kvb)
    # θ²'s queries and the actor's capability share, for every robot at once.
    cross_q = (_linear(np.ascontiguousarray(rep).reshape(B * N, E), ca_q, ca_qb) * scale).reshape(B, N, E)
    caps = np.ascontiguousarray(obs[:, :, 4 + T : 4 + T + C]).reshape(B * N, C)
    caps = (np.dot(caps, np.ascontiguousarray(act1[:, E:]).T) + act1b).reshape(B, N, act1.shape[0])
    act1_h = np.ascontiguousarray(act1[:, :E])
    self_k = np.empty((B, N, E), dtype=np.float32)
    self_v = np.empty((B, N, E), dtype=np.float32)
    cross_k = np.empty((B, N, E), dtype=np.float32)
    cross_v = np.empty((B, N, E), dtype=np.float32)
    actions = np.zeros((B, N), dtype=np.int64)
    logits = np.zeros((B, N, A), dtype=np.float32)
    token = np.zeros(B, dtype=np.int64)
    e = np.empty((B, E), dtype=np.float32)
    q = np.empty((B, E), dtype=np.float32)
    for m in range(N):
        for i in range(B):
            t = token[i]
            e[i] = e_tab[t]
            q[i] = q_tab[t]
            self_k[i, m] = kv_tab[t, :E]
            self_v[i, m] = kv_tab[t, E:]
        x = _layer_norm(e + _linear(_attend(q, self_k, self_v, m + 1, heads), sa_o, sa_ob), ln1w, ln1b)
        a_hat = _layer_norm(x + _linear(_relu(_linear(x, fc_a, fc_ab)), fc_b, fc_bb), ln2w, ln2b)
        kv = _linear(a_hat, ca_kv, ca_kvb)
        cross_k[:, m] = kv[:, :E]
        cross_v[:, m] = kv[:, E:]
        attended = _linear(_attend(np.ascontiguousarray(cross_q[:, m]), cross_k, cross_v, m + 1, heads), ca_o, ca_ob)
        h = _layer_norm(np.ascontiguousarray(rep[:, m]) + attended, ln3w, ln3b)
        h = _layer_norm(h + _linear(_relu(_linear(h, fc2_a, fc2_ab)), fc2_b, fc2_bb), ln4w, ln4b)
        hidden = _relu(np.dot(h, act1_h.T) + caps[:, m])  # (B, T·H) or (B, H)
        for i in range(B):
            for k in range(T):
                w = obs[i, m, 4 + k]  # the type one-hot: the robot's own head
                if w == 0.0:
                    continue
                off = 0 if shared_hidden else k * H
                for a in range(A):  # loops: a BLAS call per robot costs more than its H·A products
                    s = np.float32(0.0)
                    for j in range(H):
                        s += hidden[i, off + j] * act2[k, j, a]
                    logits[i, m, a] += w * (s + act2b[k, a])
        actions[:, m] = _choose(logits[:, m], mask[:, m], noise[m], deterministic)
        token = actions[:, m] + 1
    return actions, logits


@_jit
def mat_decode(mats, vecs, rep, mask, noise, deterministic, heads):
    """MAT (``Mat.decode_step`` for m = 0..N−1) from its parameters, as stored by torch.

    ``mats`` (out, in): the action encoder (E, A+1), then per decoder block self q, kv, out,
    cross q, kv, out, mlp (2), then the head (2). ``vecs``: dec_ln weight and bias, per block
    the 8 biases and ln1–ln3 weight and bias, then the head's two biases and its LayerNorm."""
    B, N, E = rep.shape
    n_blocks = (len(mats) - 3) // 8
    A = mats[len(mats) - 1].shape[0]
    scale = np.float32((E // heads) ** -0.5)
    table = _layer_norm(_gelu(np.ascontiguousarray(mats[0].T)), vecs[0], vecs[1])  # embedded tokens
    keys = np.empty((2 * n_blocks, B, N, E), dtype=np.float32)
    values = np.empty((2 * n_blocks, B, N, E), dtype=np.float32)
    actions = np.zeros((B, N), dtype=np.int64)
    logits = np.zeros((B, N, A), dtype=np.float32)
    token = np.zeros(B, dtype=np.int64)
    x = np.empty((B, E), dtype=np.float32)
    for m in range(N):
        for i in range(B):
            x[i] = table[token[i]]
        rep_m = np.ascontiguousarray(rep[:, m])
        y = x
        for k in range(n_blocks):
            w, v = 1 + 8 * k, 2 + 14 * k
            kv = _linear(y, mats[w + 1], vecs[v + 1])
            keys[2 * k, :, m] = kv[:, :E]
            values[2 * k, :, m] = kv[:, E:]
            q = _linear(y, mats[w], vecs[v]) * scale
            att = _linear(_attend(q, keys[2 * k], values[2 * k], m + 1, heads), mats[w + 2], vecs[v + 2])
            y = _layer_norm(y + att, vecs[v + 8], vecs[v + 9])
            kv = _linear(y, mats[w + 4], vecs[v + 4])
            keys[2 * k + 1, :, m] = kv[:, :E]
            values[2 * k + 1, :, m] = kv[:, E:]
            q = _linear(rep_m, mats[w + 3], vecs[v + 3]) * scale
            att = _linear(_attend(q, keys[2 * k + 1], values[2 * k + 1], m + 1, heads), mats[w + 5], vecs[v + 5])
            y = _layer_norm(rep_m + att, vecs[v + 10], vecs[v + 11])
            y = _layer_norm(
                y + _linear(_gelu(_linear(y, mats[w + 6], vecs[v + 6])), mats[w + 7], vecs[v + 7]),
                vecs[v + 12],
                vecs[v + 13],
            )
        w, v = 1 + 8 * n_blocks, 2 + 14 * n_blocks
        hidden = _layer_norm(_gelu(_linear(y, mats[w], vecs[v])), vecs[v + 2], vecs[v + 3])
        logits[:, m] = _linear(hidden, mats[w + 1], vecs[v + 1])
        actions[:, m] = _choose(logits[:, m], mask[:, m], noise[m], deterministic)
        token = actions[:, m] + 1
    return actions, logits


_SLOPE = np.float32(0.2)  # HEAT's LeakyReLU negative slope (comat.models.comat)


@_jit
def _leaky(x):
    return np.where(x >= 0, x, x * _SLOPE)


@_jit
def _layer_norm_rows(x, w, b):
    """LayerNorm of each row of x (R, E): ``_layer_norm`` for any contiguous 2-D input."""
    return _layer_norm(np.ascontiguousarray(x), w, b)


def comat_encode_args(arrays: Mapping[str, np.ndarray], config: Mapping) -> tuple[tuple, tuple, tuple, tuple]:
    """(node_ws, mats, vecs, flags) of :func:`comat_encode` from the encoder's and the critic's
    arrays (name -> float32 C-contiguous array, exactly ``encoder_shapes(config, critic=True)``),
    in the schema's order: the HEAT blocks' node transforms into ``node_ws``, the other arrays
    into ``mats`` or ``vecs`` by dimension; ``flags`` (root, obs_embed, reference, world,
    node_ffn) from the config. ValueError naming any missing, unexpected or misshapen array."""
    want = encoder_shapes(config, critic=True)
    check_arrays(arrays, want, "COMAT encoder weights do not match the compiled kernel's config")
    node_ws, mats, vecs = [], [], []
    for name, shape in want.items():
        node = name.startswith("heat.") and ".node." in name
        (node_ws if node else mats if len(shape) > 1 else vecs).append(arrays[name])
    flags = tuple(
        bool(config[k]) for k in ("root_weight", "obs_embed", "reference_messages", "world_edges", "node_ffn")
    )
    return tuple(node_ws), tuple(mats), tuple(vecs), flags


@_jit
def comat_encode(node_ws, mats, vecs, obs, mask, heads, n_types, root, obs_embed, reference, world, node_ffn):
    # long: a numba kernel: one compiled loop nest walking the schema's offsets (a call out per robot costs)
    """COMAT's HEAT encoder and critic (``Comat.encode``, every ``ComatConfig`` option): rep
    (B, N, E) and values (B, N) from obs (B, N, D) and mask (B, N). The arrays come in the
    schema's order (:func:`comat_encode_args`), which the offsets below walk:

    ``node_ws``: per block its T type-specific node transforms (E, d_in). ``mats`` (out, in):
    with ``obs_embed`` first the embedding (E, D); then per block the edge-feature embedding
    (d_e, 5), edge-type embedding table (T², d_e), attention on x̃_i (K, E), on ẽ^attr (K, d_e),
    on ẽ^type (K, d_e), on x̃_j (K, E), messages from ẽ^attr (E, d_e), ẽ^type (E, d_e), x̃_j
    (E, E), with ``reference`` the output map (E, E), with ``node_ffn`` its two layers (E, E);
    then the critic's two layers. ``vecs``: with ``obs_embed`` the embedding's LayerNorm weight
    and bias and its bias; per block its LayerNorm weight and bias, with ``node_ffn`` its two
    biases and LayerNorm weight and bias; then the critic's two biases."""
    B, N, D = obs.shape
    T = n_types
    n_blocks = len(node_ws) // T
    # The team graph, as comat.models.features.edge_features builds it.
    types = np.zeros((B, N), dtype=np.int64)
    for b in range(B):
        for i in range(N):
            best = obs[b, i, 4]
            for t in range(1, T):
                if obs[b, i, 4 + t] > best:
                    best, types[b, i] = obs[b, i, 4 + t], t
    attr = np.zeros((B, N, N, 5), dtype=np.float32)
    for b in range(B):
        for i in range(N):
            ci, si = obs[b, i, 2], obs[b, i, 3]
            for j in range(N):
                dx, dy = obs[b, j, 0] - obs[b, i, 0], obs[b, j, 1] - obs[b, i, 1]
                cj, sj = obs[b, j, 2], obs[b, j, 3]
                if world:
                    attr[b, i, j, 0], attr[b, i, j, 1] = dx, dy
                else:
                    attr[b, i, j, 0] = ci * dx + si * dy
                    attr[b, i, j, 1] = -si * dx + ci * dy
                if i != j:
                    attr[b, i, j, 2] = np.sqrt(dx * dx + dy * dy + np.float32(1e-12))
                attr[b, i, j, 3] = ci * cj + si * sj
                attr[b, i, j, 4] = ci * sj - si * cj
    attr2 = attr.reshape(B * N * N, 5)
    h = np.ascontiguousarray(obs).reshape(B * N, D)
    mo, vo = 0, 0
    if obs_embed:
        h = _gelu(_linear(_layer_norm_rows(h, vecs[0], vecs[1]), mats[0], vecs[2]))
        mo, vo = 1, 3
    m_stride = 9 + (1 if reference else 0) + (2 if node_ffn else 0)
    v_stride = 2 + (4 if node_ffn else 0)
    for k in range(n_blocks):
        E = node_ws[k * T].shape[0]
        m, v = mo + m_stride * k, vo + v_stride * k
        edge_w, type_tab, att_i, att_a, att_t, att_j, msg_a, msg_t, msg_j = (
            mats[m],
            mats[m + 1],
            mats[m + 2],
            mats[m + 3],
            mats[m + 4],
            mats[m + 5],
            mats[m + 6],
            mats[m + 7],
            mats[m + 8],
        )
        K = att_i.shape[0]
        xt = np.zeros((B * N, E), dtype=np.float32)
        for t in range(T):
            y = np.dot(h, node_ws[k * T + t].T)
            for r in range(B * N):
                if types[r // N, r % N] == t:
                    xt[r] = y[r]
        xt = _leaky(xt)
        ea = _leaky(np.dot(attr2, edge_w.T))  # (B·N·N, d_e)
        et = _leaky(type_tab)  # (T², d_e)
        s_i = np.dot(xt, att_i.T)
        s_j = np.dot(xt, att_j.T)
        s_a = np.dot(ea, att_a.T)
        s_t = np.dot(et, att_t.T)
        alpha = _heat_attention(s_i, s_j, s_a, s_t, types, mask, T, K)  # (B, N, N, K)
        if reference:
            out = _reference_messages(alpha, ea, et, xt, msg_a, msg_t, msg_j, types, T)
            out = np.dot(out, mats[m + 9].T)
        else:
            out = _paper_messages(alpha, ea, et, xt, msg_a, msg_t, msg_j, types, T)
        if root:
            out = out + xt
        h = _layer_norm(h + out if (k > 0 or obs_embed) else out, vecs[v], vecs[v + 1])
        if node_ffn:
            f = m + 9 + (1 if reference else 0)
            ffn = _linear(_relu(_linear(h, mats[f], vecs[v + 2])), mats[f + 1], vecs[v + 3])
            h = _layer_norm(h + ffn, vecs[v + 4], vecs[v + 5])
    c = mo + m_stride * n_blocks
    v = vo + v_stride * n_blocks
    values = _linear(_relu(_linear(h, mats[c], vecs[v])), mats[c + 1], vecs[v + 1])
    E = h.shape[1]
    return h.reshape(B, N, E), values[:, 0].copy().reshape(B, N)


@_jit
def _heat_attention(s_i, s_j, s_a, s_t, types, mask, T, K):
    """Per-head attention weights α^k_ij (B, N, N, K) from the score parts; rows of padded
    robots (no real neighbour, not even themselves) all 0, as ``nan_to_num`` gives in torch."""
    B, N = mask.shape
    alpha = np.zeros((B, N, N, K), dtype=np.float32)
    scores = np.empty(N, dtype=np.float32)
    for b in range(B):
        for i in range(N):
            if not mask[b, i]:
                continue
            for kk in range(K):
                top = np.float32(-np.inf)
                for j in range(N):
                    if mask[b, j]:
                        pair = types[b, i] * T + types[b, j]
                        s = s_i[b * N + i, kk] + s_a[(b * N + i) * N + j, kk] + s_t[pair, kk] + s_j[b * N + j, kk]
                        s = s if s >= 0 else s * _SLOPE
                        scores[j] = s
                        top = max(top, s)
                total = np.float32(0.0)
                for j in range(N):
                    if mask[b, j]:
                        scores[j] = np.exp(scores[j] - top)
                        total += scores[j]
                for j in range(N):
                    if mask[b, j]:
                        alpha[b, i, j, kk] = scores[j] / total
    return alpha


@_jit
def _paper_messages(alpha, ea, et, xt, msg_a, msg_t, msg_j, types, T):
    """Eq. 3: heads averaged, then one linear message of the weighted sums, (B·N, E)."""
    B, N, _, K = alpha.shape
    d_e, E = ea.shape[1], xt.shape[1]
    agg_a = np.zeros((B * N, d_e), dtype=np.float32)
    agg_t = np.zeros((B * N, d_e), dtype=np.float32)
    agg_x = np.zeros((B * N, E), dtype=np.float32)
    for b in range(B):
        for i in range(N):
            r = b * N + i
            for j in range(N):
                a = np.float32(0.0)
                for kk in range(K):
                    a += alpha[b, i, j, kk]
                if a == 0.0:
                    continue
                a /= K
                pair = types[b, i] * T + types[b, j]
                for d in range(d_e):
                    agg_a[r, d] += a * ea[r * N + j, d]
                    agg_t[r, d] += a * et[pair, d]
                for d in range(E):
                    agg_x[r, d] += a * xt[b * N + j, d]
    return np.dot(agg_a, msg_a.T) + np.dot(agg_t, msg_t.T) + np.dot(agg_x, msg_j.T)


@_jit
def _reference_messages(alpha, ea, et, xt, msg_a, msg_t, msg_j, types, T):
    """HEAT's reference form: LeakyReLU(W_h [ẽ_ij ‖ x̃_j]) per edge, each head summing its own
    E/K slice with its own weights, heads concatenated: (B·N, E), before the output map."""
    B, N, _, K = alpha.shape
    E = xt.shape[1]
    dh = E // K
    m_a = np.dot(ea, msg_a.T)  # (B·N·N, E)
    m_t = np.dot(et, msg_t.T)  # (T², E)
    m_j = np.dot(xt, msg_j.T)  # (B·N, E)
    out = np.zeros((B * N, E), dtype=np.float32)
    for b in range(B):
        for i in range(N):
            r = b * N + i
            for j in range(N):
                pair = types[b, i] * T + types[b, j]
                for kk in range(K):
                    a = alpha[b, i, j, kk]
                    if a == 0.0:
                        continue
                    for d in range(kk * dh, (kk + 1) * dh):
                        x = m_a[r * N + j, d] + m_t[pair, d] + m_j[b * N + j, d]
                        out[r, d] += a * (x if x >= 0 else x * _SLOPE)
    return out
