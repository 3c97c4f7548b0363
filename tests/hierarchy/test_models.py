"""model.pt files of the Chapter 4 networks: round trips and refusals by name."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch

from artic.errors import InputError
from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig, collate
from artic.hierarchy.graph import PartGraphConfig, build_part_graph
from artic.hierarchy.models import (
    LABELLER_KIND,
    SEGMENTER_KIND,
    load_labeller,
    load_segmenter,
    save_labeller,
    save_segmenter,
    segmentation_config_from_dict,
    segmentation_config_to_dict,
)
from artic.hierarchy.pointnet2 import PointNet2Config, SetAbstractionSpec
from artic.hierarchy.segmentation import (
    InferenceConfig,
    PartSegmentationNet,
    SegmentationConfig,
)
from artic.hierarchy.types import PartGraph

TINY_BACKBONE = PointNet2Config(
    set_abstractions=(
        SetAbstractionSpec(16, 0.4, 8, (8, 8)),
        SetAbstractionSpec(None, 0.0, 0, (8, 16)),
    ),
    propagations=((8,), (8,)),
)
TINY_SEG = SegmentationConfig(n_masks=6, backbone=TINY_BACKBONE, head_width=8, confidence_width=8)
TINY_GNN = GraphNetConfig(encoder_widths=(8, 16), decoder_points=8, hidden=8, head_hidden=8)


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    with torch.random.fork_rng():
        torch.manual_seed(0)
        yield
    torch.set_num_threads(threads)


def test_segmentation_config_round_trip() -> None:
    for config in (SegmentationConfig(), TINY_SEG, SegmentationConfig().scaled(0.25)):
        assert segmentation_config_from_dict(segmentation_config_to_dict(config)) == config


def test_segmenter_round_trip(tmp_path: Path) -> None:
    model = PartSegmentationNet(TINY_SEG)
    inference = InferenceConfig(n_points=64, min_points=2)
    path = tmp_path / "model.pt"
    save_segmenter(path, "storage_furniture", model, inference, {"best_epoch": 3})
    loaded = load_segmenter(path, "storage_furniture")
    assert loaded.category == "storage_furniture"
    assert loaded.inference == inference
    assert loaded.meta == {"best_epoch": 3}
    assert loaded.model.config == TINY_SEG
    assert not loaded.model.training
    points = torch.from_numpy(np.random.default_rng(0).normal(size=(1, 64, 3)).astype("f4"))
    model.eval()
    with torch.no_grad():
        expected, got = model(points), loaded.model(points)
    for a, b in zip(expected, got, strict=True):
        assert torch.equal(a, b)
    assert load_segmenter(path).category == "storage_furniture"  # any category


def _graph() -> PartGraph:
    rng = np.random.default_rng(0)
    points = np.concatenate([rng.uniform(0, 1, (50, 3)), rng.uniform(0.9, 1.5, (50, 3))])
    part_id = np.repeat(np.arange(2), 50)
    return build_part_graph(
        points, part_id, rng, PartGraphConfig(contact_threshold=0.2, points_per_node=16)
    )


def test_labeller_round_trip(tmp_path: Path) -> None:
    model = GraphLabellingNet(TINY_GNN)
    graph_cfg = PartGraphConfig(contact_threshold=0.03, points_per_node=16)
    path = tmp_path / "model.pt"
    save_labeller(path, "lamp", model, graph_cfg, {"graphs": 10})
    eager = load_labeller(path, "lamp", compiled=False)
    assert (eager.category, eager.graph, eager.meta) == ("lamp", graph_cfg, {"graphs": 10})
    assert isinstance(eager.model, GraphLabellingNet) and eager.model.cfg == TINY_GNN
    compiled = load_labeller(path, "lamp")  # the compiled program (hierarchy.compiled)
    assert isinstance(compiled.model, torch.jit.ScriptModule)
    assert (compiled.category, compiled.graph, compiled.meta) == ("lamp", graph_cfg, {"graphs": 10})
    batch = collate([_graph()])
    model.eval()
    with torch.no_grad():
        for loaded in (eager, compiled):
            assert not loaded.model.training
            for a, b in zip(model(batch), loaded.model(batch), strict=True):
                assert torch.equal(a, b)


def test_wrong_kind_or_category_refused_by_name(tmp_path: Path) -> None:
    seg, gnn = tmp_path / "seg.pt", tmp_path / "gnn.pt"
    save_segmenter(seg, "lamp", PartSegmentationNet(TINY_SEG), InferenceConfig(), {})
    save_labeller(gnn, "lamp", GraphLabellingNet(TINY_GNN), PartGraphConfig(), {})
    with pytest.raises(InputError, match=f"a {SEGMENTER_KIND} model, not a {LABELLER_KIND}"):
        load_labeller(seg)
    with pytest.raises(InputError, match=f"a {LABELLER_KIND} model, not a {SEGMENTER_KIND}"):
        load_segmenter(gnn)
    with pytest.raises(InputError, match="category lamp, not office_chair"):
        load_segmenter(seg, "office_chair")
    with pytest.raises(InputError, match="category lamp, not storage_furniture"):
        load_labeller(gnn, "storage_furniture")
    with pytest.raises(InputError, match="no such model file"):
        load_segmenter(tmp_path / "missing.pt")


def test_mismatched_weights_refused(tmp_path: Path) -> None:
    path = tmp_path / "model.pt"
    save_segmenter(path, "lamp", PartSegmentationNet(TINY_SEG), InferenceConfig(), {})
    payload = torch.load(path, weights_only=True)
    payload["hparams"]["segmentation"] = segmentation_config_to_dict(
        dataclasses.replace(TINY_SEG, head_width=12)
    )
    torch.save(payload, path)
    with pytest.raises(InputError, match="segmenter does not load"):
        load_segmenter(path)
