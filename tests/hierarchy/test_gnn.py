"""Graph labelling network (section 4.4.2): shapes, invariants, pre-training, overfitting."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np
import pytest
import torch

from artic.hierarchy.gnn import (
    GraphLabellingNet,
    GraphNetConfig,
    PointAutoencoder,
    chamfer_distance,
    collate,
    collate_labels,
    graph_log_softmax,
    predict,
    pretrain_step,
    train_step,
)
from artic.hierarchy.graph import (
    PartGraphConfig,
    build_part_graph,
    graph_labels,
    reverse_edge_features,
)
from artic.hierarchy.tree import extract_tree
from artic.hierarchy.types import PartGraph
from artic.objects.tree import JOINT_TYPE_OF_MOTION, KinematicTree
from box_clouds import box_surface

SMALL = GraphNetConfig(encoder_widths=(16, 32), decoder_points=32, hidden=32, head_hidden=32)


@pytest.fixture(autouse=True)
def one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    with torch.random.fork_rng():
        torch.manual_seed(0)
        yield
    torch.set_num_threads(threads)


def synthetic(index: int) -> tuple[PartGraph, KinematicTree]:
    """Small cabinets: a body with a door (+ handle) and/or a drawer, in various orders."""
    rng = np.random.default_rng(index)
    body = ([0.0, -0.3, 0.0], [0.4, 0.3, 0.8])
    door = ([-0.02, -0.28, 0.42], [-0.003, 0.28, 0.78])
    handle = ([-0.05, 0.2, 0.55], [-0.021, 0.24, 0.65])
    drawer = ([-0.02, -0.28, 0.02], [0.35, 0.28, 0.38])
    layouts = [
        ([body, door, handle, drawer], ((0, 1), (1, 2), (0, 3)), (0, 1, 0, 2)),
        ([drawer, body, door], ((1, 0), (1, 2)), (2, 0, 1)),
        ([door, handle, body], ((2, 0), (0, 1)), (1, 0, 0)),
    ]
    boxes, edges, motion = layouts[index]
    points = np.concatenate([box_surface(lo, hi, 100, rng) for lo, hi in boxes])
    part_id = np.repeat(np.arange(len(boxes)), 100)
    graph = build_part_graph(
        points, part_id, rng, PartGraphConfig(contact_threshold=0.08, points_per_node=32)
    )
    root = next(p for p in range(len(boxes)) if all(b != p for _, b in edges))
    joints = tuple(JOINT_TYPE_OF_MOTION[motion[b]] for _, b in edges)
    tree = KinematicTree(len(boxes), root, edges, motion, joints)
    return graph, tree


def test_forward_shapes_and_probability_invariants() -> None:
    graphs = [synthetic(i)[0] for i in range(3)]
    model = GraphLabellingNet(SMALL)
    batch = collate(graphs)
    logits = model(batch)
    parts, edges = batch.node_points.shape[0], batch.edges.shape[0]
    assert logits.motion.shape == (parts, 4) and logits.root.shape == (parts,)
    assert logits.exists.shape == (edges,) and logits.parent_first.shape == (edges,)

    graph = graphs[0]
    out = predict(model, graph)
    assert out.root.sum() == pytest.approx(1.0)
    assert np.allclose(out.motion.sum(axis=1), 1.0)
    # swapping an edge's endpoints leaves existence and flips direction
    flipped = dataclasses.replace(
        graph,
        edges=graph.edges[:, ::-1].copy(),
        edge_features=reverse_edge_features(graph.edge_features),
    )
    again = predict(model, flipped)
    assert np.allclose(again.exists, out.exists, atol=1e-6)
    assert np.allclose(again.parent_first, 1.0 - out.parent_first, atol=1e-6)


def test_graph_log_softmax_normalises_per_graph() -> None:
    logits = torch.tensor([1.0, 2.0, 3.0, -1.0, 5.0])
    batch = torch.tensor([0, 0, 0, 1, 1])
    p = graph_log_softmax(logits, batch, 2).exp()
    assert torch.allclose(p[:3], torch.softmax(logits[:3], 0))
    assert torch.allclose(p[3:], torch.softmax(logits[3:], 0))


def test_chamfer_and_pretraining() -> None:
    points = torch.rand(4, 32, 3)
    assert torch.allclose(chamfer_distance(points, points), torch.zeros(4))
    assert torch.all(chamfer_distance(points, points + 0.1) > 0)
    autoencoder = PointAutoencoder(SMALL.encoder_widths, SMALL.decoder_points)
    optimizer = torch.optim.Adam(autoencoder.parameters(), lr=3e-3)
    first = pretrain_step(autoencoder, optimizer, points)
    for _ in range(60):
        last = pretrain_step(autoencoder, optimizer, points)
    assert last < 0.5 * first


def test_overfits_small_graphs_and_trees_come_out_right() -> None:
    pairs = [synthetic(i) for i in range(3)]
    graphs = [g for g, _ in pairs]
    labels = [graph_labels(g, t) for g, t in pairs]
    assert all(lab.uncovered == () for lab in labels)
    batch, targets = collate(graphs), collate_labels(labels, graphs)
    autoencoder = PointAutoencoder(SMALL.encoder_widths, SMALL.decoder_points)
    model = GraphLabellingNet(SMALL, encoder=autoencoder.encoder)
    optimizer = torch.optim.Adam(model.parameters(), lr=3e-3)
    first = train_step(model, optimizer, batch, targets)
    for _ in range(200):
        last = train_step(model, optimizer, batch, targets)
    assert float(last.total) < 0.1 * float(first.total)
    for graph, tree in pairs:
        out = predict(model, graph)
        predicted = extract_tree(out, centroids=graph.centroids)
        assert predicted.root == tree.root
        assert set(predicted.edges) == set(tree.edges)
        assert predicted.motion_types == tree.motion_types


def test_same_seed_same_model_output() -> None:
    graph = synthetic(0)[0]
    torch.manual_seed(3)
    a = predict(GraphLabellingNet(SMALL), graph)
    torch.manual_seed(3)
    b = predict(GraphLabellingNet(SMALL), graph)
    assert np.array_equal(a.exists, b.exists) and np.array_equal(a.motion, b.motion)


def test_graphs_without_edges() -> None:
    rng = np.random.default_rng(0)
    far = np.concatenate(
        [
            box_surface([0, 0, 0], [0.1, 0.1, 0.1], 50, rng),
            box_surface([1, 1, 1], [1.1, 1.1, 1.1], 50, rng),
        ]
    )
    single = build_part_graph(far[:50], np.zeros(50, dtype=np.int64), rng)
    apart = build_part_graph(far, np.repeat([0, 1], 50), rng)
    assert single.num_edges == 0 and apart.num_edges == 0
    model = GraphLabellingNet(SMALL)
    for graph in (single, apart):
        out = predict(model, graph)
        assert out.exists.shape == (0,) and out.root.sum() == pytest.approx(1.0)
        tree = extract_tree(out, centroids=graph.centroids)
        assert len(tree.edges) == graph.num_parts - 1
    tree = KinematicTree(2, 0, ((0, 1),), (0, 1), ("revolute",))
    batch = collate([apart])
    terms = train_step(
        model,
        torch.optim.Adam(model.parameters()),
        batch,
        collate_labels([graph_labels(apart, tree)], [apart]),
    )
    assert np.isfinite(float(terms.total)) and terms.exists == 0.0 and terms.direction == 0.0


def test_the_part_frame_reads_a_part_at_its_own_scale_and_compiles():
    from artic.hierarchy.gnn import PointNetEncoder

    encoder = PointNetEncoder((16, 32), part_frame=True)
    rng = np.random.default_rng(0)
    part = torch.tensor(rng.uniform(-1.0, 1.0, (2, 64, 3)), dtype=torch.float32)
    # the part's own frame does not see where the part is, nor how large: moved and
    # scaled, only the object-frame half of the input changes
    moved = 0.05 * part + torch.tensor([0.3, -0.2, 0.1])
    object_half = PointNetEncoder((16, 32))
    with torch.no_grad():
        encoder.mlp[0].weight[:, :3] = 0.0  # the object-frame inputs switched off
        assert torch.allclose(encoder(part), encoder(moved), atol=1e-5)
        assert not torch.allclose(object_half(part), object_half(moved), atol=1e-3)
    model = GraphLabellingNet(SMALL.model_copy(update={"node_frame": "part"})).eval()
    assert model.encoder.part_frame and model.encoder.mlp[0].in_features == 6
    program = torch.jit.script(model)
    graph = collate([synthetic(0)[0]])
    with torch.no_grad():
        eager, scripted = model(graph), program(graph)
    assert all(torch.allclose(a, b, atol=1e-6) for a, b in zip(eager, scripted, strict=True))
