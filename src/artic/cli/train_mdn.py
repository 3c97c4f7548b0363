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
from typing import Any

from pydantic import Field

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.formats import write_json
from artic.artifacts.model_card import read_model_info, write_model_card
from artic.artifacts.timings import write_epoch_timings, write_history
from artic.artifacts.workdir import WorkDir
from artic.cli.stage_runner import Plan, Stage
from artic.config.schemas import TrainingStageConfig
from artic.errors import InputError
from artic.kinematics.config import MDN_KIND, CategoryRef, MdnConfig, MdnTrainConfig

MODEL = "model.pt"
METRICS = "metrics.csv"


class TrainMdnConfig(TrainingStageConfig):
    category: CategoryRef
    depth: str = Field(description="a render-depth output folder of the category")
    model: MdnConfig
    train: MdnTrainConfig


def _plan(cfg: TrainMdnConfig, inputs: dict[str, Path]) -> Plan:
    DepthDataset.open_category(inputs["depth"], cfg.category.name)
    return Plan([cfg.train.epochs], "epochs")


def train_chunk(cfg: TrainMdnConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """The training run; writes model.pt, metrics.csv into tmp."""
    import torch

    from artic.artifacts.model_file import save_model_file
    from artic.artifacts.resume import torch_checkpoint
    from artic.kinematics.data import load_split
    from artic.kinematics.mdn import KinematicsMDN
    from artic.kinematics.predict import training_domain
    from artic.kinematics.preprocess import InputPipeline
    from artic.kinematics.targets import TargetCodec
    from artic.kinematics.train import fit
    from artic.learning import trainer
    from artic.learning.fit_state import FitState

    t, m = cfg.train, cfg.model
    device = trainer.start_training(t)
    ds = DepthDataset.open(inputs["depth"])
    train = load_split(ds, "train", t.val_every, t.max_train_objects)
    val = load_split(ds, "val", t.val_every)
    if len(train) == 0 or len(val) == 0:
        raise InputError(
            f"depth: {inputs['depth']} has {len(train)} training and {len(val)} validation "
            f"images (train.val_every={t.val_every}); render more objects"
        )
    codec = TargetCodec.fit(ds.label_columns, train.labels)
    torch.manual_seed(cfg.seed)
    model = KinematicsMDN(
        codec.dim, m.components, m.width, sigma_floor=m.sigma_floor, input_size=m.input_size
    ).to(device)
    pipeline = InputPipeline(ds.info.camera, m.input_size)
    optimizer = torch.optim.Adam(model.parameters(), lr=t.lr, weight_decay=t.weight_decay)
    parts = {"model": model, "optimizer": optimizer}
    saved, save = torch_checkpoint(WorkDir(Path(cfg.out)).resume_dir("train-mdn") / "last.pt")
    state = trainer.restore(parts, saved, FitState)

    def checkpoint(s: FitState) -> None:
        save(trainer.checkpoint(parts, s))

    state = fit(
        model, optimizer, train, val, codec, pipeline, t, cfg.seed, state, device, checkpoint
    )
    assert state.best_weights is not None
    meta = {
        "codec": codec.to_dict(),
        # as read from dataset.json (keys sorted, fresh strings): the same bytes of model.pt
        "camera": json.loads(json.dumps(ds.info.camera.model_dump(), sort_keys=True)),
        "dof": ds.info.dof,
        "joint_type": ds.info.joint_type,
        "data": {"path": str(inputs["depth"]), "content_hash": ds.manifest.content_hash},
        "best_epoch": state.best_epoch,
        "best_val_nll": state.best_val,
        "train_images": len(train),
        "val_images": len(val),
        # what predict checks an estimate against (kinematics/predict.py, docs/models.md)
        "training_domain": training_domain(
            ds.label_columns,
            train.labels,
            ds.info.camera,
            ds.info.dof,
            f"labels of the {len(train)} training images",
            ds.info.noise,
            ds.info.door_thickness,
        ),
    }
    save_model_file(
        tmp / MODEL, MDN_KIND, cfg.category.name, model.hparams, state.best_weights, meta
    )
    write_history(tmp / METRICS, state.history, ["epoch", "train_nll", "val_nll", "lr"])
    write_epoch_timings(tmp, {"train": state.history})
    write_json(tmp / "model.json", {k: v for k, v in meta.items() if k != "codec"} | {
        "hparams": model.hparams, "device": str(device), "epochs_run": state.epoch,
        "stopped_early": state.stopped_early, "learned_columns": codec.learned_columns,
    })  # fmt: skip
    return state.epoch


def _domain_lines(info: dict[str, Any]) -> list[str]:
    """The card's bullets on what the model was trained on (predict's warnings)."""
    from artic.kinematics.predict import domain_card_lines

    return domain_card_lines(info["training_domain"], str(info["joint_type"]))


def _finalize(
    cfg: TrainMdnConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = read_model_info(work)
    about = ("Mixture density network of thesis section 3.2 (ResNet-18 backbone, "
             f"{cfg.model.components} components, width {cfg.model.width}).")  # fmt: skip
    write_model_card(work, f"MDN for {cfg.category.name}", about, info, [
        f"- images: {info['train_images']} train, {info['val_images']} validation",
        f"- epochs run: {info['epochs_run']} (best {info['best_epoch']}, "
        f"early stop: {info['stopped_early']}), device {info['device']}",
        f"- best validation NLL: {info['best_val_nll']:.4f} (standardised label units)",
        f"- predicted columns: {', '.join(info['learned_columns'])}",
        *_domain_lines(info),
    ], "metrics.csv")  # fmt: skip
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
    help=(
        "Train the per-category mixture density network (section 3.2, Eq. 3.1 and 3.2).\n\n"
        "Example: artic train-mdn category=microwave"
    ),
    conf="train_mdn",
    schema=TrainMdnConfig,
    plan=_plan,
    chunk=train_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"depth": "render-depth"},
    input_paths=lambda cfg: {"depth": Path(cfg.depth)},
)
