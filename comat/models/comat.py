"""COMAT: a HEAT graph-attention encoder and a capability-oriented autoregressive decoder.

Encoder (paper eq. 1–3, in the form of HEAT's reference code). The team is a directed graph
with self-loops; node types are robot types, edge types ordered type pairs (type_i·T + type_j),
edge features robot j seen from robot i (``comat.models.features.edge_features``). Each robot's
observation is first embedded on its own, h⁰_i = GELU(W_o LN(o_i)); then each HEAT block:

    x̃_i    = LeakyReLU(W_{type(i)} h_i)                        type-specific node transform
    ẽ_ij   = [LeakyReLU(W_a e_ij) ‖ LeakyReLU(E[type_ij])]     edge features ‖ edge-type embedding
    α^k_ij = softmax_j LeakyReLU(â_k · [x̃_i ‖ ẽ_ij ‖ x̃_j])    over i's neighbours, K heads
    m_ij   = LeakyReLU(W_h [ẽ_ij ‖ x̃_j])                       one message per edge
    ô_i    = W_out ‖_k Σ_j α^k_ij · m^k_ij                     head k weighs its own slice m^k

followed by h ← LN(h + ô) and a per-robot feed-forward sublayer h ← LN(h + MLP(h)). The critic
is an MLP on h_i (one value per robot).

Decoder (eq. 4–5). Tokens are the start token a⁰ and the previous robots' actions. θ¹, the
action-embedding block: token embedding, K-head causal self-attention, two linear layers. θ²:
K-head attention with queries h^{0:m} and keys/values the embedded actions, masked so robot m
sees actions 0..m−1. Decision layer: one actor head per robot type on [h_m ‖ c_m] (capability
vector). No weight depends on the team size; masks are built per forward pass.

What follows the paper literally and what does not (``results/ablations/``). The typed graph,
the type-specific node transforms, the edge-feature and edge-type embeddings, the additive
K-head attention over neighbours with self-loops, the capability-oriented autoregressive
decoder (θ¹, θ²) and the type-stratified decision layer are the paper's. Eq. 3 read literally
(heads averaged before one linear message shared by all heads, raw observations into a first
block without a skip path: ``PAPER_FORM``) nearly erases a robot's own observation from its
latent — at initialization a linear probe recovers own position and load with R² 0.2–0.4, and
COMAT finished no HMT training episode in 300 k steps. The default therefore follows HEAT's
reference code and PyG's ``HEATConv`` where they differ from that reading: a nonlinear message
per edge, concatenated heads with an output map, and a path for the robot's own features — here
a per-robot observation embedding, a residual on every block and the output map initialized
small (gain 0.01), so COMAT starts as a per-robot policy, as MAT does — plus a per-robot
feed-forward sublayer. The decision layer stays type-stratified, but as one layer every robot
trains with a zero-initialized per-type part (``decision: adapters``): with one head per type the
slow type learned from slow robots alone and, in a third of the seeds, never learned to carry
material home (``results/stability/``). Every paper-form choice stays available as a
``ComatConfig`` option.

Shapes: obs (B, N, D_obs), mask (B, N); embedding E; T types; C capabilities; A = 5 actions. The
update scores a batch packed as one graph where its compiled kernels apply (:mod:`comat.models.packing`:
the real robots as rows (R, ·), every same-team pair of robots as an edge row (M, ·)); the padded
form is the reference and the general path.
Every parameter's name and shape, and the decision layer's form, are described once in
``comat.models.comat_schema``, which the compiled kernels and the export's numpy runtime read too;
a Comat checks its parameters against it when built.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from comat import kernels
from comat.config import check_numbers
from comat.models.act_kernels import comat_decode, comat_decode_args, comat_encode, comat_encode_args
from comat.models.attention_kernels import HEAD_WIDTH
from comat.models.autoregressive import AutoregressivePolicy, numpy_view
from comat.models.comat_schema import (
    DECISIONS,
    DecisionMode,
    check_arrays,
    decoder_shapes,
    encoder_shapes,
    parameter_shapes,
    weight_shapes,
    weights_config,
)
from comat.models.features import ObsLayout, edge_features, packed_edge_features
from comat.models.heat_kernels import edge_stage
from comat.models.layers import Attention, KVCache, TypeHeads, causal, init_linear, mlp, score_actions
from comat.models.packing import PackedTeams, pack, split_teams

__all__ = ["PAPER_FORM", "VALUE_CHUNK_EDGES", "Comat", "ComatConfig", "build"]

VALUE_CHUNK_EDGES = 20_000
"""Edges of one packed pass of :meth:`Comat.values`, about. A PPO update's value passes score a
whole rollout (PCP: about 72,000 edges); in one pass every per-edge tensor is a fresh allocation
of tens of MB. In passes of about a minibatch's edges a PCP rollout's values took 35 ms against 48
(2 threads, medians of 10, alternating), as did the one pass with glibc's mmap and trim thresholds
raised: the cost was the allocations. Each team's values are its own, so the passes equal the one
pass within float rounding."""


PAPER_FORM = {
    "root_weight": False,
    "obs_embed": False,
    "message_gain": 1.0,
    "node_ffn": False,
    "heat_form": "paper",
    "edge_frame": "heading",
    "decision": "type_heads",
}
"""The architecture options that read the paper's eq. 2–3 literally (COMAT before the encoder
ablation, results/ablations/): ``ComatConfig(**PAPER_FORM)``."""
HEAT_FORMS = ("paper", "reference")
EDGE_FRAMES = ("heading", "world")


@dataclass(frozen=True)
class ComatConfig:
    """COMAT sizes and architecture options. Defaults: the encoder ablation's choice
    (results/ablations/) and the stability study's decision layer (results/stability/);
    ``ComatConfig(**PAPER_FORM)`` is the paper's eq. 2–3 read literally."""

    embed: int = 64
    """Embedding width E of node features, attention and decoder."""
    heads: int = 4
    """Attention heads K (HEAT and decoder)."""
    heat_blocks: int = 2
    """Stacked HEAT blocks in the encoder."""
    edge_embed: int = 32
    """Width of the edge-feature and edge-type embeddings."""
    node_ffn: bool = True
    """After each HEAT block, a per-robot feed-forward sublayer h = LN(h + MLP(h)), as in a
    transformer encoder (MAT has one; the paper's HEAT does not)."""
    root_weight: bool = False
    """Add each robot's own transformed features x̃_i to its HEAT output (PyG ``HEATConv``'s root
    term). False: a robot's own features reach it only through its self-loop, as in the
    paper's eq. 3."""
    obs_embed: bool = True
    """A per-robot observation embedding LN(o) → Linear → GELU in front of the HEAT blocks, and
    a residual on every block, h = LN(h + HEAT(h)) (as MAT's encoder). False: raw observations
    into block 1, which has no residual (the paper's eq. 2–3 read literally)."""
    message_gain: float = 0.01
    """Orthogonal-initialization gain of the maps that carry neighbours' messages into a robot's
    output (paper form: W_h; reference form: the output map after the heads). 0.01 with
    ``obs_embed`` starts COMAT as a per-robot policy, as MAT's small attention output does."""
    heat_form: str = "reference"
    """``paper``: heads averaged, one linear message W_h [ẽ_ij ‖ x̃_j] shared by all heads (eq. 3).
    ``reference``: HEAT's reference code — a nonlinear message LeakyReLU(W_h [ẽ_ij ‖ x̃_j]) per
    edge, split into K heads each weighted by its own attention, heads concatenated and mapped
    by a linear output layer."""
    edge_frame: str = "heading"
    """Frame of the relative positions in the edge features: ``heading`` (robot j's position in
    robot i's body frame) or ``world`` (p_j − p_i unrotated; actions are world-frame steps)."""
    decision: str = "adapters"
    """Decision layer on [h_m ‖ c_m], type-stratified in every form: ``adapters`` (default, issue
    30: one two-layer layer every robot trains, plus a per-type part of its output layer that
    starts at zero, so a type's own term grows only where it pays; results/stability/),
    ``type_heads`` (one two-layer head per robot type, the paper's layer read literally: the
    default until issue 30; a checkpoint without this option was trained with it) or
    ``shared_trunk`` (a hidden layer shared by all robots and a per-type output layer)."""

    def __post_init__(self) -> None:
        check_numbers(self, "models.comat", at_least_one=("embed", "heads", "heat_blocks", "edge_embed"))
        for name, choices in (("heat_form", HEAT_FORMS), ("edge_frame", EDGE_FRAMES), ("decision", DECISIONS)):
            if getattr(self, name) not in choices:
                raise ValueError(f"models.comat.{name} must be one of {list(choices)}, got {getattr(self, name)!r}")
        gain = self.message_gain
        if isinstance(gain, bool) or not isinstance(gain, (int, float)) or not 0 < gain < float("inf"):
            raise ValueError(f"models.comat.message_gain must be a positive finite number, got {gain!r}")
        if self.heat_form == "reference" and self.embed % self.heads:
            raise ValueError(
                f"models.comat.heat_form 'reference' needs embed divisible by heads, "
                f"got embed {self.embed}, heads {self.heads}"
            )


class HEATBlock(nn.Module):
    """One heterogeneous edge-enhanced graph-attention layer (dense, (B, N, N) edges).

    Paper form: the message W_h [ẽ_ij ‖ x̃_j] is linear, so it is applied after the
    attention-weighted sum over neighbours (Σ_j α_ij W x_ij = W Σ_j α_ij x_ij): no (B, N, N, E)
    tensor is built. Reference form: the message is nonlinear per edge, so it is built per edge
    and each head sums its own slice of it. The edge-type embedding ẽ^type has one row per
    ordered type pair, so its score and its share of the message are looked up per pair.
    """

    def __init__(
        self,
        d_in: int,
        d: int,
        n_types: int,
        d_edge: int,
        heads: int,
        root: bool = False,
        form: str = "paper",
        message_gain: float = 1.0,
    ) -> None:
        super().__init__()
        self.n_types, self.heads, self.root, self.form = n_types, heads, root, form
        self.node = nn.ModuleList(init_linear(nn.Linear(d_in, d, bias=False)) for _ in range(n_types))
        self.edge_attr = init_linear(nn.Linear(5, d_edge, bias=False))
        self.edge_type = nn.Embedding(n_types * n_types, d_edge)
        # â · [x̃_i ‖ ẽ^attr_ij ‖ ẽ^type_ij ‖ x̃_j], split by part.
        self.att_i = init_linear(nn.Linear(d, heads, bias=False))
        self.att_attr = init_linear(nn.Linear(d_edge, heads, bias=False))
        self.att_type = init_linear(nn.Linear(d_edge, heads, bias=False))
        self.att_j = init_linear(nn.Linear(d, heads, bias=False))
        # W_h [ẽ^attr_ij ‖ ẽ^type_ij ‖ x̃_j], split by part; in the reference form the small
        # gain sits on the output map instead (the message itself passes a nonlinearity).
        gain = message_gain if form == "paper" else 1.0
        self.msg_attr = init_linear(nn.Linear(d_edge, d, bias=False), gain)
        self.msg_type = init_linear(nn.Linear(d_edge, d, bias=False), gain)
        self.msg_j = init_linear(nn.Linear(d, d, bias=False), gain)
        if form == "reference":
            self.msg_out = init_linear(nn.Linear(d, d, bias=False), message_gain)

    def forward(self, x, types, edge_attr, edge_type, edge_mask, packed: PackedTeams | None = None) -> torch.Tensor:
        """x (B, N, d_in) -> (B, N, d); ``packed`` (the reference form only): x (R, d_in), the
        edges (M, ·), ``edge_mask`` unused, the edge stage in its fused kernels (heat_kernels)."""
        T = self.n_types
        if packed is not None:
            # Each type's node transform on its own robots' rows, put back in their order.
            # (index_select: its backward is a summed gather, several times cheaper than indexing's)
            parts = [F.linear(x.index_select(0, rows), layer.weight) for rows, layer in zip(packed.by_type, self.node)]
            xt = torch.cat(parts).index_select(0, packed.type_inverse)
        else:
            # Every type's node transform in one matmul, each robot keeping its own type's (a
            # product with the one-hot: exact, as only one term is not zero).
            w_node = torch.cat([layer.weight for layer in self.node])  # (T·d, d_in)
            onehot = F.one_hot(types, T).to(x.dtype)[..., None]  # (B, N, T, 1)
            xt = (F.linear(x, w_node).unflatten(-1, (T, -1)) * onehot).sum(-2)
        xt = F.leaky_relu(xt, 0.2)
        if packed is not None:
            # With the weight as a contiguous (5, d_edge) matrix, autograd takes its gradient as
            # raw.T @ grad, (5, M) @ (M, d_edge), not as nn.Linear's grad.T @ raw, (d_edge, M) @ (M, 5),
            # which MKL runs at a seventh of the speed (a PCP minibatch's edges, forward and backward:
            # 1.19 -> 0.33 ms on one thread).
            ea = F.leaky_relu(edge_attr @ self.edge_attr.weight.T.contiguous(), 0.2)  # (M, d_edge)
        else:
            ea = F.leaky_relu(self.edge_attr(edge_attr), 0.2)  # (B, N, N, d_edge)
        et = F.leaky_relu(self.edge_type.weight, 0.2)  # (T², d_edge): one row per type pair
        if self.form == "paper":
            pair = F.one_hot(edge_type, et.shape[0]).to(x.dtype)  # (B, N, N, T²)
            # The pair's score as a product with the one-hot rather than a lookup: the same values,
            # and a backward pass several times cheaper than the lookup's scatter.
            score = self.att_i(xt)[:, :, None] + self.att_attr(ea) + pair @ self.att_type(et) + self.att_j(xt)[:, None]
            score = F.leaky_relu(score, 0.2).masked_fill(~edge_mask[..., None], float("-inf"))
            alpha = torch.softmax(score, dim=2).nan_to_num(0.0).mean(-1)  # (B, N, N): heads averaged
            w = alpha[..., None]
            # Elementwise weighted sums: tiny batched matmuls are slower on CPU.
            out = self.msg_attr((w * ea).sum(2)) + self.msg_type((w * pair).sum(2) @ et) + self.msg_j(alpha @ xt)
            return out + xt if self.root else out
        # Reference form. Every per-edge linear map in one matmul on [ẽ^attr ‖ one-hot pair]: the
        # message's (d columns) and the score's (K columns), the pair's rows its type embedding's
        # share; then robot j's share of both, and robot i's of the score. (The same sums as one
        # map each, in another order: equal within float rounding, and far fewer passes over the
        # (B, N, N, ·) edge tensors, which are the encoder's cost.)
        d, K = xt.shape[-1], self.heads
        w_edge = torch.cat(
            [
                torch.cat([self.msg_attr.weight, self.att_attr.weight]).T,  # (d_edge, d + K)
                torch.cat([self.msg_type(et), self.att_type(et)], 1),  # (T², d + K)
            ]
        )
        if packed is not None:
            # The stage below, fused (heat_kernels): each robot's shares as robot j and as robot i
            # in one matmul, and each edge's type-pair row of w_edge added in the kernel rather
            # than through one-hot columns of the (M, ·) edge matrix.
            node = F.linear(xt, torch.cat([self.msg_j.weight, self.att_j.weight, self.att_i.weight]))
            d_edge = ea.shape[-1]
            out = edge_stage(ea @ w_edge[:d_edge], node, w_edge[d_edge:], edge_type, packed, K)
        else:
            w_j = torch.cat([self.msg_j.weight, self.att_j.weight])  # (d + K, d)
            xj, ai = F.linear(xt, w_j), self.att_i(xt)  # (B, N, d + K), (B, N, K)
            pair = F.one_hot(edge_type, et.shape[0]).to(x.dtype)  # (B, N, N, T²)
            z = torch.cat([ea, pair], -1) @ w_edge  # (B, N, N, d + K)
            z_msg, z_score = (z + xj[:, None]).split([d, K], -1)  # (split: a slice's gradient fills a zero z)
            score = F.leaky_relu(z_score + ai[:, :, None], 0.2).masked_fill(~edge_mask[..., None], float("-inf"))
            alpha = torch.softmax(score, dim=2).nan_to_num(0.0)  # (B, N, N, K)
            msg = F.leaky_relu(z_msg, 0.2)
            B, N = msg.shape[:2]
            out = (alpha[..., None] * msg.view(B, N, N, K, d // K)).sum(2).reshape(B, N, d)  # heads concatenated
        out = self.msg_out(out)
        return out + xt if self.root else out


class Comat(AutoregressivePolicy):
    """COMAT policy for a task's observation layout (see module docstring)."""

    # The HEAT blocks' work is N × N edges: where a batch is not packed (see evaluate_actions), score
    # each team size on its own edges.
    group_by_team_size = True

    def __init__(self, layout: ObsLayout, config: ComatConfig | None = None) -> None:
        super().__init__()
        cfg = config or ComatConfig()
        self.layout, self.config = layout, cfg
        E, K, T = cfg.embed, cfg.heads, layout.n_types
        if cfg.obs_embed:
            D = layout.obs_dim
            self.obs_encoder = nn.Sequential(nn.LayerNorm(D), init_linear(nn.Linear(D, E)), nn.GELU())
        self.heat = nn.ModuleList(
            HEATBlock(
                layout.obs_dim if k == 0 and not cfg.obs_embed else E,
                E,
                T,
                cfg.edge_embed,
                K,
                cfg.root_weight,
                cfg.heat_form,
                cfg.message_gain,
            )
            for k in range(cfg.heat_blocks)
        )
        self.heat_norm = nn.ModuleList(nn.LayerNorm(E) for _ in range(cfg.heat_blocks))
        if cfg.node_ffn:
            self.node_ffn = nn.ModuleList(mlp([E, E, E]) for _ in range(cfg.heat_blocks))
            self.node_ffn_norm = nn.ModuleList(nn.LayerNorm(E) for _ in range(cfg.heat_blocks))
        self.critic = mlp([E, E, 1])
        # θ¹: action embedding block.
        self.token = nn.Sequential(init_linear(nn.Linear(self.n_actions + 1, E, bias=False)), nn.ReLU())
        self.self_attn = Attention(E, K)
        self.ln1, self.ln2 = nn.LayerNorm(E), nn.LayerNorm(E)
        self.fc = mlp([E, E, E])
        # θ²: robot representations attend to the embedded actions.
        self.cross_attn = Attention(E, K)
        self.ln3, self.ln4 = nn.LayerNorm(E), nn.LayerNorm(E)
        self.fc2 = mlp([E, E, E])
        # Decision layer: type-stratified (ComatConfig.decision), on [h_m ‖ c_m].
        self.decision = DecisionMode(cfg.decision)
        self.heads = TypeHeads(E + layout.n_caps, E, self.n_actions, T, mode=self.decision)
        self.weights_config = weights_config(layout, cfg)  # what fixes every array's shape (comat_schema)
        check_arrays(
            self.state_dict(),
            parameter_shapes(self.weights_config),
            "Comat's parameters do not match their description in comat.models.comat_schema",
        )

    # -- encoder ------------------------------------------------------------------------------------
    def encode(self, obs, mask, packed: PackedTeams | None = None):
        """Representations (B, N, E) and values (B, N); ``packed``: of a packed batch's robots,
        obs (R, D) -> (R, E) and (R,), ``mask`` unused."""
        cfg = self.config
        world = cfg.edge_frame == "world"
        if packed is None:
            edge_attr, edge_type, edge_mask = edge_features(obs, mask, self.layout, world)
        else:
            (edge_attr, edge_type), edge_mask = packed_edge_features(obs, packed, self.layout, world), None
        types = self.layout.types(obs)
        h = self.obs_encoder(obs) if cfg.obs_embed else obs
        for k, (block, norm) in enumerate(zip(self.heat, self.heat_norm)):
            out = block(h, types, edge_attr, edge_type, edge_mask, packed)
            h = norm(h + out if k or cfg.obs_embed else out)
            if self.config.node_ffn:
                h = self.node_ffn_norm[k](h + self.node_ffn[k](h))
        return h, self.critic(h)[..., 0]

    # -- decoder ------------------------------------------------------------------------------------
    def _actor(self, h, obs) -> torch.Tensor:
        x = torch.cat([h, self.layout.capabilities(obs)], -1)
        return self.heads(x, obs[..., 4 : 4 + self.layout.n_types])

    def _embed_actions(self, e, attended) -> torch.Tensor:
        x = self.ln1(e + attended)
        return self.ln2(x + self.fc(x))

    def _decide(self, rep, attended, obs) -> torch.Tensor:
        h = self.ln3(rep + attended)
        h = self.ln4(h + self.fc2(h))
        return self._actor(h, obs)

    def decode_all(self, rep, tokens, obs, mask, packed: PackedTeams | None = None):
        """Teacher-forced logits (B, N, A); ``packed``: of a packed batch's robots, (R, A) from
        rep (R, E), tokens (R, A+1) and obs (R, D), each robot attending to its team up to itself."""
        m = None if packed is not None else causal(tokens.shape[1], tokens.device)[None]
        # θ¹'s token embedding and its attention's queries, keys and values depend on the token
        # alone: computed for the A+1 tokens once and looked up by the one-hot tokens (a product
        # with a one-hot is exact), as decode_init does, instead of per robot.
        sa = self.self_attn
        table = self.token(torch.eye(self.n_actions + 1, device=tokens.device))  # (A+1, E)
        k_table, v_table = sa._kv_merged(table, table)
        e = tokens @ table
        attended = sa.attend(tokens @ sa.q(table), tokens @ k_table, tokens @ v_table, m, packed)
        a_hat = self._embed_actions(e, attended)
        return self._decide(rep, self.cross_attn(rep, a_hat, a_hat, m, packed), obs)

    def decode_init(self, rep, obs):
        # θ¹'s token embedding and its attention's queries, keys and values depend on the token
        # alone: tabulated for the A+1 tokens once per sequence, looked up per robot. θ²'s
        # queries for every robot in one matmul; the actor's capability share likewise.
        sa = self.self_attn
        e = self.token(torch.eye(self.n_actions + 1, device=rep.device))[:, None]  # (A+1, 1, E)
        k, v = sa._kv(e, e)
        return _Decoding(
            rep=rep,
            types=obs[..., 4 : 4 + self.layout.n_types],
            e=e,
            q=sa.step_query(e),
            k=k,
            v=v,
            self_cache=KVCache(),
            cross_cache=KVCache(),
            cross_q=self.cross_attn.step_query(rep),
            caps=self.heads.partial(self.layout.capabilities(obs)),
        )

    def decode_step(self, st: _Decoding, m: int, token):
        e = st.e[token]  # (B, 1, E)
        attended = self.self_attn.step_projected(st.q[token], st.k[token], st.v[token], st.self_cache)
        a_hat = self._embed_actions(e, attended)
        attended = self.cross_attn.step(st.cross_q[:, :, m : m + 1], a_hat, a_hat, st.cross_cache)
        h = self.ln3(st.rep[:, m : m + 1] + attended)
        h = self.ln4(h + self.fc2(h))[:, 0]
        return self.heads.finish(h, st.caps[:, m], st.types[:, m])

    # -- the update: a batch packed as one graph ---------------------------------------------------
    def _packs(self, obs) -> bool:
        """Whether the fused kernels apply (CPU float32, HEAT's reference form, 16-wide heads)."""
        cfg = self.config
        return (
            kernels.enabled()
            and obs.device.type == "cpu"
            and obs.dtype == torch.float32
            and self.critic[0].weight.dtype == torch.float32
            and cfg.heat_form == "reference"
            and cfg.embed == cfg.heads * HEAD_WIDTH
        )

    def _packing(self, obs, mask) -> PackedTeams | None:
        """The batch packed (``comat.models.packing``) where the fused kernels apply and each team's
        robots come first, else None."""
        return pack(mask, self.layout.types(obs), self.layout.n_types) if self._packs(obs) else None

    def evaluate_actions(self, obs, mask, actions, state=None):
        """Log-probs, entropies and values (B, N) of given actions: over the batch packed as one
        graph where the fused kernels apply (the same numbers within float rounding,
        ``tests/test_packing.py``), else one padded pass per group of team sizes."""
        packed = self._packing(obs, mask)
        if packed is None:
            return super().evaluate_actions(obs, mask, actions, state)
        x, a = packed.gather(obs), packed.gather(actions)
        rep, values = self.encode(x, None, packed)
        previous = torch.where(packed.first, 0, a.roll(1) + 1)  # the token before each robot's action
        tokens = F.one_hot(previous, self.n_actions + 1).to(x.dtype)
        logp, entropy = score_actions(self.decode_all(rep, tokens, x, None, packed), a, None)
        return packed.scatter(torch.stack([logp, entropy, values], -1)).unbind(-1)

    def values(self, obs, mask, state=None):
        """Values (B, N): over the batch packed as one graph where the fused kernels apply (padded
        slots 0), in passes of at most about :data:`VALUE_CHUNK_EDGES` edges; else one padded pass
        per group of team sizes."""
        if not self._packs(obs):
            return super().values(obs, mask, state)
        size = mask.sum(1)
        edges = int((size * size).sum())
        parts = (
            split_teams(size.numpy(), -(-edges // VALUE_CHUNK_EDGES)) if edges > VALUE_CHUNK_EDGES else [slice(None)]
        )
        return torch.cat([self._packed_values(obs[teams], mask[teams]) for teams in parts])

    def _packed_values(self, obs, mask):
        packed = self._packing(obs, mask)
        if packed is None:
            return super().values(obs, mask)  # (COMAT's critic reads no global state)
        return packed.scatter(self.encode(packed.gather(obs), None, packed)[1])

    # -- the arrays acting reads, by name -----------------------------------------------------------
    def weight_tensors(self, names) -> dict[str, torch.Tensor]:
        """name -> tensor for names of ``comat_schema`` (``weight_shapes``, ``parameter_shapes``),
        the decision layer (``heads.*``) in acting form: the parameters themselves, except each
        type's output layer where adapters add the shared one."""
        out, heads = {}, None
        for name in names:
            if name.startswith("heads."):
                heads = self.heads.acting_arrays() if heads is None else heads
                out[name] = heads[name[len("heads.") :]]
                continue
            # The modules' own dicts: this runs on every compiled call, and nn.Module's attribute
            # lookup (get_parameter) costs several times more per name.
            *path, leaf = name.split(".")
            module = self
            for part in path:
                module = module._modules[part]
            out[name] = module._parameters[leaf]
        return out

    def acting_arrays(self, critic: bool = False) -> dict[str, torch.Tensor]:
        """Every array acting reads (``comat_schema.weight_shapes``, in its order), by name; the
        critic's only with ``critic``. What the compiled kernels and the numpy runtime take."""
        return self.weight_tensors(weight_shapes(self.weights_config, critic))

    @torch.no_grad()
    def encode_compiled(self, obs, mask):
        arrays = self.weight_tensors(encoder_shapes(self.weights_config, critic=True))
        node_ws, mats, vecs, flags = comat_encode_args(
            {n: numpy_view(t) for n, t in arrays.items()}, self.weights_config
        )
        rep, values = comat_encode(
            node_ws,
            mats,
            vecs,
            numpy_view(obs),
            mask.contiguous().numpy(),
            self.config.heads,
            self.layout.n_types,
            *flags,
        )
        return torch.from_numpy(rep), torch.from_numpy(values)

    @torch.no_grad()
    def decode_compiled(self, rep, obs, mask, noise):
        arrays = self.weight_tensors(decoder_shapes(self.weights_config))
        mats, vecs, shared_hidden = comat_decode_args(
            {n: numpy_view(t) for n, t in arrays.items()}, self.weights_config
        )
        noise_np, mask_np = self._compiled_inputs(noise, mask)
        actions, logits = comat_decode(
            mats,
            vecs,
            numpy_view(rep),
            numpy_view(obs),
            mask_np,
            noise_np,
            noise is None,
            self.config.heads,
            self.layout.n_types,
            shared_hidden,
        )
        return torch.from_numpy(actions), torch.from_numpy(logits)


@dataclass
class _Decoding:
    """Per-sequence state of cached decoding: representations (B, N, E), type one-hots
    (B, N, T), token tables e (A+1, 1, E) and q/k/v (A+1, K, 1, E/K), the two attentions'
    caches, θ²'s queries (B, K, N, E/K) and the actor's capability share (B, N, T·E); queries
    come scaled (:meth:`Attention.step_query`)."""

    rep: torch.Tensor
    types: torch.Tensor
    e: torch.Tensor
    q: torch.Tensor
    k: torch.Tensor
    v: torch.Tensor
    self_cache: KVCache
    cross_cache: KVCache
    cross_q: torch.Tensor
    caps: torch.Tensor


def build(dims, config: ComatConfig, acting_only: bool = False) -> dict[str, nn.Module]:
    """COMAT's network (learner ``comat``, :mod:`comat.learners`): acting needs all of it (its value
    head shares the encoder the actions are decoded from)."""
    return {"policy": Comat(dims.layout, config)}
