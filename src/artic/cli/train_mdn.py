"""`artic train-mdn`: train the mixture density network of one category (section 3.2).

One chunk: the whole training run, checkpointed after every epoch in the work area's
resume folder, so an interrupted run continues from its last finished epoch. The
checkpoint is read with `weights_only=True`; a corrupt one is an InputError naming it
(exit 2: delete it or use `--force` to start over), never silently discarded. Outputs:
`model.pt` (best validation NLL weights, target codec, training camera), `metrics.csv`
(one row per epoch), `model.json` and `model_card.md`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

from pydantic import Field

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.formats import write_csv, write_json
from artic.artifacts.timings import write_epoch_timings
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import TRAIN_THREADS_HELP, Strict, TrainingStageConfig
from artic.errors import InputError

KIND = "kinematics-mdn"
MODEL = "model.pt"
METRICS = "metrics.csv"


class CategoryRef(Strict):
    """The category config group; train-mdn needs only its name."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str
    dof: int


class ModelConfig(Strict):
    components: int = Field(20, gt=0, description="mixture components m")
    width: int = Field(64, gt=0, description="ResNet-18 first-stage channels")
    sigma_floor: float = Field(1e-3, gt=0, description="lower bound of each std")
    input_size: int = Field(64, ge=32, description="side of the object crop, pixels")


class TrainConfig(Strict):
    epochs: int = Field(40, gt=0)
    batch_size: int = Field(64, gt=0)
    lr: float = Field(1e-3, gt=0)
    schedule: Literal["constant", "cosine"] = "cosine"
    min_lr_ratio: float = Field(0.01, ge=0, le=1, description="cosine's final lr / lr")
    weight_decay: float = Field(0.0, ge=0)
    patience: int = Field(5, gt=0)
    augment_dropout: float = Field(0.1, ge=0, lt=1)
    val_every: int = Field(10, ge=2)
    max_train_objects: int | None = Field(None, gt=0)
    device: Literal["auto", "cpu", "cuda"] = "auto"
    threads: int = Field(2, ge=1, description=TRAIN_THREADS_HELP)
    channels_last: bool = True


class TrainMdnConfig(TrainingStageConfig):
    category: CategoryRef
    depth: str = Field(description="a render-depth output folder of the category")
    model: ModelConfig
    train: TrainConfig


def _plan(cfg: TrainMdnConfig, inputs: dict[str, Path]) -> Plan:
    DepthDataset.open_category(inputs["depth"], cfg.category.name)
    return Plan([cfg.train.epochs], "epochs")


def train_chunk(cfg: TrainMdnConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """The training run; writes model.pt, metrics.csv into tmp."""
    import torch

    from artic.artifacts.model_file import load_torch_file, save_model_file, save_torch_file
    from artic.geometry.camera import CameraIntrinsics
    from artic.kinematics.data import load_split
    from artic.kinematics.mdn import KinematicsMDN
    from artic.kinematics.preprocess import InputPipeline
    from artic.kinematics.targets import TargetCodec
    from artic.kinematics.train import FitConfig, FitState, fit

    torch.set_num_threads(cfg.train.threads)
    device = training_device(cfg.train.device)
    ds = DepthDataset.open(inputs["depth"])
    t = cfg.train
    train = load_split(ds, "train", t.val_every, t.max_train_objects)
    val = load_split(ds, "val", t.val_every)
    if len(train) == 0 or len(val) == 0:
        raise InputError(
            f"depth: {inputs['depth']} has {len(train)} training and {len(val)} validation "
            f"images (train.val_every={t.val_every}); render more objects"
        )
    codec = TargetCodec.fit(ds.label_columns, train.labels)
    torch.manual_seed(cfg.seed)
    m = cfg.model
    model = KinematicsMDN(
        codec.dim, m.components, m.width, sigma_floor=m.sigma_floor, input_size=m.input_size
    ).to(device)
    pipeline = InputPipeline(CameraIntrinsics.model_validate(ds.info["camera"]), m.input_size)
    optimizer = torch.optim.Adam(model.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    resume = WorkDir(Path(cfg.out)).resume_dir("train-mdn") / "last.pt"
    state = FitState()
    if resume.is_file():  # weights_only; a corrupt checkpoint is an InputError naming it
        saved = load_torch_file(resume, "checkpoint")
        model.load_state_dict(saved["model"])
        optimizer.load_state_dict(saved["optimizer"])
        state = FitState.from_dict(saved["state"])

    def checkpoint(s: FitState) -> None:
        payload = {"model": model.state_dict(), "optimizer": optimizer.state_dict()}
        save_torch_file(resume, {**payload, "state": s.to_dict()})

    fit_cfg = FitConfig(
        t.epochs, t.batch_size, t.lr, t.weight_decay, t.patience, t.augment_dropout,
        cfg.seed, t.channels_last, schedule=t.schedule, min_lr_ratio=t.min_lr_ratio,
    )  # fmt: skip
    state = fit(model, optimizer, train, val, codec, pipeline, fit_cfg, state, device, checkpoint)
    assert state.best_weights is not None
    meta = {
        "codec": codec.to_dict(),
        "camera": ds.info["camera"],
        "dof": ds.info["dof"],
        "joint_type": ds.info["joint_type"],
        "data": {"path": str(inputs["depth"]), "content_hash": ds.manifest.content_hash},
        "best_epoch": state.best_epoch,
        "best_val_nll": state.best_val,
        "train_images": len(train),
        "val_images": len(val),
    }
    save_model_file(tmp / MODEL, KIND, cfg.category.name, model.hparams, state.best_weights, meta)
    columns = ["epoch", "train_nll", "val_nll", "lr"]
    write_csv(tmp / METRICS, columns, [[h[c] for c in columns] for h in state.history])
    write_epoch_timings(tmp, {"train": state.history})
    write_json(tmp / "model.json", {k: v for k, v in meta.items() if k != "codec"} | {
        "hparams": model.hparams, "device": str(device), "epochs_run": state.epoch,
        "stopped_early": state.stopped_early, "learned_columns": codec.learned_columns,
    })  # fmt: skip
    return state.epoch


def training_device(name: str) -> Any:
    """`train.device` (auto | cpu | cuda) as a torch device; cuda without one is bad input."""
    import torch

    if name == "cuda" and not torch.cuda.is_available():
        raise InputError("train.device: cuda requested but no CUDA device is available")
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    return torch.device(name)


def _finalize(
    cfg: TrainMdnConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = json.loads((work / "model.json").read_text())
    card = [
        f"# MDN for {cfg.category.name}",
        "",
        "Mixture density network of thesis section 3.2 (ResNet-18 backbone, "
        f"{cfg.model.components} components, width {cfg.model.width}).",
        "",
        f"- data: `{info['data']['path']}` (content hash `{info['data']['content_hash'][:16]}`)",
        f"- images: {info['train_images']} train, {info['val_images']} validation",
        f"- epochs run: {info['epochs_run']} (best {info['best_epoch']}, "
        f"early stop: {info['stopped_early']}), device {info['device']}",
        f"- best validation NLL: {info['best_val_nll']:.4f} (standardised label units)",
        f"- predicted columns: {', '.join(info['learned_columns'])}",
        "- config: see manifest.json; per-epoch metrics: metrics.csv",
        "",
    ]
    (work / "model_card.md").write_text("\n".join(card))
    return {
        "category": cfg.category.name,
        "train images": info["train_images"],
        "val images": info["val_images"],
        "epochs run": info["epochs_run"],
        "best epoch": info["best_epoch"],
        "best val NLL": round(float(info["best_val_nll"]), 4),
        "device": info["device"],
    }


STAGE: Stage[TrainMdnConfig] = Stage(
    name="train-mdn",
    conf="train_mdn",
    schema=TrainMdnConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    inputs={"depth": "render-depth"},
    input_paths=lambda cfg: {"depth": Path(cfg.depth)},
)
