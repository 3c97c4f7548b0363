"""Training of the section 4.4 graph labelling network (section 4.4.3).

1. Pre-training: the PointNet node encoder is the encoder of a point autoencoder trained
   on the parts' point sets with the Chamfer distance (thesis: Nesterov SGD, learning
   rate 1e-3, 500 epochs).
2. Training: `GraphLabellingNet` with the pre-trained encoder, on part graphs built from
   ground-truth segmentations, with the sum of the four cross-entropies (thesis: Adam,
   learning rate 1e-3, 30 epochs); validation loss after every epoch, early stopping.

Examples come from labelled clouds (`make_example`): parts that no point shows (e.g. a
handle hidden in a noisy scan) are dropped and the tree is contracted over them
(`restrict_tree`). Resumable and reproducible as `fit_segmenter`: epoch e of each phase
draws its order from (seed, phase, e). No file access here.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import torch
from numpy.typing import NDArray

from artic.evaluation.hierarchy import HierarchyMetrics, hierarchy_counts, summarize
from artic.hierarchy.gnn import (
    GraphLabellingNet,
    PointAutoencoder,
    chamfer_distance,
    collate,
    collate_labels,
    labelling_loss,
    predict,
    pretrain_step,
    train_step,
)
from artic.hierarchy.graph import PartGraphConfig, build_part_graph, graph_labels
from artic.hierarchy.tree import extract_tree
from artic.hierarchy.types import GraphLabels, KinematicTree, PartGraph
from artic.learning.fit_state import FitState

log = logging.getLogger("artic")


@dataclass
class LabellerFitState(FitState):
    """`FitState` of the graph network plus its autoencoder pre-training phase."""

    pretrain_epoch: int = 0
    pretrain_history: list[dict[str, float]] = field(default_factory=list)


PRETRAIN, TRAIN = 1, 2  # phase numbers in the seeds


def restrict_tree(tree: KinematicTree, present: Sequence[int]) -> KinematicTree:
    """The tree over the parts `present` (sorted ids of `tree`), renumbered 0..len-1 in
    that order: each part hangs from its nearest present ancestor, keeping its own motion
    and joint type. ValueError when the root is not present."""
    keep = sorted(int(p) for p in present)
    if tree.root not in keep:
        raise ValueError(f"the root part {tree.root} is not present")
    new = {p: i for i, p in enumerate(keep)}
    parent = tree.parents
    joint_of = {child: tree.joint_types[e] for e, (_, child) in enumerate(tree.edges)}
    edges, joints = [], []
    for _, child in tree.edges:  # breadth-first from the root: parents first
        if child not in new:
            continue
        up = int(parent[child])
        while up not in new:
            up = int(parent[up])
        edges.append((new[up], new[child]))
        joints.append(joint_of[child])
    return KinematicTree(
        num_parts=len(keep),
        root=new[tree.root],
        edges=tuple(edges),
        motion_types=tuple(tree.motion_types[p] for p in keep),
        joint_types=tuple(joints),
    )


class LabelledGraph(NamedTuple):
    """A training example: the part graph of a cloud, its targets and its tree."""

    graph: PartGraph
    labels: GraphLabels
    tree: KinematicTree


def make_example(
    points: NDArray[np.floating],
    part_id: NDArray[np.integer],
    tree: KinematicTree,
    rng: np.random.Generator,
    graph_cfg: PartGraphConfig,
) -> LabelledGraph | None:
    """The labelled part graph of a cloud with ground-truth part ids (N,) over `tree`'s
    parts (-1: no part); None when fewer than two parts or not the root are visible."""
    ids = np.asarray(part_id, dtype=np.int64)
    labelled = ids >= 0
    present = np.unique(ids[labelled])
    if len(present) < 2 or tree.root not in present or present.max() >= tree.num_parts:
        return None
    sub = restrict_tree(tree, present.tolist())
    compact = np.searchsorted(present, ids[labelled])
    graph = build_part_graph(np.asarray(points)[labelled], compact, rng, graph_cfg)
    return LabelledGraph(graph, graph_labels(graph, sub), sub)


@dataclass(frozen=True)
class LabellerFitConfig:
    pretrain_epochs: int
    pretrain_batch_size: int  # part point sets per step
    pretrain_lr: float
    pretrain_momentum: float
    epochs: int
    batch_size: int  # graphs per step
    lr: float
    weight_decay: float
    patience: int
    seed: int
    log_every_s: float = 30.0


def part_point_sets(examples: Sequence[LabelledGraph]) -> torch.Tensor:
    """Every node's points of every example: (sum of P, K, 3) float32."""
    return torch.from_numpy(np.concatenate([e.graph.node_points for e in examples]))


def pretrain_autoencoder(
    autoencoder: PointAutoencoder,
    optimizer: torch.optim.Optimizer,
    points: torch.Tensor,
    cfg: LabellerFitConfig,
    state: LabellerFitState,
    device: torch.device,
    on_epoch: Callable[[LabellerFitState], None],
) -> LabellerFitState:
    """Chamfer-distance autoencoder epochs over part point sets (M, K, 3) until
    `cfg.pretrain_epochs`; `on_epoch(state)` after each."""
    autoencoder.to(device)
    while state.pretrain_epoch < cfg.pretrain_epochs:
        t0 = time.perf_counter()
        order = np.random.default_rng([cfg.seed, PRETRAIN, state.pretrain_epoch])
        index = order.permutation(len(points))
        total = 0.0
        for start in range(0, len(index), cfg.pretrain_batch_size):
            chunk = torch.from_numpy(index[start : start + cfg.pretrain_batch_size])
            batch = points[chunk].to(device)
            total += pretrain_step(autoencoder, optimizer, batch) * len(chunk)
        state.pretrain_epoch += 1
        seconds = time.perf_counter() - t0
        chamfer = total / max(len(points), 1)
        state.pretrain_history.append(
            {"epoch": state.pretrain_epoch, "chamfer": chamfer, "seconds": seconds}
        )
        if state.pretrain_epoch % 10 == 0 or state.pretrain_epoch == cfg.pretrain_epochs:
            log.info(
                "pretrain epoch %d/%d: Chamfer %.5f, %.1f s",
                state.pretrain_epoch, cfg.pretrain_epochs, chamfer, seconds,
            )  # fmt: skip
        on_epoch(state)
    return state


def fit_labeller(
    model: GraphLabellingNet,
    optimizer: torch.optim.Optimizer,
    train: Sequence[LabelledGraph],
    val: Sequence[LabelledGraph],
    cfg: LabellerFitConfig,
    state: LabellerFitState,
    device: torch.device,
    on_epoch: Callable[[LabellerFitState], None],
) -> LabellerFitState:
    """Labelling-network epochs until `cfg.epochs` or early stopping on the validation
    loss; `on_epoch(state)` after each."""
    model.to(device)
    while state.epoch < cfg.epochs and not state.stopped_early:
        t0 = time.perf_counter()
        order = np.random.default_rng([cfg.seed, TRAIN, state.epoch]).permutation(len(train))
        sums = np.zeros(5)
        for start in range(0, len(order), cfg.batch_size):
            chosen = [train[i] for i in order[start : start + cfg.batch_size]]
            graph, labels = _batch(chosen, device)
            terms = train_step(model, optimizer, graph, labels)
            sums += np.array([float(terms.total), *terms[1:]]) * len(chosen)
        train_terms = sums / max(len(train), 1)
        val_terms = validate_labeller(model, val, cfg.batch_size, device)
        state.end_epoch(val_terms[0], model, cfg.patience)
        seconds = time.perf_counter() - t0
        names = ("loss", "motion", "exists", "direction", "root")
        row: dict[str, float] = {"epoch": state.epoch}
        row |= {f"train_{n}": float(v) for n, v in zip(names, train_terms, strict=True)}
        row |= {f"val_{n}": float(v) for n, v in zip(names, val_terms, strict=True)}
        state.history.append(row | {"seconds": seconds})
        log.info(
            "epoch %d/%d: train loss %.3f, val loss %.3f (best %.3f at %d), %.1f s",
            state.epoch, cfg.epochs, train_terms[0], val_terms[0], state.best_val,
            state.best_epoch, seconds,
        )  # fmt: skip
        on_epoch(state)
    return state


def _batch(examples: Sequence[LabelledGraph], device: torch.device) -> tuple[Any, Any]:
    graphs = [e.graph for e in examples]
    labels = collate_labels([e.labels for e in examples], graphs)
    return collate(graphs).to(device), labels.to(device)


@torch.no_grad()
def validate_labeller(
    model: GraphLabellingNet,
    examples: Sequence[LabelledGraph],
    batch_size: int,
    device: torch.device,
) -> NDArray[np.float64]:
    """Mean (total, motion, exists, direction, root) losses per graph, evaluation mode."""
    model.eval()
    sums = np.zeros(5)
    for start in range(0, len(examples), batch_size):
        chosen = examples[start : start + batch_size]
        graph, labels = _batch(chosen, device)
        terms = labelling_loss(model(graph), labels, graph)
        sums += np.array([float(terms.total), *terms[1:]]) * len(chosen)
    return sums / max(len(examples), 1)


def score_labeller(model: GraphLabellingNet, examples: Sequence[LabelledGraph]) -> HierarchyMetrics:
    """Table 4.2 metrics with ground-truth segmentation: labelling -> Prim tree from the
    predicted root (section 4.2.3) -> E_type, E_exist, E_dir, E_root, Tree F1."""
    counts = []
    for example in examples:
        labelling = predict(model, example.graph)
        tree = extract_tree(labelling, example.graph.centroids)
        counts.append(hierarchy_counts(labelling, tree, example.tree))
    return summarize(counts)


def autoencoder_chamfer(
    autoencoder: PointAutoencoder, points: torch.Tensor, batch_size: int, device: torch.device
) -> float:
    """Mean Chamfer distance of the autoencoder's reconstructions of (M, K, 3)."""
    autoencoder.eval()
    total = 0.0
    with torch.no_grad():
        for start in range(0, len(points), batch_size):
            batch = points[start : start + batch_size].to(device)
            total += float(chamfer_distance(autoencoder(batch), batch).sum())
    return total / max(len(points), 1)
