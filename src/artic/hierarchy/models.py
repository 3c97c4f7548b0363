"""Trained Chapter 4 networks as `model.pt` files: the part segmenter (section 4.3) and the
graph labelling network (section 4.4), each with what is needed to use it.

`save_segmenter` / `load_segmenter`: a `PartSegmentationNet`, its architecture
(`SegmentationConfig`) and the `InferenceConfig` it was trained for (the number of points
the cloud is downsampled to must match training), kind "part-segmenter".
`save_labeller` / `load_labeller`: a `GraphLabellingNet`, its `GraphNetConfig` and the
`PartGraphConfig` of the part graphs it was trained on, kind "hierarchy-gnn".

Both wrap `artic.artifacts.model_file`, which refuses, by name, a file of another kind,
another category or another format. The loaded network is in evaluation mode, on `device`.
`find_segmenter` / `find_labeller`: the model a command was given, or by default the
category's trained one under artifacts/models/; `hierarchy_config`: the `HierarchyConfig`
the loaded models were trained for.
"""

from __future__ import annotations

import re
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from artic.artifacts.model_file import load_model_file, save_model_file
from artic.errors import InputError

if TYPE_CHECKING:
    import torch

    from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig
    from artic.hierarchy.graph import PartGraphConfig
    from artic.hierarchy.infer import HierarchyConfig
    from artic.hierarchy.segmentation import (
        InferenceConfig,
        PartSegmentationNet,
        SegmentationConfig,
    )

SEGMENTER_KIND = "part-segmenter"
LABELLER_KIND = "hierarchy-gnn"
#: the trained models of a category, by default: ROOT/<category>/model.pt
SEGMENTER_ROOT = Path("artifacts/models/segmenter")
LABELLER_ROOT = Path("artifacts/models/hierarchy")
DEFAULT_CATEGORY = "storage_furniture"
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


class LoadedSegmenter(NamedTuple):
    """A trained segmenter (eval mode), how to run it, and the file's meta."""

    model: PartSegmentationNet
    inference: InferenceConfig
    category: str
    meta: dict[str, Any]


class LoadedLabeller(NamedTuple):
    """A trained graph labelling network (eval mode), the part-graph settings it was
    trained with, and the file's meta."""

    model: GraphLabellingNet
    graph: PartGraphConfig
    category: str
    meta: dict[str, Any]


def segmentation_config_to_dict(config: SegmentationConfig) -> dict[str, Any]:
    """JSON-able dict of a SegmentationConfig (tuples become lists)."""
    return asdict(config)


def segmentation_config_from_dict(data: dict[str, Any]) -> SegmentationConfig:
    """Inverse of `segmentation_config_to_dict`; ValueError/KeyError/TypeError if malformed."""
    from artic.hierarchy.pointnet2 import PointNet2Config, SetAbstractionSpec
    from artic.hierarchy.segmentation import SegmentationConfig

    backbone = dict(data["backbone"])
    backbone["set_abstractions"] = tuple(
        SetAbstractionSpec(
            None if s["n_centroids"] is None else int(s["n_centroids"]),
            float(s["radius"]),
            int(s["n_neighbours"]),
            tuple(int(w) for w in s["widths"]),
        )
        for s in backbone["set_abstractions"]
    )
    backbone["propagations"] = tuple(tuple(int(w) for w in p) for p in backbone["propagations"])
    return SegmentationConfig(**{**data, "backbone": PointNet2Config(**backbone)})


def graph_net_config_from_dict(data: dict[str, Any]) -> GraphNetConfig:
    from artic.hierarchy.gnn import GraphNetConfig

    return GraphNetConfig(
        **{**data, "encoder_widths": tuple(int(w) for w in data["encoder_widths"])}
    )


def save_segmenter(
    path: Path,
    category: str,
    model: PartSegmentationNet,
    inference_cfg: InferenceConfig,
    meta: dict[str, Any],
) -> None:
    """Write `model` (weights moved to the CPU) as a "part-segmenter" model file."""
    hparams = {
        "segmentation": segmentation_config_to_dict(model.config),
        "inference": inference_cfg.model_dump(),
    }
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    save_model_file(path, SEGMENTER_KIND, category, hparams, state, meta)


def load_segmenter(
    path: Path, category: str | None = None, device: str | torch.device = "cpu"
) -> LoadedSegmenter:
    """Read a "part-segmenter" model file (of `category` when given); InputError naming
    the file when it is of another kind, category or format, or does not fit."""
    from artic.hierarchy.segmentation import InferenceConfig, PartSegmentationNet

    payload = load_model_file(path, SEGMENTER_KIND, category)
    try:
        config = segmentation_config_from_dict(payload["hparams"]["segmentation"])
        inference = InferenceConfig(**payload["hparams"]["inference"])
        model = PartSegmentationNet(config)
        model.load_state_dict(payload["state_dict"])
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        raise InputError(f"{path}: segmenter does not load ({type(err).__name__}: {err})") from None
    model.to(device).eval()
    return LoadedSegmenter(model, inference, str(payload["category"]), dict(payload["meta"]))


def save_labeller(
    path: Path,
    category: str,
    model: GraphLabellingNet,
    graph_cfg: PartGraphConfig,
    meta: dict[str, Any],
) -> None:
    """Write `model` (weights moved to the CPU) as a "hierarchy-gnn" model file."""
    hparams = {"network": model.cfg.model_dump(), "graph": graph_cfg.model_dump()}
    state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
    save_model_file(path, LABELLER_KIND, category, hparams, state, meta)


def load_labeller(
    path: Path, category: str | None = None, device: str | torch.device = "cpu"
) -> LoadedLabeller:
    """Read a "hierarchy-gnn" model file (of `category` when given); InputError naming
    the file when it is of another kind, category or format, or does not fit."""
    from artic.hierarchy.gnn import GraphLabellingNet
    from artic.hierarchy.graph import PartGraphConfig

    payload = load_model_file(path, LABELLER_KIND, category)
    try:
        network = graph_net_config_from_dict(payload["hparams"]["network"])
        graph = PartGraphConfig(**payload["hparams"]["graph"])
        model = GraphLabellingNet(network)
        model.load_state_dict(payload["state_dict"])
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        raise InputError(f"{path}: labeller does not load ({type(err).__name__}: {err})") from None
    model.to(device).eval()
    return LoadedLabeller(model, graph, str(payload["category"]), dict(payload["meta"]))


def _model_path(model: Path | None, category: str | None, root: Path, what: str) -> Path:
    """`model`, or the category's default model file (InputError when there is none)."""
    if category is not None and not _NAME.match(category):
        raise InputError(f"--category: '{category}' is not a category name")
    name = category or DEFAULT_CATEGORY
    path = model or root / name / "model.pt"
    if model is None and not path.is_file():
        stage = "train-segmenter" if root == SEGMENTER_ROOT else "train-hierarchy"
        raise InputError(
            f"{path}: no {what} for {name}; train one with: artic {stage} category={name}"
        )
    return path


def find_segmenter(model: Path | None, category: str | None) -> tuple[LoadedSegmenter, Path]:
    """The segmenter at `model` (None: SEGMENTER_ROOT/<category>/model.pt, category
    default storage_furniture), checked to be of `category` when given, and its path."""
    path = _model_path(model, category, SEGMENTER_ROOT, "segmenter")
    return load_segmenter(path, category), path


def find_labeller(model: Path | None, category: str | None) -> tuple[LoadedLabeller, Path]:
    """The graph labelling network at `model` (None: LABELLER_ROOT/<category>/model.pt),
    as `find_segmenter`, and its path."""
    path = _model_path(model, category, LABELLER_ROOT, "hierarchy model")
    return load_labeller(path, category), path


def hierarchy_config(
    segmenter: LoadedSegmenter | None, labeller: LoadedLabeller | None, max_points: int
) -> HierarchyConfig:
    """The `HierarchyConfig` the trained models were made for (defaults for the rest)."""
    from artic.hierarchy.infer import HierarchyConfig

    cfg = HierarchyConfig(max_points=max_points)
    if segmenter is not None:
        cfg = HierarchyConfig(segmenter.inference, cfg.graph, cfg.joints, max_points)
    if labeller is not None:
        cfg = HierarchyConfig(cfg.segmentation, labeller.graph, cfg.joints, max_points)
    return cfg
