"""`artic train-segmenter`: train the part segmenter of one category (thesis section 4.3).

Input: a render-scan folder (`scans=`). Training clouds: the clean and noisy scans of the
training objects (never the withheld test split), every `data.val_every`-th training
object held out for validation. Each cloud is downsampled to `inference.n_points` by
farthest-point sampling, as `segment` does at inference.

One chunk: the whole training run. The prepared clouds and a checkpoint after every epoch
live in the work area's resume folder, so an interrupted run continues from its last
finished epoch with the same result (the checkpoint is read with `weights_only=True`; a
corrupt one is an InputError naming it, never silently discarded). Outputs: `model.pt`
(kind "part-segmenter", best validation loss weights,
`artic.hierarchy.models.load_segmenter`), `metrics.csv` (one row per epoch), `model.json`
and `model_card.md` (validation mAP@0.5, clean and noisy).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field

from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.scan_dataset import ObjectSplit, ScanDataset, split_train_objects
from artic.artifacts.timings import data_columns, write_epoch_timings
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.cli.train_mdn import training_device
from artic.config.schemas import TRAIN_THREADS_HELP, Strict, TrainingStageConfig
from artic.errors import InputError

if TYPE_CHECKING:
    from artic.hierarchy.fit_segmenter import SegmentationData
    from artic.hierarchy.segmentation import InferenceConfig, SegmentationConfig

KIND = "part-segmenter"
MODEL = "model.pt"
METRICS = "metrics.csv"
log = logging.getLogger("artic")


class CategoryRef(Strict):
    """The category config group; the training stages need only its name."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str


class ModelConfig(Strict):
    """Architecture: the PointNet++ SSG backbone of PartNet, optionally narrower/lighter."""

    width: float = Field(1.0, gt=0, description="every layer width times this")
    n_masks: int = Field(24, gt=0, description="N instance masks (section 4.3: 24)")
    norm: Literal["batch", "layer"] = Field("batch", description="normalisation in the MLPs")
    centroids: tuple[int, int] = Field((512, 128), description="FPS centroids, levels 1 and 2")
    neighbours: tuple[int, int] = Field((32, 64), description="ball query size, levels 1 and 2")
    radii: tuple[float, float] = Field((0.2, 0.4), description="ball radii (unit-sphere units)")

    def network(self) -> SegmentationConfig:
        from artic.hierarchy.segmentation import SegmentationConfig

        base = SegmentationConfig(n_masks=self.n_masks).scaled(self.width)
        levels = list(base.backbone.set_abstractions)
        for i in range(2):
            levels[i] = dataclasses.replace(
                levels[i],
                n_centroids=self.centroids[i],
                n_neighbours=self.neighbours[i],
                radius=self.radii[i],
            )
        backbone = dataclasses.replace(
            base.backbone, set_abstractions=tuple(levels), norm=self.norm
        )
        return dataclasses.replace(base, backbone=backbone)


class InferenceSection(Strict):
    """Saved with the model; `segment` uses it (see InferenceConfig)."""

    n_points: int = Field(2048, gt=1, description="network input size (FPS downsampling)")
    min_points: int = Field(8, ge=0, description="smaller masks are merged away")
    min_fraction: float = Field(0.005, ge=0, lt=1, description="... or smaller than this fraction")
    min_confidence: float = Field(0.1, ge=0, le=1, description="... or less confident")

    def config(self) -> InferenceConfig:
        from artic.hierarchy.segmentation import InferenceConfig

        return InferenceConfig(**self.model_dump())


class DataConfig(Strict):
    kinds: tuple[Literal["clean", "noisy"], ...] = Field(
        ("clean", "noisy"), min_length=1, description="which clouds to train on"
    )
    val_every: int = Field(10, ge=2, description="every Nth training object validates")
    max_train_objects: int | None = Field(None, gt=0, description="first N training objects")
    max_poses: int | None = Field(None, gt=0, description="first N poses per object")


def training_objects(ds: ScanDataset, data: DataConfig) -> ObjectSplit:
    """The scan folder's training objects (the first `data.max_train_objects`) split by
    object into training and validation; InputError when either side is empty."""
    train_ids = ds.object_ids("train")[: data.max_train_objects]
    split = split_train_objects(train_ids, data.val_every)
    if not split.train or not split.val:
        raise InputError(
            f"scans: {ds.root} has {len(train_ids)} training objects; with "
            f"data.val_every={data.val_every} that leaves {len(split.train)} to train "
            f"on and {len(split.val)} to validate on; scan more objects"
        )
    return split


class AugmentSection(Strict):
    rotate_z_deg: float = Field(0.0, ge=0, le=180, description="random rotation about z, +-deg")
    jitter_m: float = Field(0.0, ge=0, description="per-point Gaussian noise std, metres")


class TrainConfig(Strict):
    epochs: int = Field(100, gt=0)
    batch_size: int = Field(8, ge=2, description="clouds per step (BatchNorm needs >= 2)")
    lr: float = Field(1e-4, gt=0, description="Adam (section 4.3: 1e-4)")
    weight_decay: float = Field(0.0, ge=0)
    patience: int = Field(10, gt=0, description="epochs without a better val loss")
    device: Literal["auto", "cpu", "cuda"] = "auto"
    threads: int = Field(2, ge=1, description=TRAIN_THREADS_HELP)


class TrainSegmenterConfig(TrainingStageConfig):
    category: CategoryRef
    scans: str = Field(description="a render-scan output folder of the category")
    model: ModelConfig
    inference: InferenceSection
    data: DataConfig
    augment: AugmentSection
    train: TrainConfig


def _plan(cfg: TrainSegmenterConfig, inputs: dict[str, Path]) -> Plan:
    ScanDataset.open_category(inputs["scans"], cfg.category.name)
    return Plan([cfg.train.epochs], "epochs")


def load_clouds(
    ds: ScanDataset, objects: list[int], cfg: TrainSegmenterConfig
) -> tuple[SegmentationData, int]:
    """The prepared clouds of `objects` (kinds and poses per `cfg.data`) and the number
    of clouds skipped for having more parts than masks."""
    import numpy as np

    from artic.hierarchy.fit_segmenter import SegmentationData, prepare_cloud

    rows = ds.select("train", cfg.data.kinds, objects)
    if cfg.data.max_poses is not None:
        rows = [r for r in rows if r.pose < cfg.data.max_poses]
    clouds, ids, noisy, skipped = [], [], [], 0
    for row in rows:
        cloud = ds.cloud(row)
        assert cloud.part_id is not None and cloud.motion_type is not None
        if len(np.unique(cloud.part_id[cloud.part_id >= 0])) > cfg.model.n_masks:
            skipped += 1
            continue
        rng = np.random.default_rng([cfg.seed, row.object_id, row.pose, row.kind == "noisy"])
        n = cfg.inference.n_points
        clouds.append(prepare_cloud(cloud.points, cloud.part_id, cloud.motion_type, n, rng))
        ids.append(row.object_id)
        noisy.append(row.kind == "noisy")
    if not clouds:
        raise InputError(f"scans: {ds.root} has no usable clouds of objects {objects[:5]}...")
    return SegmentationData.stack(clouds, ids, noisy), skipped


def _cached_data(
    ds: ScanDataset, objects: list[int], cfg: TrainSegmenterConfig, cache: Path
) -> tuple[SegmentationData, int]:
    """`load_clouds`, stored in the resume folder on first use (the work area is specific
    to the config and input hashes, so the cache cannot be stale)."""
    import numpy as np

    from artic.hierarchy.fit_segmenter import SegmentationData

    names = [f.name for f in dataclasses.fields(SegmentationData)]
    if cache.is_file():
        with np.load(cache) as z:
            return SegmentationData(**{k: z[k] for k in names}), int(z["skipped"])
    data, skipped = load_clouds(ds, objects, cfg)
    tmp = cache.with_name(cache.name + ".tmp.npz")
    np.savez(tmp, skipped=skipped, **{k: getattr(data, k) for k in names})
    os.replace(tmp, cache)
    return data, skipped


def train_chunk(cfg: TrainSegmenterConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """The training run; writes model.pt, metrics.csv and model.json into tmp."""
    import torch

    from artic.artifacts.model_file import load_torch_file, save_torch_file
    from artic.hierarchy.fit_segmenter import (
        AugmentConfig,
        FitState,
        SegmenterFitConfig,
        fit_segmenter,
        score_segmenter,
    )
    from artic.hierarchy.models import save_segmenter
    from artic.hierarchy.segmentation import PartSegmentationNet

    torch.set_num_threads(cfg.train.threads)
    device = training_device(cfg.train.device)
    ds = ScanDataset.open_category(inputs["scans"], cfg.category.name)
    split = training_objects(ds, cfg.data)
    resume = WorkDir(Path(cfg.out)).resume_dir("train-segmenter")
    train, skipped_train = _cached_data(ds, split.train, cfg, resume / "train.npz")
    val, skipped_val = _cached_data(ds, split.val, cfg, resume / "val.npz")
    log.info("train-segmenter: %d training and %d validation clouds", len(train), len(val))

    torch.manual_seed(cfg.seed)
    model = PartSegmentationNet(cfg.model.network()).to(device)
    t = cfg.train
    optimizer = torch.optim.Adam(model.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    last = resume / "last.pt"
    state = FitState()
    if last.is_file():  # weights_only; a corrupt checkpoint is an InputError naming it
        saved = load_torch_file(last, "checkpoint", map_location=device)
        model.load_state_dict(saved["model"])
        optimizer.load_state_dict(saved["optimizer"])
        state = FitState.from_dict(saved["state"])

    def checkpoint(s: FitState) -> None:
        payload = {"model": model.state_dict(), "optimizer": optimizer.state_dict()}
        save_torch_file(last, {**payload, "state": s.to_dict()})

    augment = AugmentConfig(cfg.augment.rotate_z_deg, cfg.augment.jitter_m)
    fit_cfg = SegmenterFitConfig(
        t.epochs, t.batch_size, t.lr, t.weight_decay, t.patience, cfg.seed, augment
    )
    state = fit_segmenter(model, optimizer, train, val, fit_cfg, state, device, checkpoint)
    assert state.best_weights is not None
    model.load_state_dict(state.best_weights)
    inference = cfg.inference.config()
    scores = score_segmenter(model, val, inference)
    meta: dict[str, Any] = {
        "data": {"path": str(inputs["scans"]), "content_hash": ds.manifest.content_hash},
        "kinds": list(cfg.data.kinds),
        "train_objects": split.train,
        "val_objects": split.val,
        "train_clouds": len(train),
        "val_clouds": len(val),
        "skipped_clouds": skipped_train + skipped_val,
        "best_epoch": state.best_epoch,
        "best_val_loss": state.best_val,
        "val_map_clean": _finite(scores.map_clean),
        "val_map_noisy": _finite(scores.map_noisy),
        "val_motion_accuracy": _finite(scores.motion_accuracy),
    }
    save_segmenter(tmp / MODEL, cfg.category.name, model, inference, meta)
    columns = data_columns(state.history, ["epoch"])
    write_csv(tmp / METRICS, columns, [[h[c] for c in columns] for h in state.history])
    write_epoch_timings(tmp, {"train": state.history})
    info = {k: v for k, v in meta.items() if not k.endswith("_objects")}
    write_json(tmp / "model.json", info | {
        "network": dataclasses.asdict(model.config), "inference": cfg.inference.model_dump(),
        "device": str(device), "epochs_run": state.epoch, "stopped_early": state.stopped_early,
        "n_train_objects": len(split.train), "n_val_objects": len(split.val),
    })  # fmt: skip
    return state.epoch


def _finite(value: float) -> float | None:
    return None if math.isnan(value) else round(float(value), 4)


def _finalize(
    cfg: TrainSegmenterConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = json.loads((work / "model.json").read_text())

    def fmt(value: float | None) -> str:
        return "n/a" if value is None else f"{value:.3f}"

    m = cfg.model
    card = [
        f"# Part segmenter for {cfg.category.name}",
        "",
        "PointNet++ instance segmenter of thesis section 4.3 (after PartNet): "
        f"{m.n_masks} masks + confidence, motion-type branch; width x{m.width}, "
        f"{m.norm} norm, input {cfg.inference.n_points} points (FPS).",
        "",
        f"- data: `{info['data']['path']}` (content hash `{info['data']['content_hash'][:16]}`),"
        f" clouds: {', '.join(info['kinds'])}",
        f"- objects: {info['n_train_objects']} train, {info['n_val_objects']} validation "
        "(held out from the training split; the test split is never used)",
        f"- clouds: {info['train_clouds']} train, {info['val_clouds']} validation, "
        f"{info['skipped_clouds']} skipped (more parts than masks)",
        f"- epochs run: {info['epochs_run']} (best {info['best_epoch']}, early stop: "
        f"{info['stopped_early']}), Adam lr {cfg.train.lr}, batch {cfg.train.batch_size}, "
        f"device {info['device']}",
        f"- best validation loss: {info['best_val_loss']:.4f}",
        f"- validation mAP@0.5 (on the {cfg.inference.n_points} sampled points): clean "
        f"{fmt(info['val_map_clean'])}, noisy {fmt(info['val_map_noisy'])}; motion-type "
        f"accuracy {fmt(info['val_motion_accuracy'])}",
        "- config: see manifest.json; per-epoch metrics: metrics.csv; test-set scores: "
        "`artic evaluate hierarchy`",
        "",
    ]
    (work / "model_card.md").write_text("\n".join(card))
    return {
        "category": cfg.category.name,
        "train clouds": info["train_clouds"],
        "val clouds": info["val_clouds"],
        "epochs run": info["epochs_run"],
        "best epoch": info["best_epoch"],
        "best val loss": round(float(info["best_val_loss"]), 4),
        "val mAP clean": fmt(info["val_map_clean"]),
        "val mAP noisy": fmt(info["val_map_noisy"]),
        "device": info["device"],
    }


STAGE: Stage[TrainSegmenterConfig] = Stage(
    name="train-segmenter",
    conf="train_segmenter",
    schema=TrainSegmenterConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    inputs={"scans": "render-scan"},
    input_paths=lambda cfg: {"scans": Path(cfg.scans)},
)
