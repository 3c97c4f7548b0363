"""`artic train-hierarchy`: train the graph labelling network of one category (thesis
section 4.4, training as in 4.4.3).

Input: a render-scan folder (`scans=`). Every clean and noisy scan of a training object
(never the withheld test split) becomes a part graph built from its ground-truth part ids
(`artic.hierarchy.graph.build_part_graph`), labelled from the object's tree
(`trees/<id>.json`, `graph_labels`); every `data.val_every`-th training object is held
out for validation. With `segmenter=` (a train-segmenter folder), every cloud also becomes
the part graph of that segmenter's parts, labelled from the true tree
(`fit_labeller.predicted_parts_tree`), so the network learns trees over over- and
under-segmented parts as it will meet them. The PointNet node encoder is pre-trained as a
point autoencoder (Chamfer distance, Nesterov SGD), then the GraphLabellingNet trains with
Adam.

One chunk: the whole run, checkpointed after every epoch of either phase in the work
area's resume folder (with the prepared graphs, as tensors and plain data: no pickles),
so an interrupted run resumes with the same result; both are read with
`weights_only=True`, and a corrupt one is an InputError naming it. Outputs: `model.pt`
(kind "hierarchy-gnn", best validation loss weights,
`artic.hierarchy.models.load_labeller`), `metrics.csv` (one row per epoch),
`pretrain.csv`, `model.json` and `model_card.md` (validation Table 4.2 metrics with
ground-truth segmentation).
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import Field

from artic.artifacts.formats import write_json
from artic.artifacts.model_card import read_model_info, write_model_card
from artic.artifacts.scan_dataset import ScanDataset
from artic.artifacts.timings import write_epoch_timings, write_history
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import TrainingStageConfig
from artic.hierarchy.config import (
    CategoryName,
    CloudDataConfig,
    GraphNetConfig,
    LabellerTrainConfig,
    PartGraphConfig,
    PretrainConfig,
)

if TYPE_CHECKING:
    from artic.hierarchy.fit_labeller import LabelledGraph

MODEL = "model.pt"
METRICS = "metrics.csv"
PRETRAIN_METRICS = "pretrain.csv"
log = logging.getLogger("artic")


class TrainHierarchyConfig(TrainingStageConfig):
    category: CategoryName
    scans: str = Field(description="a render-scan output folder of the category")
    segmenter: str | None = Field(
        None, description="a train-segmenter folder: its parts of every cloud are examples too"
    )
    graph: PartGraphConfig
    model: GraphNetConfig
    data: CloudDataConfig
    pretrain: PretrainConfig
    train: LabellerTrainConfig


def _plan(cfg: TrainHierarchyConfig, inputs: dict[str, Path]) -> Plan:
    ScanDataset.open_category(inputs["scans"], cfg.category.name)
    return Plan([cfg.pretrain.epochs + cfg.train.epochs], "epochs")


def _cached(
    ds: ScanDataset, objects: list[int], cfg: TrainHierarchyConfig, cache: Path
) -> tuple[list[LabelledGraph], int]:
    """`load_examples`, stored in the resume folder on first use as tensors and plain
    data (`fit_labeller.encode`)."""
    from artic.artifacts.resume import cached_torch
    from artic.hierarchy.fit_labeller import LabelledGraph, decode, encode, load_examples

    segment_cloud = None
    if cfg.segmenter is not None:
        from artic.hierarchy.models import load_segmenter
        from artic.hierarchy.segmentation import segment

        loaded = load_segmenter(Path(cfg.segmenter) / MODEL, cfg.category.name)

        def segment_cloud(points: Any) -> Any:
            return segment(loaded.model, points, loaded.inference).part_id

    return cached_torch(
        cache,
        lambda: load_examples(ds, objects, cfg.data, cfg.graph, cfg.seed, segment_cloud),
        lambda v: {"examples": [[encode(x) for x in e] for e in v[0]], "skipped": v[1]},
        lambda s: ([LabelledGraph(*(decode(x) for x in e)) for e in s["examples"]],
                   int(s["skipped"])),
    )  # fmt: skip


def train_chunk(cfg: TrainHierarchyConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Pre-training and training; writes model.pt, metrics and model.json into tmp."""
    import numpy as np
    import torch

    from artic.artifacts.resume import torch_checkpoint
    from artic.hierarchy.fit_labeller import (
        LabellerFitState,
        autoencoder_chamfer,
        fit_labeller,
        part_point_sets,
        pretrain_autoencoder,
        score_labeller,
    )
    from artic.hierarchy.fit_segmenter import training_objects
    from artic.hierarchy.gnn import GraphLabellingNet, PointAutoencoder
    from artic.hierarchy.models import save_labeller
    from artic.learning import trainer

    m, p, t = cfg.model, cfg.pretrain, cfg.train
    device = trainer.start_training(t)
    ds = ScanDataset.open_category(inputs["scans"], cfg.category.name)
    split = training_objects(ds, cfg.data)
    resume = WorkDir(Path(cfg.out)).resume_dir("train-hierarchy")
    train, skipped_train = _cached(ds, split.train, cfg, resume / "train.pt")
    val, skipped_val = _cached(ds, split.val, cfg, resume / "val.pt")
    log.info("train-hierarchy: %d training and %d validation graphs", len(train), len(val))

    torch.manual_seed(cfg.seed)
    part_frame = m.node_frame == "part"
    autoencoder = PointAutoencoder(m.encoder_widths, m.decoder_points, part_frame).to(device)
    ae_optimizer = torch.optim.SGD(
        autoencoder.parameters(), lr=p.lr, momentum=p.momentum, nesterov=True
    )
    model = GraphLabellingNet(m, encoder=autoencoder.encoder).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    # the autoencoder shares its encoder with the model
    parts = {"autoencoder": autoencoder, "model": model, "ae_optimizer": ae_optimizer,
             "optimizer": optimizer}  # fmt: skip
    saved, save = torch_checkpoint(resume / "last.pt", map_location=device)
    state = trainer.restore(parts, saved, LabellerFitState)

    def checkpoint(s: LabellerFitState) -> None:
        save(trainer.checkpoint(parts, s))

    sets = part_point_sets(train)
    if p.max_sets is not None and len(sets) > p.max_sets:
        chosen = np.random.default_rng([cfg.seed, 0]).choice(len(sets), p.max_sets, replace=False)
        sets = sets[torch.from_numpy(np.sort(chosen))]
    state = pretrain_autoencoder(
        autoencoder, ae_optimizer, sets, p, cfg.seed, state, device, checkpoint
    )
    val_chamfer = autoencoder_chamfer(autoencoder, part_point_sets(val), p.batch_size, device)
    state = fit_labeller(model, optimizer, train, val, t, cfg.seed, state, device, checkpoint)
    assert state.best_weights is not None
    model.load_state_dict(state.best_weights)
    scores = score_labeller(model, val)
    uncovered = sum(len(e.labels.uncovered) for e in train)
    meta: dict[str, Any] = {
        "data": {"path": str(inputs["scans"]), "content_hash": ds.manifest.content_hash},
        "kinds": list(cfg.data.kinds),
        "train_objects": split.train,
        "val_objects": split.val,
        "train_graphs": len(train),
        "val_graphs": len(val),
        "skipped_clouds": skipped_train + skipped_val,
        "uncovered_tree_edges": uncovered,
        "tree_edges": sum(len(e.tree.edges) for e in train),
        "pretrain_epochs": state.pretrain_epoch,
        "pretrain_sets": len(sets),
        "val_chamfer": val_chamfer,
        "best_epoch": state.best_epoch,
        "best_val_loss": state.best_val,
        "val_metrics_gt_segmentation": dataclasses.asdict(scores),
    }
    save_labeller(tmp / MODEL, cfg.category.name, model, cfg.graph, meta)
    write_history(tmp / METRICS, state.history)
    write_history(tmp / PRETRAIN_METRICS, state.pretrain_history, ["epoch", "chamfer"])
    write_epoch_timings(tmp, {"pretrain": state.pretrain_history, "train": state.history})
    info = {k: v for k, v in meta.items() if not k.endswith("_objects")}
    write_json(tmp / "model.json", info | {
        "network": m.model_dump(), "graph": cfg.graph.model_dump(),
        "device": str(device), "epochs_run": state.epoch, "stopped_early": state.stopped_early,
        "n_train_objects": len(split.train), "n_val_objects": len(split.val),
    })  # fmt: skip
    return state.pretrain_epoch + state.epoch


def _finalize(
    cfg: TrainHierarchyConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = read_model_info(work)
    s = info["val_metrics_gt_segmentation"]
    about = ("Section 4.4: PointNet node encoder (pre-trained as an autoencoder), "
             f"{cfg.model.num_layers} GraphSAGE layers with edge-collapse pooling, width "
             f"{cfg.model.hidden}; heads for motion type, edge existence, direction and root. "
             f"Part graphs: contact threshold {cfg.graph.contact_threshold} m, "
             f"{cfg.graph.points_per_node} points per part.")  # fmt: skip
    write_model_card(work, f"Graph labelling network for {cfg.category.name}", about, info, [
        f"- graphs: {info['train_graphs']} train, {info['val_graphs']} validation, "
        f"{info['skipped_clouds']} clouds skipped; {info['uncovered_tree_edges']} of "
        f"{info['tree_edges']} training tree edges are not candidate edges",
        f"- pre-training: {info['pretrain_epochs']} epochs, validation Chamfer "
        f"{info['val_chamfer']:.5f} (normalised units)",
        f"- training: {info['epochs_run']} epochs (best {info['best_epoch']}, early stop: "
        f"{info['stopped_early']}), device {info['device']}; best validation loss "
        f"{info['best_val_loss']:.4f}",
        f"- validation, ground-truth segmentation (Table 4.2, %): E_type {s['e_type']:.2f}, "
        f"E_exist {s['e_exist']:.2f}, E_dir {s['e_dir']:.2f}, E_root {s['e_root']:.2f}, "
        f"Tree F1 {s['tree_f1']:.2f} over {s['models']} graphs",
    ], "metrics.csv, pretrain.csv; test-set scores: `artic evaluate hierarchy`",
       f", clouds: {', '.join(info['kinds'])}, ground-truth part ids")  # fmt: skip
    return {
        "category": cfg.category.name,
        "train graphs": info["train_graphs"],
        "val graphs": info["val_graphs"],
        "epochs run": info["epochs_run"],
        "best val loss": round(float(info["best_val_loss"]), 4),
        "val Tree F1 (GT seg.)": round(float(s["tree_f1"]), 2),
        "val E_type / E_exist / E_dir / E_root": " / ".join(
            f"{s[k]:.1f}" for k in ("e_type", "e_exist", "e_dir", "e_root")
        ),
        "device": info["device"],
    }


STAGE: Stage[TrainHierarchyConfig] = Stage(
    name="train-hierarchy",
    help=(
        "Train the graph labelling network of one category on its scans (section 4.4).\n\n"
        "Example: artic train-hierarchy category=storage_furniture"
    ),
    conf="train_hierarchy",
    schema=TrainHierarchyConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"scans": "render-scan", "segmenter": "train-segmenter"},
    input_paths=lambda cfg: (
        {"scans": Path(cfg.scans)}
        | ({} if cfg.segmenter is None else {"segmenter": Path(cfg.segmenter)})
    ),
)
