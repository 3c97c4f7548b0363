"""Chapter 3's configs, validated straight from the Hydra config of `train-mdn` and
`evaluate mdn` (conf/train_mdn, conf/evaluate_mdn: the YAML holds each value, these models
its type, range and meaning), and the metadata of an MDN model file.

No torch here: a config validates without loading the numerical libraries.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field

from artic.config.schemas import Strict
from artic.geometry.camera import CameraIntrinsics
from artic.learning.trainer import TrainConfig

#: the kind of an MDN model file (`artifacts.model_file`)
MDN_KIND = "kinematics-mdn"


class MdnConfig(Strict):
    """`model:` the network of section 3.2 (`KinematicsMDN`)."""

    components: int = Field(20, gt=0, description="mixture components m")
    width: int = Field(64, gt=0, description="ResNet-18 first-stage channels")
    sigma_floor: float = Field(1e-3, gt=0, description="lower bound of each std")
    input_size: int = Field(64, ge=32, description="side of the object crop, pixels")


class MdnTrainConfig(TrainConfig):
    """`train:` Adam on the NLL (Eq. 3.2) with a learning-rate schedule (`train.fit`)."""

    epochs: int = Field(40, gt=0, description="at most; early stopping usually ends sooner")
    batch_size: int = Field(64, gt=0)
    lr: float = Field(1e-3, gt=0, description="Adam's learning rate")
    schedule: Literal["constant", "cosine"] = "cosine"
    patience: int = Field(5, gt=0, description="epochs without a better validation NLL")
    augment_dropout: float = Field(0.1, ge=0, lt=1)
    val_every: int = Field(10, ge=2, description="every Nth training object validates")
    max_train_objects: int | None = Field(None, gt=0)
    channels_last: bool = True


class MdnEvaluateConfig(Strict):
    """`evaluate:` of `evaluate mdn` (Table 3.1, `evaluate.evaluate`)."""

    max_test_images: int | None = Field(None, gt=0)
    icp_images: int = Field(500, ge=0)
    batch_size: int = Field(64, gt=0)
    levels: tuple[Annotated[float, Field(gt=0, lt=1)], ...] = Field(
        (0.5, 0.9, 0.95), min_length=1, description="nominal coverages, each in (0, 1)"
    )
    examples: int = Field(8, ge=0)
    refine: bool = Field(True, description="add the 'Ours + refinement' row (kinematics/refine.py)")
    refine_images: int | None = Field(
        500, ge=0, description="the refinement runs on the first N test images (None: all)"
    )
    calibration_images: int = Field(
        500, ge=0, description="the refined intervals' scales are fitted on the first N val images"
    )

    def refined_count(self, test_images: int) -> int:
        """How many of the first test images the refinement runs on (0: no refined row)."""
        if not self.refine:
            return 0
        return test_images if self.refine_images is None else self.refine_images


class DataRecord(Strict):
    """An input a model was trained on: where it was and its content hash."""

    path: str
    content_hash: str


class MdnModelMeta(Strict):
    """The `meta` of an MDN model file (`train-mdn`'s model.pt); model.json holds the
    same fields but `codec`. The camera, DoF and joint type are the training images'."""

    model_config = Strict.model_config | {"extra": "ignore"}
    codec: dict[str, Any]
    camera: CameraIntrinsics
    dof: int
    joint_type: str
    data: DataRecord | None = None
    best_epoch: int = 0
    best_val_nll: float = float("nan")
    train_images: int = 0
    val_images: int = 0


class CategoryRef(Strict):
    """The category config group (conf/common/category); Chapter 3 needs its name and DoF."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str
    dof: int
