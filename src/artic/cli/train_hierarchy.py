"""`artic train-hierarchy`: train the graph labelling network of one category (thesis
section 4.4, training as in 4.4.3).

Input: a render-scan folder (`scans=`). Every clean and noisy scan of a training object
(never the withheld test split) becomes a part graph built from its ground-truth part ids
(`artic.hierarchy.graph.build_part_graph`), labelled from the object's tree
(`trees/<id>.json`, `graph_labels`); every `data.val_every`-th training object is held
out for validation. The PointNet node encoder is pre-trained as a point autoencoder
(Chamfer distance, Nesterov SGD), then the GraphLabellingNet trains with Adam.

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
import json
import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.scan_dataset import ScanDataset
from artic.artifacts.timings import data_columns, write_epoch_timings
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.cli.train_mdn import training_device
from artic.cli.train_segmenter import CategoryRef, DataConfig, training_objects
from artic.config.schemas import TRAIN_THREADS_HELP, Strict, TrainingStageConfig
from artic.errors import InputError

if TYPE_CHECKING:
    from artic.hierarchy.fit_labeller import LabelledGraph

KIND = "hierarchy-gnn"
MODEL = "model.pt"
METRICS = "metrics.csv"
PRETRAIN_METRICS = "pretrain.csv"
log = logging.getLogger("artic")


class GraphSection(Strict):
    """Part-graph construction (section 4.4.1); saved with the model for inference."""

    contact_threshold: float = Field(0.05, gt=0, description="metres; closer parts get an edge")
    points_per_node: int = Field(128, gt=0, description="points per part for the PointNet")


class NetworkSection(Strict):
    encoder_widths: tuple[int, ...] = Field((32, 64, 128), min_length=1)
    decoder_points: int = Field(128, gt=0, description="points the autoencoder emits")
    hidden: int = Field(64, gt=0, description="GraphSAGE width")
    head_hidden: int = Field(64, gt=0, description="hidden width of the MLP heads")
    num_layers: int = Field(3, gt=0, description="convolution + edge pooling levels (3)")


class PretrainSection(Strict):
    epochs: int = Field(500, ge=0, description="autoencoder epochs (4.4.3: 500; 0: none)")
    batch_size: int = Field(64, gt=0, description="part point sets per step")
    lr: float = Field(1e-3, gt=0, description="Nesterov SGD (4.4.3: 1e-3)")
    momentum: float = Field(0.9, gt=0, lt=1)
    max_sets: int | None = Field(
        None, gt=0, description="a seeded subset of at most N part point sets (null: all)"
    )


class TrainSection(Strict):
    epochs: int = Field(30, gt=0, description="4.4.3: 30")
    batch_size: int = Field(16, gt=0, description="graphs per step")
    lr: float = Field(1e-3, gt=0, description="Adam (4.4.3: 1e-3)")
    weight_decay: float = Field(0.0, ge=0)
    patience: int = Field(10, gt=0, description="epochs without a better val loss")
    device: Literal["auto", "cpu", "cuda"] = "auto"
    threads: int = Field(2, ge=1, description=TRAIN_THREADS_HELP)


class TrainHierarchyConfig(TrainingStageConfig):
    category: CategoryRef
    scans: str = Field(description="a render-scan output folder of the category")
    graph: GraphSection
    model: NetworkSection
    data: DataConfig
    pretrain: PretrainSection
    train: TrainSection


def _plan(cfg: TrainHierarchyConfig, inputs: dict[str, Path]) -> Plan:
    ScanDataset.open_category(inputs["scans"], cfg.category.name)
    return Plan([cfg.pretrain.epochs + cfg.train.epochs], "epochs")


def load_examples(
    ds: ScanDataset, objects: list[int], cfg: TrainHierarchyConfig
) -> tuple[list[LabelledGraph], int]:
    """Labelled part graphs of the training clouds of `objects`, and the number of clouds
    skipped (fewer than two parts, or the root hidden)."""
    import numpy as np

    from artic.hierarchy.fit_labeller import make_example
    from artic.hierarchy.graph import PartGraphConfig

    graph_cfg = PartGraphConfig(**cfg.graph.model_dump())
    rows = ds.select("train", cfg.data.kinds, objects)
    if cfg.data.max_poses is not None:
        rows = [r for r in rows if r.pose < cfg.data.max_poses]
    trees = {o: ds.tree(o) for o in objects}
    examples, skipped = [], 0
    for row in rows:
        cloud = ds.cloud(row)
        assert cloud.part_id is not None
        rng = np.random.default_rng([cfg.seed, row.object_id, row.pose, row.kind == "noisy"])
        example = make_example(cloud.points, cloud.part_id, trees[row.object_id], rng, graph_cfg)
        if example is None:
            skipped += 1
        else:
            examples.append(example)
    if not examples:
        raise InputError(f"scans: {ds.root} has no usable clouds of objects {objects[:5]}...")
    return examples, skipped


def _cached(
    ds: ScanDataset, objects: list[int], cfg: TrainHierarchyConfig, cache: Path
) -> tuple[list[LabelledGraph], int]:
    """`load_examples`, stored in the resume folder (specific to the config and input
    hashes) on first use: a torch file of tensors and plain data (`_encode`), read with
    `weights_only=True`; a corrupt one is an InputError naming it."""
    from artic.artifacts.model_file import load_torch_file, save_torch_file
    from artic.hierarchy.fit_labeller import LabelledGraph

    if cache.is_file():
        stored = load_torch_file(cache, "checkpoint")
        try:
            examples = [LabelledGraph(*(_decode(v) for v in e)) for e in stored["examples"]]
            return examples, int(stored["skipped"])
        except (KeyError, TypeError, ValueError) as err:
            raise InputError(f"{cache}: not a readable checkpoint ({err})") from None
    examples, skipped = load_examples(ds, objects, cfg)
    save_torch_file(cache, {"examples": [[_encode(v) for v in e] for e in examples],
                            "skipped": skipped})  # fmt: skip
    return examples, skipped


def _encode(value: Any) -> Any:
    """A training example's parts (dataclasses of numpy arrays and scalars, tuples) as
    tensors and plain data that `_decode` turns back into equal objects of the same types
    (arrays keep their dtype, numpy scalars stay numpy scalars)."""
    import numpy as np
    import torch

    if isinstance(value, np.ndarray | np.generic):
        return {"numpy": torch.from_numpy(np.array(value)), "scalar": isinstance(value, np.generic)}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: _encode(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {"dataclass": type(value).__name__, "fields": fields}
    if type(value) in (tuple, list):
        return type(value)(_encode(v) for v in value)
    return value


def _decode(value: Any) -> Any:
    from artic.hierarchy import types

    if isinstance(value, dict) and "numpy" in value:
        array = value["numpy"].numpy()
        return array[()] if value["scalar"] else array
    if isinstance(value, dict) and "dataclass" in value:
        known = (types.PartGraph, types.GraphLabels, types.KinematicTree, types.JointAxis)
        cls: Any = {c.__name__: c for c in known}[value["dataclass"]]
        return cls(**{k: _decode(v) for k, v in value["fields"].items()})
    if type(value) in (tuple, list):
        return type(value)(_decode(v) for v in value)
    return value


def train_chunk(cfg: TrainHierarchyConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Pre-training and training; writes model.pt, metrics and model.json into tmp."""
    import numpy as np
    import torch

    from artic.artifacts.model_file import load_torch_file, save_torch_file
    from artic.hierarchy.fit_labeller import (
        LabellerFitConfig,
        LabellerFitState,
        autoencoder_chamfer,
        fit_labeller,
        part_point_sets,
        pretrain_autoencoder,
        score_labeller,
    )
    from artic.hierarchy.gnn import GraphLabellingNet, GraphNetConfig, PointAutoencoder
    from artic.hierarchy.graph import PartGraphConfig
    from artic.hierarchy.models import save_labeller

    torch.set_num_threads(cfg.train.threads)
    device = training_device(cfg.train.device)
    ds = ScanDataset.open_category(inputs["scans"], cfg.category.name)
    split = training_objects(ds, cfg.data)
    resume = WorkDir(Path(cfg.out)).resume_dir("train-hierarchy")
    train, skipped_train = _cached(ds, split.train, cfg, resume / "train.pt")
    val, skipped_val = _cached(ds, split.val, cfg, resume / "val.pt")
    log.info("train-hierarchy: %d training and %d validation graphs", len(train), len(val))

    m, p, t = cfg.model, cfg.pretrain, cfg.train
    net_cfg = GraphNetConfig(
        m.encoder_widths, m.decoder_points, m.hidden, m.head_hidden, m.num_layers
    )
    torch.manual_seed(cfg.seed)
    autoencoder = PointAutoencoder(net_cfg.encoder_widths, net_cfg.decoder_points).to(device)
    ae_optimizer = torch.optim.SGD(
        autoencoder.parameters(), lr=p.lr, momentum=p.momentum, nesterov=True
    )
    model = GraphLabellingNet(net_cfg, encoder=autoencoder.encoder).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    last = resume / "last.pt"
    state = LabellerFitState()
    if last.is_file():  # weights_only; a corrupt checkpoint is an InputError naming it
        saved = load_torch_file(last, "checkpoint", map_location=device)
        autoencoder.load_state_dict(saved["autoencoder"])  # shares the encoder with model
        model.load_state_dict(saved["model"])
        ae_optimizer.load_state_dict(saved["ae_optimizer"])
        optimizer.load_state_dict(saved["optimizer"])
        state = LabellerFitState.from_dict(saved["state"])

    def checkpoint(s: LabellerFitState) -> None:
        payload = {
            "autoencoder": autoencoder.state_dict(), "model": model.state_dict(),
            "ae_optimizer": ae_optimizer.state_dict(), "optimizer": optimizer.state_dict(),
        }  # fmt: skip
        save_torch_file(last, {**payload, "state": s.to_dict()})

    fit_cfg = LabellerFitConfig(
        p.epochs, p.batch_size, p.lr, p.momentum, t.epochs, t.batch_size, t.lr,
        t.weight_decay, t.patience, cfg.seed,
    )  # fmt: skip
    parts = part_point_sets(train)
    if p.max_sets is not None and len(parts) > p.max_sets:
        chosen = np.random.default_rng([cfg.seed, 0]).choice(len(parts), p.max_sets, replace=False)
        parts = parts[torch.from_numpy(np.sort(chosen))]
    state = pretrain_autoencoder(
        autoencoder, ae_optimizer, parts, fit_cfg, state, device, checkpoint
    )
    val_chamfer = autoencoder_chamfer(autoencoder, part_point_sets(val), p.batch_size, device)
    state = fit_labeller(model, optimizer, train, val, fit_cfg, state, device, checkpoint)
    assert state.best_weights is not None
    model.load_state_dict(state.best_weights)
    scores = score_labeller(model, val)
    graph_cfg = PartGraphConfig(**cfg.graph.model_dump())
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
        "pretrain_sets": len(parts),
        "val_chamfer": val_chamfer,
        "best_epoch": state.best_epoch,
        "best_val_loss": state.best_val,
        "val_metrics_gt_segmentation": dataclasses.asdict(scores),
    }
    save_labeller(tmp / MODEL, cfg.category.name, model, graph_cfg, meta)
    columns = data_columns(state.history, ["epoch"])
    write_csv(tmp / METRICS, columns, [[h[c] for c in columns] for h in state.history])
    write_csv(
        tmp / PRETRAIN_METRICS,
        ["epoch", "chamfer"],
        [[h[c] for c in ("epoch", "chamfer")] for h in state.pretrain_history],
    )
    write_epoch_timings(tmp, {"pretrain": state.pretrain_history, "train": state.history})
    info = {k: v for k, v in meta.items() if not k.endswith("_objects")}
    write_json(tmp / "model.json", info | {
        "network": dataclasses.asdict(net_cfg), "graph": cfg.graph.model_dump(),
        "device": str(device), "epochs_run": state.epoch, "stopped_early": state.stopped_early,
        "n_train_objects": len(split.train), "n_val_objects": len(split.val),
    })  # fmt: skip
    return state.pretrain_epoch + state.epoch


def _finalize(
    cfg: TrainHierarchyConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = json.loads((work / "model.json").read_text())
    s = info["val_metrics_gt_segmentation"]
    card = [
        f"# Graph labelling network for {cfg.category.name}",
        "",
        "Section 4.4: PointNet node encoder (pre-trained as an autoencoder), "
        f"{cfg.model.num_layers} GraphSAGE layers with edge-collapse pooling, width "
        f"{cfg.model.hidden}; heads for motion type, edge existence, direction and root. "
        f"Part graphs: contact threshold {cfg.graph.contact_threshold} m, "
        f"{cfg.graph.points_per_node} points per part.",
        "",
        f"- data: `{info['data']['path']}` (content hash `{info['data']['content_hash'][:16]}`),"
        f" clouds: {', '.join(info['kinds'])}, ground-truth part ids",
        f"- objects: {info['n_train_objects']} train, {info['n_val_objects']} validation "
        "(held out from the training split; the test split is never used)",
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
        "- config: see manifest.json; per-epoch metrics: metrics.csv, pretrain.csv; "
        "test-set scores: `artic evaluate hierarchy`",
        "",
    ]
    (work / "model_card.md").write_text("\n".join(card))
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
    conf="train_hierarchy",
    schema=TrainHierarchyConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    inputs={"scans": "render-scan"},
    input_paths=lambda cfg: {"scans": Path(cfg.scans)},
)
