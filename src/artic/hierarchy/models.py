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
category's model as the model store chooses it (trained here under artifacts/models/,
else shipped); `hierarchy_config`: the `HierarchyConfig`
the loaded models were trained for.
"""

from __future__ import annotations

import re
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from artic.artifacts.model_file import load_model_file, save_model_file
from artic.artifacts.model_store import ModelChoice, choose_model
from artic.errors import InputError

if TYPE_CHECKING:
    import torch

    from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig, Labeller
    from artic.hierarchy.graph import PartGraphConfig
    from artic.hierarchy.infer import HierarchyConfig
    from artic.hierarchy.segmentation import (
        InferenceConfig,
        PartSegmentationNet,
        SegmentationConfig,
    )

SEGMENTER_KIND = "part-segmenter"
LABELLER_KIND = "hierarchy-gnn"
DEFAULT_CATEGORY = "storage_furniture"
_NAME = re.compile(r"^[a-z][a-z0-9_]*$")


class LoadedSegmenter(NamedTuple):
    """A trained segmenter (eval mode), how to run it, and the file's meta."""

    model: PartSegmentationNet
    inference: InferenceConfig
    category: str
    meta: dict[str, Any]


class LoadedLabeller(NamedTuple):
    """A trained graph labelling network (eval mode; compiled or eager), the part-graph
    settings it was trained with, and the file's meta."""

    model: Labeller
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
    path: Path,
    category: str | None = None,
    device: str | torch.device = "cpu",
    compiled: bool = True,
) -> LoadedLabeller:
    """Read a "hierarchy-gnn" model file (of `category` when given); InputError naming
    the file when it is of another kind, category or format, or does not fit. `compiled`:
    the network as its compiled program (`hierarchy.compiled`: no PyG import once the
    program is cached; the same outputs), else the eager `GraphLabellingNet`."""
    from artic.hierarchy.graph import PartGraphConfig

    payload = load_model_file(path, LABELLER_KIND, category)
    try:
        network = graph_net_config_from_dict(payload["hparams"]["network"])
        graph = PartGraphConfig(**payload["hparams"]["graph"])
    except (KeyError, TypeError, ValueError) as err:
        raise InputError(f"{path}: labeller does not load ({type(err).__name__}: {err})") from None

    def build() -> GraphLabellingNet:
        from artic.hierarchy.gnn import GraphLabellingNet

        try:
            model = GraphLabellingNet(network)
            model.load_state_dict(payload["state_dict"])
        except (KeyError, TypeError, ValueError, RuntimeError) as err:
            raise InputError(
                f"{path}: labeller does not load ({type(err).__name__}: {err})"
            ) from None
        return model.eval()

    if compiled:
        from artic.hierarchy.compiled import load_program

        labeller: Labeller = load_program(path, build, device)
    else:
        labeller = build().to(device)
    return LoadedLabeller(labeller, graph, str(payload["category"]), dict(payload["meta"]))


def _choose(model: Path | None, category: str | None, kind: str, option: str) -> ModelChoice:
    """`model`, or the category's model as the store chooses it (local, else shipped:
    `artifacts.model_store.choose_model`); InputError when there is none."""
    if category is not None and not _NAME.match(category):
        raise InputError(f"--category: '{category}' is not a category name")
    return choose_model(kind, category or DEFAULT_CATEGORY, model, option)


def find_segmenter(
    model: Path | None, category: str | None, option: str = "--segmenter"
) -> tuple[LoadedSegmenter, ModelChoice]:
    """The segmenter at `model` (None: the store's choice for `category`, default
    storage_furniture), checked to be of `category` when given, and where it came from."""
    choice = _choose(model, category, "segmenter", option)
    return load_segmenter(choice.path, category), choice


def find_labeller(
    model: Path | None, category: str | None, option: str = "--labeller"
) -> tuple[LoadedLabeller, ModelChoice]:
    """The graph labelling network at `model` (None: the store's choice), as
    `find_segmenter`."""
    choice = _choose(model, category, "hierarchy", option)
    return load_labeller(choice.path, category), choice


def hierarchy_config(
    segmenter: LoadedSegmenter | None, labeller: LoadedLabeller | None, max_points: int
) -> HierarchyConfig:
    """The `HierarchyConfig` the trained models were made for, with their category's yaw
    step (`canonical.yaw_config`); defaults for the rest."""
    from artic.hierarchy.canonical import yaw_config
    from artic.hierarchy.infer import HierarchyConfig

    cfg = HierarchyConfig(max_points=max_points)
    if segmenter is not None:
        cfg = replace(cfg, segmentation=segmenter.inference)
    if labeller is not None:
        cfg = replace(cfg, graph=labeller.graph)
    model = segmenter or labeller
    return cfg if model is None else replace(cfg, yaw_settings=yaw_config(model.category))
