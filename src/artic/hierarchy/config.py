"""Chapter 4's configs, validated straight from the Hydra config of `train-segmenter`,
`train-hierarchy` and `evaluate hierarchy` (conf/<stage>/config.yaml holds each value,
these models its type, range and meaning). `InferenceConfig` and `PartGraphConfig` are
also stored in the model files and used at inference; `GraphNetConfig` is the labelling
network's architecture. The networks' modules re-export them (`segmentation`, `graph`,
`gnn`).

No torch here: a config validates without loading the numerical libraries.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import Field, NonNegativeInt, PositiveFloat, PositiveInt, field_validator

from artic.config.schemas import Strict
from artic.learning.trainer import TrainConfig

if TYPE_CHECKING:
    from artic.hierarchy.segmentation import SegmentationConfig


class CategoryName(Strict):
    """The category config group (conf/common/category); only its name is needed."""

    model_config = Strict.model_config | {"extra": "ignore"}
    name: str


# --- the part segmenter (section 4.3) ---------------------------------------------------


class SegmenterModelConfig(Strict):
    """`model:` the PointNet++ SSG backbone of PartNet, optionally narrower/lighter."""

    width: float = Field(1.0, gt=0, description="every layer width times this")
    n_masks: int = Field(24, gt=0, description="N instance masks (section 4.3: 24)")
    norm: Literal["batch", "layer"] = Field("batch", description="normalisation in the MLPs")
    centroids: tuple[int, int] = Field((512, 128), description="FPS centroids, levels 1 and 2")
    neighbours: tuple[int, int] = Field((32, 64), description="ball query size, levels 1 and 2")
    radii: tuple[float, float] = Field((0.2, 0.4), description="ball radii (unit-sphere units)")
    head: Literal["masks", "votes"] = Field(
        "masks", description="masks: section 4.3's N masks; votes: offsets + clustering"
    )
    normals: bool = Field(False, description="per-point normals as input features")
    static_part: Literal["votes", "one", "auto"] = Field(
        "votes",
        description="votes head: 'one' makes every static point one part (a category whose "
        "static points are one rigid body, e.g. storage furniture) and drops their offset "
        "loss; 'auto': 'one' when every training cloud has at most one static part",
    )
    offset_weight: Literal["points", "parts"] = Field(
        "points",
        description="votes head: the offset loss's mean over labelled points (PointGroup) "
        "or over the parts of each cloud, every part weighing the same",
    )
    axis_head: bool = Field(
        False,
        description="votes head: a per-point head reading whether the point's part moves "
        "about (or along) a vertical axis, for inference.axis_split",
    )

    def network(self, static_part: Literal["votes", "one"] | None = None) -> SegmentationConfig:
        """The architecture these settings describe; `static_part` resolves "auto" (which
        the training data decides: `fit_segmenter.static_part_of`), as "votes" if None."""
        import dataclasses

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
            base.backbone,
            set_abstractions=tuple(levels),
            norm=self.norm,
            in_channels=3 if self.normals else 0,
        )
        if static_part is None:
            static_part = "votes" if self.static_part == "auto" else self.static_part
        return dataclasses.replace(
            base,
            backbone=backbone,
            head=self.head,
            normals=self.normals,
            static_part=static_part,
            offset_weight=self.offset_weight,
            axis_head=self.axis_head,
        )


class InferenceConfig(Strict):
    """`inference:` how `segment` turns the network's masks into parts; saved with the
    model (the cloud must be downsampled to the size it was trained with)."""

    n_points: int = Field(2048, gt=1, description="network input size (FPS downsampling)")
    min_points: int = Field(8, ge=0, description="smaller masks are merged away")
    min_fraction: float = Field(0.005, ge=0, lt=1, description="... or smaller than this fraction")
    min_confidence: float = Field(0.1, ge=0, le=1, description="... or less confident")
    cluster_radius: tuple[PositiveFloat, PositiveFloat, PositiveFloat, PositiveFloat] = Field(
        (0.12, 0.12, 0.12, 0.12),
        description="votes head: flood-fill radius of the shifted points, cloud radii, per "
        "motion type (static, rotating, translating, both); one number: all four",
    )
    mode_bandwidth: float = Field(
        0.0,
        ge=0,
        description="votes head: Gaussian mean-shift bandwidth (cloud radii) the shifted points "
        "climb to their modes with before the flood fill; 0: none",
    )
    mirror_y: bool = Field(
        False,
        description="votes head: average the network's outputs on the cloud and on its mirror "
        "image (y -> -y), for a model trained with augment.mirror_y",
    )
    moving_together: bool = Field(
        False,
        description="votes head: cluster the votes of every moving type (rotating, translating, "
        "both) as one set, so a part whose points the network reads as two moving types "
        "stays one part (radius: the largest of those types')",
    )
    axis_split: bool = Field(
        False,
        description="votes head with an axis head: a part whose points read a vertical and a "
        "horizontal axis (each side at least min_points per sample, the smaller at least "
        "axis_share of the part) is cut in two",
    )
    axis_share: float = Field(
        0.25,
        ge=0,
        lt=0.5,
        description="votes head, axis_split: the smaller half of a cut part holds at least this "
        "share of its points (a few misread points of a seat are no second part)",
    )
    axis_smooth: int = Field(
        0,
        ge=0,
        description="votes head, axis_split: before the cut, each point's vertical-axis "
        "probability is the mean over its part's this many nearest points (itself included) "
        "in the coordinates the network saw, since a rigid part's points read one axis; 0: none",
    )
    passes: int = Field(
        1,
        ge=1,
        description="votes head: the network runs on this many disjoint farthest-point samples "
        "of n_points each (as many as the cloud has points for) and all their votes are "
        "clustered together, so parts are cut at passes x n_points points",
    )
    modes_per_pass: bool = Field(
        False,
        description="votes head, passes > 1: each pass's votes climb to their modes among "
        "that pass's own votes (mode_bandwidth) before all passes' are clustered together: "
        "the samples are independent draws of one cloud, so their modes agree to within the "
        "flood-fill radius, at passes x n_points^2 mean-shift work instead of "
        "(passes x n_points)^2",
    )

    @field_validator("cluster_radius", mode="before")
    @classmethod
    def _one_radius_for_all(cls, value: object) -> object:
        return (value,) * 4 if isinstance(value, int | float) else value


class CloudDataConfig(Strict):
    """`data:` which training clouds; every `val_every`-th training object validates."""

    kinds: tuple[Literal["clean", "noisy"], ...] = Field(
        ("clean", "noisy"), min_length=1, description="which clouds to train on"
    )
    val_every: int = Field(10, ge=2, description="every Nth training object validates")
    max_train_objects: int | None = Field(None, gt=0, description="first N training objects")
    max_poses: int | None = Field(None, gt=0, description="first N poses per object")


class AugmentConfig(Strict):
    """`augment:` of the segmenter's training clouds."""

    rotate_z_deg: float = Field(0.0, ge=0, le=180, description="random rotation about z, +-deg")
    jitter_m: float = Field(0.0, ge=0, description="per-point Gaussian noise std, metres")
    mirror_y: bool = Field(False, description="mirror half of the clouds in y (left <-> right)")


class SegmenterTrainConfig(TrainConfig):
    """`train:` Adam on the instance + motion-type loss (`fit_segmenter`)."""

    epochs: int = Field(100, gt=0, description="at most; early stopping usually ends sooner")
    batch_size: int = Field(8, ge=2, description="clouds per step (BatchNorm needs >= 2)")
    lr: float = Field(1e-4, gt=0, description="Adam (section 4.3: 1e-4)")
    patience: int = Field(10, gt=0, description="epochs without a better val loss")
    cluster_radii: tuple[PositiveFloat, ...] = Field(
        (0.05, 0.08, 0.12, 0.16, 0.2, 0.25, 0.3),
        description="votes head: radii tried on the validation clouds after training, first "
        "one for all motion types, then each type's in turn; the best mAP@0.5's are saved "
        "with the model (empty: keep inference.cluster_radius)",
    )
    mode_bandwidths: tuple[float, ...] = Field(
        (),
        description="votes head: mean-shift bandwidths tried with the radii (a radius search "
        "for each), the best mAP's kept (empty: keep inference.mode_bandwidth)",
    )
    select_passes: tuple[PositiveInt, ...] = Field(
        (),
        description="votes head: inference.passes tried on whole validation scans after the "
        "radius search, with select_min_points, select_moving_together, cluster_radii and "
        "mode_bandwidths (`choose_inference`); all three empty: no such search",
    )
    select_min_points: tuple[NonNegativeInt, ...] = Field(
        (), description="votes head: inference.min_points tried in that search"
    )
    select_moving_together: tuple[bool, ...] = Field(
        (), description="votes head: inference.moving_together tried in that search"
    )
    select_poses: PositiveInt = Field(4, description="poses of each validation object in it")


# --- the graph labelling network (section 4.4) ------------------------------------------


class PartGraphConfig(Strict):
    """`graph:` part-graph construction (section 4.4.1); saved with the model. The
    contact threshold's default is train-hierarchy's: 0.02 m leaves ~11% of
    storage-furniture tree edges out of the graph, 0.05 m ~0.3%."""

    contact_threshold: float = Field(0.05, gt=0, description="metres; closer parts get an edge")
    points_per_node: int = Field(128, gt=0, description="K, points per part for the PointNet")


class GraphNetConfig(Strict):
    """`model:` sizes of the labelling network (small: graphs have fewer than ~30 nodes)."""

    encoder_widths: tuple[int, ...] = Field(
        (32, 64, 128), min_length=1, description="PointNet point-wise MLP; the last: code size"
    )
    decoder_points: int = Field(128, gt=0, description="points the autoencoder emits")
    hidden: int = Field(64, gt=0, description="GraphSAGE width")
    head_hidden: int = Field(64, gt=0, description="hidden width of the MLP heads")
    num_layers: int = Field(3, gt=0, description="convolution + edge pooling levels (3)")
    node_frame: Literal["object", "part"] = Field(
        "object",
        description="the node encoder reads each part's points in the object's frame (the "
        "thesis) or also in the part's own (`gnn.PointNetEncoder`)",
    )


class PretrainConfig(Strict):
    """`pretrain:` the node encoder as a point autoencoder (Chamfer, Nesterov SGD)."""

    epochs: int = Field(500, ge=0, description="autoencoder epochs (4.4.3: 500; 0: none)")
    batch_size: int = Field(64, gt=0, description="part point sets per step")
    lr: float = Field(1e-3, gt=0, description="Nesterov SGD (4.4.3: 1e-3)")
    momentum: float = Field(0.9, gt=0, lt=1)
    max_sets: int | None = Field(
        None, gt=0, description="a seeded subset of at most N part point sets (null: all)"
    )


class LabellerTrainConfig(TrainConfig):
    """`train:` Adam on the sum of the four cross-entropies (`fit_labeller`)."""

    epochs: int = Field(30, gt=0, description="4.4.3: 30")
    batch_size: int = Field(16, gt=0, description="graphs per step")
    lr: float = Field(1e-3, gt=0, description="Adam (4.4.3: 1e-3)")
    patience: int = Field(10, gt=0, description="epochs without a better val loss")


# --- evaluation (Tables 4.1 and 4.2) ----------------------------------------------------


class HierarchyEvaluateConfig(Strict):
    """`evaluate:` of `evaluate hierarchy` (`hierarchy.evaluate.evaluate_scan`)."""

    kinds: tuple[Literal["clean", "noisy"], ...] = Field(("clean", "noisy"), min_length=1)
    max_objects: int | None = Field(None, gt=0, description="first N test objects (null: all)")
    max_poses: int | None = Field(None, gt=0, description="first N poses of each (null: all)")
    iou_threshold: float = Field(0.5, gt=0, le=1, description="mAP true-positive IoU")
    match_iou: float = Field(0.5, gt=0, le=1, description="predicted-to-true part matching")
    objects_per_chunk: int = Field(4, gt=0, description="test objects per resumable chunk")
    yaw: Literal["none", "random"] = Field(
        "none",
        description="none: scans in the object frame (the thesis' protocol); random: each "
        "scan turned about z by a seeded random angle, then brought back by the estimated "
        "yaw (`canonical.canonical_yaw`), as infer-hierarchy --yaw canonical does",
    )
    motion_evidence: Literal["labeller", "both"] = Field(
        "both",
        description="a part's motion type from the labeller alone (the thesis) or from the "
        "product of its and the segmenter's per-point probabilities (`infer.part_motion`)",
    )
