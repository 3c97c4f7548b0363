"""Graph labelling network (thesis section 4.4.2, Fig. 4.4) and its training steps.

- Node encoder: a PointNet (shared point-wise MLP + max pool) turns each part's points
  (K, 3) into a code; it is pre-trained as the encoder of a point autoencoder whose
  decoder emits a fixed set of points, trained with the Chamfer distance (4.4.3).
- Graph network: three GraphSAGE convolutions (Hamilton et al., 2017), each followed by
  learned edge-collapse pooling (Diehl, 2019; PyG's `EdgePooling`, which runs on plain
  torch without torch_scatter). The output of every convolution and every pooling is
  unpooled back to the original nodes and concatenated: the multi-scale feature y.
- Heads (MLPs): node motion type (4 classes), root (one logit per node, softmax over
  the nodes of a graph), edge existence and edge direction from [y_a, y_b, edge
  features]. Existence is symmetric in the endpoints (f(a, b) + f(b, a)); direction is
  antisymmetric (g(a, b) - g(b, a)), so p(a parent of b) = 1 - p(b parent of a).
- Loss: the sum of the four cross-entropies (direction only on existing edges).

`GraphLabellingNet` compiles with `torch.jit.script` (inference runs the compiled program,
`compiled.py`): hence no `from __future__ import annotations` in this module (TorchScript
reads the class annotations as types) and the poolings' unpool data kept as tensors.
"""

import itertools
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from artic.hierarchy.config import GraphNetConfig
from artic.hierarchy.graph import EDGE_FEATURES, NODE_FEATURES
from artic.hierarchy.types import GraphLabels, PartGraph
from artic.objects.tree import MOTION_TYPES, GraphLabelling


def _mlp(widths: Sequence[int], last_activation: bool = False) -> nn.Sequential:
    layers: list[nn.Module] = []
    for i, (a, b) in enumerate(itertools.pairwise(widths)):
        layers.append(nn.Linear(a, b))
        if last_activation or i < len(widths) - 2:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


class PointNetEncoder(nn.Module):
    """PointNet (Qi et al., 2017a): points (B, K, 3) -> codes (B, C), C = widths[-1].

    With `part_frame` every point is also read in its own set's frame (minus the set's
    centroid, over the set's radius), as PointNet++ reads a neighbourhood: the points come
    in the object's frame (`graph.build_part_graph`), where a drawer's 1.5 cm handle is a
    hundredth of the coordinates' range; in the part's frame it is a tenth."""

    def __init__(self, widths: Sequence[int] = (32, 64, 128), part_frame: bool = False) -> None:
        super().__init__()
        self.code_size = int(widths[-1])
        self.part_frame = bool(part_frame)
        self.mlp = _mlp([6 if part_frame else 3, *widths], last_activation=True)

    def forward(self, points: Tensor) -> Tensor:
        if self.part_frame:
            local = points - points.mean(dim=-2, keepdim=True)
            radius = local.square().sum(dim=-1, keepdim=True).amax(dim=-2, keepdim=True).sqrt()
            points = torch.cat([points, local / radius.clamp_min(1e-6)], dim=-1)
        return self.mlp(points).amax(dim=-2)


class PointAutoencoder(nn.Module):
    """Encoder + MLP decoder to `num_points` points: (B, K, 3) -> (B, num_points, 3)."""

    def __init__(
        self,
        widths: Sequence[int] = (32, 64, 128),
        num_points: int = 128,
        part_frame: bool = False,
    ) -> None:
        super().__init__()
        self.encoder = PointNetEncoder(widths, part_frame)
        self.num_points = num_points
        self.decoder = _mlp([self.encoder.code_size, 256, 256, num_points * 3])

    def forward(self, points: Tensor) -> Tensor:
        code = self.encoder(points)
        return self.decoder(code).view(points.shape[0], self.num_points, 3)


def chamfer_distance(a: Tensor, b: Tensor) -> Tensor:
    """Symmetric Chamfer distance (mean squared nearest-neighbour distance both ways).

    a: (B, M, 3), b: (B, K, 3) -> (B,).
    """
    d = (a[:, :, None, :] - b[:, None, :, :]).square().sum(dim=-1)
    return d.min(dim=2).values.mean(dim=1) + d.min(dim=1).values.mean(dim=1)


def pretrain_step(
    autoencoder: PointAutoencoder, optimizer: torch.optim.Optimizer, points: Tensor
) -> float:
    """One autoencoder step on part point sets (B, K, 3); returns the mean Chamfer loss.
    The thesis trains it with Nesterov SGD, learning rate 1e-3 (section 4.4.3)."""
    autoencoder.train()
    optimizer.zero_grad()
    loss = chamfer_distance(autoencoder(points), points).mean()
    loss.backward()
    optimizer.step()
    return float(loss.detach())


class GraphBatch(NamedTuple):
    """Several part graphs as one disjoint graph (tensors).

    node_points: (P, K, 3). node_features: (P, 7). edges: (E, 2) long, node indices of
    the batch. edge_features: (E, 10). batch: (P,) graph of each node. num_graphs: G.
    """

    node_points: Tensor
    node_features: Tensor
    edges: Tensor
    edge_features: Tensor
    batch: Tensor
    num_graphs: int

    def to(self, device: torch.device | str) -> "GraphBatch":
        return GraphBatch(
            self.node_points.to(device),
            self.node_features.to(device),
            self.edges.to(device),
            self.edge_features.to(device),
            self.batch.to(device),
            self.num_graphs,
        )


class LabelBatch(NamedTuple):
    """Targets aligned with a GraphBatch: motion_type (P,) long, exists (E,) float,
    parent_first (E,) float, root (G,) long node index in the batch."""

    motion_type: Tensor
    exists: Tensor
    parent_first: Tensor
    root: Tensor

    def to(self, device: torch.device | str) -> "LabelBatch":
        return LabelBatch(*(t.to(device) for t in self))


class GraphLogits(NamedTuple):
    """motion (P, 4), root (P,), exists (E,), parent_first (E,): unnormalised logits."""

    motion: Tensor
    root: Tensor
    exists: Tensor
    parent_first: Tensor


class LossTerms(NamedTuple):
    """The labelling loss (a tensor, for backward) and its four parts as floats."""

    total: Tensor
    motion: float
    exists: float
    direction: float
    root: float


def collate(graphs: Sequence[PartGraph]) -> GraphBatch:
    """Stack part graphs into one disjoint graph, offsetting node indices."""
    if not graphs:
        raise ValueError("collate needs at least one graph")
    offsets = np.cumsum([0] + [g.num_parts for g in graphs[:-1]])
    edges = np.concatenate([g.edges + o for g, o in zip(graphs, offsets, strict=True)])
    batch = np.concatenate([np.full(g.num_parts, i) for i, g in enumerate(graphs)])
    return GraphBatch(
        node_points=torch.from_numpy(np.concatenate([g.node_points for g in graphs])),
        node_features=torch.from_numpy(np.concatenate([g.node_features for g in graphs])),
        edges=torch.from_numpy(edges.astype(np.int64)).reshape(-1, 2),
        edge_features=torch.from_numpy(np.concatenate([g.edge_features for g in graphs])),
        batch=torch.from_numpy(batch.astype(np.int64)),
        num_graphs=len(graphs),
    )


def collate_labels(labels: Sequence[GraphLabels], graphs: Sequence[PartGraph]) -> LabelBatch:
    """Targets of `graphs` (same order as `collate`)."""
    offsets = np.cumsum([0] + [g.num_parts for g in graphs[:-1]])
    return LabelBatch(
        motion_type=torch.from_numpy(np.concatenate([lab.motion_type for lab in labels])),
        exists=torch.from_numpy(np.concatenate([lab.exists for lab in labels]).astype(np.float32)),
        parent_first=torch.from_numpy(
            np.concatenate([lab.parent_first for lab in labels]).astype(np.float32)
        ),
        root=torch.tensor([lab.root + int(o) for lab, o in zip(labels, offsets, strict=True)]),
    )


_REVERSE_INDEX = [0, 1, 2, 3, 7, 8, 9, 4, 5, 6]
_REVERSE_SIGN = [1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]


def graph_log_softmax(logits: Tensor, batch: Tensor, num_graphs: int) -> Tensor:
    """log softmax of per-node logits (P,) over the nodes of each graph."""
    peak = torch.full((num_graphs,), -torch.inf, dtype=logits.dtype, device=logits.device)
    peak = peak.scatter_reduce(0, batch, logits.detach(), reduce="amax")
    shifted = logits - peak[batch]
    total = torch.zeros(num_graphs, dtype=logits.dtype, device=logits.device)
    total = total.index_add(0, batch, shifted.exp())
    return shifted - total.log()[batch]


def _unpool(x: Tensor, clusters: list[Tensor], scores: list[Tensor]) -> Tensor:
    """Features of the graph after len(clusters) edge poolings -> the original nodes:
    `EdgePooling.unpool` (divide by the merged edge's score, copy to the merged nodes)
    from the last pooling back to the first."""
    for level in range(len(clusters) - 1, -1, -1):
        x = (x / scores[level].view(-1, 1))[clusters[level]]
    return x


class GraphLabellingNet(nn.Module):
    """Fig. 4.4: PointNet node codes -> GraphSAGE + edge pooling/unpooling -> MLP heads."""

    _reverse_sign: Tensor
    _reverse_index: Tensor

    def __init__(self, cfg: GraphNetConfig | None = None, encoder: PointNetEncoder | None = None):
        super().__init__()
        from torch_geometric.nn import SAGEConv
        from torch_geometric.nn.pool import EdgePooling

        self.cfg = cfg = cfg or GraphNetConfig()
        self.encoder = encoder or PointNetEncoder(cfg.encoder_widths, cfg.node_frame == "part")
        width = cfg.hidden
        node_in = self.encoder.code_size + len(NODE_FEATURES)
        self.convs = nn.ModuleList(
            [SAGEConv(node_in if i == 0 else width, width) for i in range(cfg.num_layers)]
        )
        self.pools = nn.ModuleList([EdgePooling(width) for _ in range(cfg.num_layers)])
        y_size = 2 * cfg.num_layers * width
        edge_in = 2 * y_size + len(EDGE_FEATURES)
        h = cfg.head_hidden
        self.motion_head = _mlp([y_size, h, h, len(MOTION_TYPES)])
        self.root_head = _mlp([y_size, h, 1])
        self.exists_head = _mlp([edge_in, h, h, 1])
        self.direction_head = _mlp([edge_in, h, h, 1])
        self.register_buffer("_reverse_sign", torch.tensor(_REVERSE_SIGN), persistent=False)
        self.register_buffer("_reverse_index", torch.tensor(_REVERSE_INDEX), persistent=False)

    def node_features(self, graph: GraphBatch) -> Tensor:
        """The multi-scale features y (P, 2 * num_layers * hidden)."""
        x = torch.cat([self.encoder(graph.node_points), graph.node_features], dim=1)
        edge_index = torch.cat([graph.edges.T, graph.edges.T.flip(0)], dim=1)
        batch = graph.batch
        # what EdgePooling.unpool reads of each pooling (its UnpoolInfo's cluster and
        # new_edge_score), as plain tensors so that the network compiles (`compiled.py`)
        clusters: list[Tensor] = []
        scores: list[Tensor] = []
        levels: list[Tensor] = []
        for conv, pool in zip(self.convs, self.pools, strict=True):
            x = F.relu(conv(x, edge_index))
            levels.append(_unpool(x, clusters, scores))
            x, edge_index, batch, info = pool(x, edge_index, batch)
            clusters.append(info.cluster)
            scores.append(info.new_edge_score)
            levels.append(_unpool(x, clusters, scores))
        return torch.cat(levels, dim=1)

    def forward(self, graph: GraphBatch) -> GraphLogits:
        y = self.node_features(graph)
        a, b = graph.edges[:, 0], graph.edges[:, 1]
        forward_in = torch.cat([y[a], y[b], graph.edge_features], dim=1)
        reverse_features = graph.edge_features[:, self._reverse_index] * self._reverse_sign
        backward_in = torch.cat([y[b], y[a], reverse_features], dim=1)
        return GraphLogits(
            motion=self.motion_head(y),
            root=self.root_head(y).squeeze(-1),
            exists=(self.exists_head(forward_in) + self.exists_head(backward_in)).squeeze(-1),
            parent_first=(
                self.direction_head(forward_in) - self.direction_head(backward_in)
            ).squeeze(-1),
        )


#: the network as inference uses it: eager, or its compiled program (`hierarchy.compiled`)
Labeller = GraphLabellingNet | torch.jit.ScriptModule


def labelling_loss(logits: GraphLogits, labels: LabelBatch, graph: GraphBatch) -> LossTerms:
    """Sum of the cross-entropies of motion type, edge existence, edge direction (on
    edges that exist) and root (softmax over each graph's nodes)."""
    motion = F.cross_entropy(logits.motion, labels.motion_type)
    zero = logits.motion.sum() * 0.0
    exists = (
        F.binary_cross_entropy_with_logits(logits.exists, labels.exists)
        if labels.exists.numel()
        else zero
    )
    real = labels.exists > 0.5
    direction = (
        F.binary_cross_entropy_with_logits(logits.parent_first[real], labels.parent_first[real])
        if bool(real.any())
        else zero
    )
    root = -graph_log_softmax(logits.root, graph.batch, graph.num_graphs)[labels.root].mean()
    total = motion + exists + direction + root
    return LossTerms(
        total,
        float(motion.detach()),
        float(exists.detach()),
        float(direction.detach()),
        float(root.detach()),
    )


def train_step(
    model: GraphLabellingNet,
    optimizer: torch.optim.Optimizer,
    graph: GraphBatch,
    labels: LabelBatch,
) -> LossTerms:
    """One optimisation step of the labelling loss (the thesis: Adam, lr 1e-3)."""
    model.train()
    optimizer.zero_grad()
    terms = labelling_loss(model(graph), labels, graph)
    terms.total.backward()
    optimizer.step()
    return terms._replace(total=terms.total.detach())


@torch.no_grad()
def predict(model: Labeller, graph: PartGraph) -> GraphLabelling:
    """The network's probabilities on one part graph (evaluation mode)."""
    model.eval()
    device = next(model.parameters()).device
    batch = collate([graph]).to(device)
    logits = model(batch)

    def as_numpy(t: Tensor) -> np.ndarray:
        return t.detach().cpu().numpy()

    # the network runs in float32; its probabilities are normalised in float64 from the
    # logits, so a distribution sums to 1 to float64 precision on any CPU's kernels
    def f64(t: Tensor) -> Tensor:
        return t.detach().cpu().double()

    root = graph_log_softmax(f64(logits.root), batch.batch.cpu(), 1).exp()
    return GraphLabelling(
        edges=graph.edges.copy(),
        motion=as_numpy(torch.softmax(f64(logits.motion), dim=1)),
        exists=as_numpy(torch.sigmoid(f64(logits.exists))),
        parent_first=as_numpy(torch.sigmoid(f64(logits.parent_first))),
        root=as_numpy(root),
    )
