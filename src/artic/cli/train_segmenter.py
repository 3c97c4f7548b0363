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
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import Field, model_validator

from artic.artifacts.formats import write_json
from artic.artifacts.model_card import read_model_info, write_model_card
from artic.artifacts.scan_dataset import ScanDataset
from artic.artifacts.timings import write_epoch_timings, write_history
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import TrainingStageConfig
from artic.hierarchy.config import (
    AugmentConfig,
    CategoryName,
    CloudDataConfig,
    InferenceConfig,
    SegmenterModelConfig,
    SegmenterTrainConfig,
)

if TYPE_CHECKING:
    from artic.hierarchy.fit_segmenter import SegmentationData

MODEL = "model.pt"
METRICS = "metrics.csv"
log = logging.getLogger("artic")


class TrainSegmenterConfig(TrainingStageConfig):
    category: CategoryName
    scans: str = Field(description="a render-scan output folder of the category")
    model: SegmenterModelConfig
    inference: InferenceConfig
    data: CloudDataConfig
    augment: AugmentConfig
    train: SegmenterTrainConfig

    @model_validator(mode="after")
    def _mirror_and_passes_need_votes(self) -> TrainSegmenterConfig:
        if self.model.head != "votes":
            for name, used in (
                ("mirror_y", self.inference.mirror_y),
                ("passes", self.inference.passes > 1),
            ):
                if used:
                    raise ValueError(
                        f"inference.{name}: only the votes head (model.head=votes) has it"
                    )
        return self


def _plan(cfg: TrainSegmenterConfig, inputs: dict[str, Path]) -> Plan:
    ScanDataset.open_category(inputs["scans"], cfg.category.name)
    return Plan([cfg.train.epochs], "epochs")


def _cached_data(
    ds: ScanDataset, objects: list[int], cfg: TrainSegmenterConfig, cache: Path
) -> tuple[SegmentationData, int]:
    """`load_clouds`, stored in the resume folder on first use."""
    import numpy as np

    from artic.artifacts.resume import cached_npz
    from artic.hierarchy.cloud_cache import segmenter_cache_dir
    from artic.hierarchy.fit_segmenter import SegmentationData, load_clouds

    names = [f.name for f in dataclasses.fields(SegmentationData)]

    def make() -> dict[str, Any]:
        n_points, n_masks = cfg.inference.n_points, cfg.model.n_masks
        data, skipped = load_clouds(ds, objects, cfg.data, n_points, n_masks, cfg.seed)
        arrays = {k: getattr(data, k) for k in names if isinstance(getattr(data, k), np.ndarray)}
        return {"skipped": np.asarray(skipped), **arrays}

    z = cached_npz(cache, make)
    data = SegmentationData(**{k: z[k] for k in names if k in z})
    return data.with_features(cfg.model.network(), segmenter_cache_dir(ds.root)), int(z["skipped"])


def train_chunk(cfg: TrainSegmenterConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """The training run; writes model.pt, metrics.csv and model.json into tmp."""
    import torch

    from artic.artifacts.resume import torch_checkpoint
    from artic.hierarchy.fit_segmenter import (
        choose_cluster_radius,
        fit_segmenter,
        score_segmenter,
        select_on_whole_scans,
        static_part_of,
        training_objects,
    )
    from artic.hierarchy.models import save_segmenter
    from artic.hierarchy.segmentation import PartSegmentationNet
    from artic.learning import trainer
    from artic.learning.fit_state import FitState

    t = cfg.train
    device = trainer.start_training(t)
    ds = ScanDataset.open_category(inputs["scans"], cfg.category.name)
    split = training_objects(ds, cfg.data)
    resume = WorkDir(Path(cfg.out)).resume_dir("train-segmenter")
    train, skipped_train = _cached_data(ds, split.train, cfg, resume / "train.npz")
    val, skipped_val = _cached_data(ds, split.val, cfg, resume / "val.npz")
    log.info("train-segmenter: %d training and %d validation clouds", len(train), len(val))

    static_part = cfg.model.static_part
    if static_part == "auto":
        static_part = static_part_of(train.part_id, train.motion_type)
        log.info("train-segmenter: model.static_part=auto -> %s", static_part)
    torch.manual_seed(cfg.seed)
    model = PartSegmentationNet(cfg.model.network(static_part)).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    parts = {"model": model, "optimizer": optimizer}
    saved, save = torch_checkpoint(resume / "last.pt", map_location=device)
    state = trainer.restore(parts, saved, FitState)

    def checkpoint(s: FitState) -> None:
        save(trainer.checkpoint(parts, s))

    state = fit_segmenter(
        model, optimizer, train, val, t, cfg.augment, cfg.seed, state, device, checkpoint,
        inference=cfg.inference,
    )  # fmt: skip
    assert state.best_weights is not None
    model.load_state_dict(state.best_weights)
    inference, radius_scores = choose_cluster_radius(
        model, val, cfg.inference, t.cluster_radii, t.mode_bandwidths
    )
    kinds = cfg.data.kinds
    inference, whole_scores = select_on_whole_scans(model, ds, split.val, kinds, t, inference)
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
    if radius_scores:
        meta["cluster_radius_val_map"] = {r: round(v, 4) for r, v in radius_scores.items()}
    if whole_scores:
        meta["whole_scan_val_map"] = {k: round(v, 4) for k, v in whole_scores.items()}
    save_segmenter(tmp / MODEL, cfg.category.name, model, inference, meta)
    write_history(tmp / METRICS, state.history)
    write_epoch_timings(tmp, {"train": state.history})
    info = {k: v for k, v in meta.items() if not k.endswith("_objects")}
    write_json(tmp / "model.json", info | {
        "network": dataclasses.asdict(model.config), "inference": inference.model_dump(),
        "device": str(device), "epochs_run": state.epoch, "stopped_early": state.stopped_early,
        "n_train_objects": len(split.train), "n_val_objects": len(split.val),
    })  # fmt: skip
    return state.epoch


def _finite(value: float) -> float | None:
    return None if math.isnan(value) else round(float(value), 4)


def _finalize(
    cfg: TrainSegmenterConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = read_model_info(work)

    def fmt(value: float | None) -> str:
        return "n/a" if value is None else f"{value:.3f}"

    from artic.hierarchy.fit_segmenter import head_description

    m = cfg.model
    about = ("PointNet++ instance segmenter of thesis section 4.3 (after PartNet): "
             f"{head_description(m, info)}, motion-type branch; width x{m.width}, {m.norm} norm, "
             f"{'normals, ' if m.normals else ''}"
             f"input {cfg.inference.n_points} points (FPS).")  # fmt: skip
    whole, chosen = info.get("whole_scan_val_map"), info["inference"]
    whole_line = [f"- on whole validation scans ({len(whole)} settings tried): passes "
                  f"{chosen['passes']}, min_points {chosen['min_points']}, mAP@0.5 (mean of "
                  f"clean and noisy) {max(whole.values()):.3f}"] if whole else []  # fmt: skip
    write_model_card(work, f"Part segmenter for {cfg.category.name}", about, info, [
        f"- clouds: {info['train_clouds']} train, {info['val_clouds']} validation, "
        f"{info['skipped_clouds']} skipped (more parts than masks)",
        f"- epochs run: {info['epochs_run']} (best {info['best_epoch']}, early stop: "
        f"{info['stopped_early']}), Adam lr {cfg.train.lr}, batch {cfg.train.batch_size}, "
        f"device {info['device']}",
        f"- best validation loss: {info['best_val_loss']:.4f}",
        f"- validation mAP@0.5 (on the {cfg.inference.n_points} sampled points): clean "
        f"{fmt(info['val_map_clean'])}, noisy {fmt(info['val_map_noisy'])}; motion-type "
        f"accuracy {fmt(info['val_motion_accuracy'])}",
        *whole_line,
    ], "metrics.csv; test-set scores: `artic evaluate hierarchy`",
       f", clouds: {', '.join(info['kinds'])}")  # fmt: skip
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
    help=(
        "Train the part segmenter of one category on its scans (section 4.3).\n\n"
        "Example: artic train-segmenter category=storage_furniture"
    ),
    conf="train_segmenter",
    schema=TrainSegmenterConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"scans": "render-scan"},
    input_paths=lambda cfg: {"scans": Path(cfg.scans)},
)
