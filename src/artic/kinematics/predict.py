"""Kinematic model, configuration and geometry of an object from one depth image.

`Predictor` wraps a trained MDN (`model.pt` of `artic train-mdn`): depth in the
training camera -> mixture over the label columns (docs/formats.md) -> an estimate.
Estimators (`ESTIMATORS`):
- `most-likely` (section 3.3.1, the thesis' "maximum likelihood sample"): the mean of
  the component with the largest mixing weight;
- `densest`: the component mean with the highest mixture density (an approximation to
  the mixture's mode; worse on every Table 3.1 error, docs/kinematics.md);
- `max-point` (section 3.3.2, Table 3.2): as most-likely, but each joint's axis origin
  is the point of the observed cloud with the highest density under the model's
  marginal over that origin.

What the model was trained on (`TrainingDomain`, in model.pt's meta and model.json as
`training_domain`, written by `train-mdn`): `domain_warnings` says when an estimate
lies outside it, the image's camera is not a training camera, or the mixture's weight is
split between the two hinge sides (docs/kinematics.md, "Warnings").
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict

from artic.artifacts.workers import available_cpus
from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics
from artic.kinematics import Estimator
from artic.kinematics.config import MDN_KIND, MdnModelMeta
from artic.kinematics.intervals import (
    REFINED_INTERVALS,
    Scales,
    read_refined_intervals,
    refined_interval,
)
from artic.kinematics.mdn import (
    KinematicsMDN,
    Mixture,
    densest,
    marginal_interval,
    marginal_intervals,
    most_likely,
    sample,
)
from artic.kinematics.preprocess import InputPipeline
from artic.kinematics.refine import INTERVAL_LEVEL, Refinement, refine, side_weight
from artic.kinematics.targets import TargetCodec
from artic.objects.labels import joint_column, joint_vector
from artic.objects.spec import PartsConfig

log = logging.getLogger(__name__)

#: an estimate is outside a training range [lo, hi] beyond this fraction of hi - lo ...
RANGE_TOLERANCE = 0.1
#: ... plus this, in the quantity's unit (metres or radians)
RANGE_TOLERANCE_ABS = 0.01
#: the mixture is split between hinge sides below this weight on the estimate's side
SIDE_WEIGHT = 0.8
#: the geometry columns a training range is recorded for (with each joint's `q` and the
#: derived `distance`, the norm of (pose_x, pose_y, pose_z): camera to object origin)
DOMAIN_COLUMNS = ("depth", "width", "height", "pose_yaw")


class TrainingDomain(BaseModel):
    """What an MDN's training images covered (`training_domain` of its meta): the
    training split's labels' chiralities and [min, max] ranges, and the cameras."""

    model_config = ConfigDict(frozen=True, extra="ignore")
    source: str
    images: int
    chiralities: list[int]
    ranges: dict[str, tuple[float, float]]
    cameras: list[CameraIntrinsics]
    noise: bool | None = None
    #: [min, max] of the training objects' door thickness, metres (the depth dataset's;
    #: None for a model trained before it was recorded: every door was 2 cm thick)
    door_thickness: tuple[float, float] | None = None


def training_domain(
    columns: list[str],
    labels: NDArray[np.float64],
    camera: CameraIntrinsics,
    dof: int,
    source: str,
    noise: bool | None = None,
    door_thickness: tuple[float, float] | None = None,
) -> dict[str, Any]:
    """`TrainingDomain` of training labels (N, L) in `columns` order, as plain data (what
    a `weights_only` model file can hold). `source` says where the labels come from;
    `door_thickness` the training objects' range (`DepthDatasetInfo.door_thickness`)."""
    col = {c: i for i, c in enumerate(columns)}
    keys = [*DOMAIN_COLUMNS, *(joint_column(j, "q") for j in range(dof))]
    values = {k: labels[:, col[k]] for k in keys}
    values["distance"] = np.linalg.norm(labels[:, [col[f"pose_{a}"] for a in "xyz"]], axis=1)
    ranges = {k: (float(v.min()), float(v.max())) for k, v in values.items()}
    chiralities = sorted({1 if c >= 0 else -1 for c in labels[:, col["chirality"]].tolist()})
    domain = TrainingDomain(
        source=source,
        images=len(labels),
        chiralities=chiralities,
        ranges=ranges,
        cameras=[camera],
        noise=noise,
        door_thickness=door_thickness,
    )
    return domain.model_dump(mode="json")


def _unit(key: str, joint_type: str) -> str:
    if key in ("pose_yaw",) or (key.endswith("_q") and joint_type == "revolute"):
        return "rad"
    return "m"


def _camera_text(cam: CameraIntrinsics) -> str:
    return f"{cam.width}x{cam.height} fx {cam.fx:g} fy {cam.fy:g} cx {cam.cx:g} cy {cam.cy:g}"


def domain_card_lines(domain: dict[str, Any], joint_type: str) -> list[str]:
    """Model-card bullets of a `training_domain` (train-mdn's card)."""
    d = TrainingDomain.model_validate(domain)
    sides = ", ".join(f"{c:+d}" for c in d.chiralities)
    ranges = "; ".join(
        f"{k} {lo:.3f} to {hi:.3f} {_unit(k, joint_type)}" for k, (lo, hi) in d.ranges.items()
    )
    lines = [
        f"- trained on ({d.source}): chirality {sides}; {ranges}",
        f"- training camera{'s' if len(d.cameras) > 1 else ''}: "
        + "; ".join(_camera_text(c) for c in d.cameras)
        + ("" if d.noise is None else f" ({'with' if d.noise else 'without'} sensor noise)"),
    ]
    if d.door_thickness is not None:
        lo, hi = d.door_thickness
        span = f"{lo * 100:.1f} cm" if lo == hi else f"{lo * 100:.1f} to {hi * 100:.1f} cm"
        lines.append(
            f"- doors {span} thick; the refinement builds them "
            f"{refinement_door_thickness(d) * 100:.2f} cm thick (docs/kinematics.md)"
        )
    if len(d.chiralities) == 1:
        lines.append(
            f"- one hinge side only (chirality {d.chiralities[0]:+d}, docs/objects.md): an object "
            "hinged on the other side is answered as its mirror image"
        )
    return lines


def refinement_door_thickness(domain: TrainingDomain | None) -> float:
    """The door thickness (m) the refinement builds its hypotheses with: the middle of the
    training objects' range (a closed door's front and the body's front, where the hinge
    is, lie a door's thickness apart, which the image does not show: docs/kinematics.md),
    `PartsConfig`'s default for a model that did not record it (trained on 2 cm doors)."""
    if domain is None or domain.door_thickness is None:
        return PartsConfig().door_thickness
    lo, hi = domain.door_thickness
    return 0.5 * (lo + hi)


#: the levels of `describe`'s `intervals`
INTERVAL_LEVELS = (0.5, 0.9, 0.95)


@dataclass(frozen=True)
class Predictor:
    category: str
    model: KinematicsMDN
    codec: TargetCodec
    camera: CameraIntrinsics
    dof: int
    joint_type: str
    #: what the training images covered; None for a model trained before it was recorded
    domain: TrainingDomain | None = None
    #: the refined estimate's interval scales (kinematics/intervals.py), read from
    #: `refined_intervals.csv` beside the model file; None without one
    refined_scales: Scales | None = None
    #: threads the refinement casts its candidates' rays with (0: every CPU this process
    #: may use); each ray is cast alone, so the estimates do not depend on it
    threads: int = 0

    @classmethod
    def load(cls, path: Path, category: str | None = None) -> Predictor:
        """From a `train-mdn` model file (of `category` when given); InputError naming the
        file when it is of another kind, category or format."""
        from artic.artifacts.model_file import load_model_file

        predictor = cls.from_payload(load_model_file(path, MDN_KIND, category), path)
        scales = Path(path).parent / REFINED_INTERVALS
        if not scales.is_file():
            return predictor
        columns = list(predictor.codec.columns)
        return dataclasses.replace(
            predictor, refined_scales=read_refined_intervals(scales, columns)
        )

    @classmethod
    def from_payload(cls, payload: dict[str, Any], path: Path | None = None) -> Predictor:
        """From `artifacts.model_file.load_model_file(..., kind="kinematics-mdn")`."""
        from pydantic import ValidationError

        try:
            meta = MdnModelMeta.model_validate(payload["meta"])
        except ValidationError as err:
            where = ".".join(str(p) for p in err.errors()[0]["loc"])
            raise InputError(
                f"{path or 'MDN'}: model meta {where}: {err.errors()[0]['msg']}"
            ) from None
        if "input_size" not in payload["hparams"]:
            raise InputError(
                f"MDN of {payload['category']} from artic {payload.get('artic_version')} reads "
                "the whole image; this artic's MDN reads an object crop: retrain it "
                "(artic train-mdn)"
            )
        domain = None
        if payload["meta"].get("training_domain") is not None:
            try:
                domain = TrainingDomain.model_validate(payload["meta"]["training_domain"])
            except ValidationError as err:
                where = ".".join(str(p) for p in err.errors()[0]["loc"])
                raise InputError(
                    f"{path or 'MDN'}: model meta training_domain.{where}: {err.errors()[0]['msg']}"
                ) from None
        model = KinematicsMDN(**payload["hparams"])
        model.load_state_dict(payload["state_dict"])
        model.eval()
        return cls(
            payload["category"],
            model,
            TargetCodec.from_dict(meta.codec),
            meta.camera,
            meta.dof,
            meta.joint_type,
            domain,
        )

    @property
    def inputs(self) -> InputPipeline:
        """The preprocessing the model was trained with (preprocess.py)."""
        return InputPipeline(self.camera, int(self.model.hparams["input_size"]))

    @torch.no_grad()
    def mixture(
        self, depth: NDArray[np.floating], mask: NDArray[np.bool_] | None = None
    ) -> Mixture:
        """The network's mixture (standardised units) for (N, H, W) or (H, W) depth."""
        mix: Mixture = self.model(*self.inputs(depth, mask))
        return mix

    def estimate(
        self,
        depth: NDArray[np.floating],
        mask: NDArray[np.bool_] | None = None,
        estimator: Estimator = "most-likely",
    ) -> NDArray[np.float64]:
        """(L,) label vector for one (H, W) image in the training camera."""
        return self._estimate(self.mixture(depth, mask), depth, mask, estimator)

    def estimate_refined(
        self,
        depth: NDArray[np.floating],
        mask: NDArray[np.bool_] | None = None,
        estimator: Estimator = "most-likely",
        refine: bool = True,
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """(L,) label vector for one (H, W) image in the training camera, geometrically
        refined when `refine` (as `describe`), and the refinement's record."""
        mix = self.mixture(depth, mask)
        label = self._estimate(mix, depth, mask, estimator)
        if not refine:
            return label, {"status": "off", "refined": False}
        result = self.refine(mix, depth, mask, label)
        return result.label, result.as_json()

    def _estimate(
        self,
        mix: Mixture,
        depth: NDArray[np.floating],
        mask: NDArray[np.bool_] | None,
        estimator: Estimator,
    ) -> NDArray[np.float64]:
        """`estimate` from the image's mixture (`mixture(depth, mask)`)."""
        point = densest(mix) if estimator == "densest" else most_likely(mix)
        label = self.codec.decode(point.numpy())[0]
        if estimator == "max-point":
            points = self.camera.back_project(
                np.where(mask, depth, 0) if mask is not None else depth
            )
            for j in range(self.dof):
                label[self._origin(j)] = self._max_point(mix, j, points)
        return label

    def refine(
        self,
        mix: Mixture,
        depth: NDArray[np.floating],
        mask: NDArray[np.bool_] | None,
        label: NDArray[np.float64],
        detail: tuple[NDArray[np.floating], CameraIntrinsics] | None = None,
    ) -> Refinement:
        """Test-time geometric refinement of `label` (L,) against the image
        (kinematics/refine.py) from the image's mixture's components and its central
        `INTERVAL_LEVEL` interval; `detail`: the image in the camera that took it (masked),
        when it was reprojected into the model's."""
        observed = np.where(mask, depth, 0) if mask is not None else depth
        lower, upper = marginal_interval(mix, INTERVAL_LEVEL)
        return refine(
            np.asarray(observed, dtype=np.float32), self.camera, self.category,
            list(self.codec.columns), label, mix.log_pi[0].exp().double().numpy(),
            self.codec.decode(mix.mu[0].numpy()), self.codec.decode(lower[0].numpy()),
            self.codec.decode(upper[0].numpy()), parts=self.parts, detail=detail,
            threads=self.threads or available_cpus(),
        )  # fmt: skip

    @property
    def parts(self) -> PartsConfig:
        """The part constants the refinement builds its hypotheses with: the defaults, the
        doors `refinement_door_thickness` thick."""
        return PartsConfig(door_thickness=refinement_door_thickness(self.domain))

    def _origin(self, joint: int) -> list[int]:
        return [self.codec.columns.index(c) for c in joint_vector(joint, "origin")]

    def _max_point(
        self, mix: Mixture, joint: int, points: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The cloud point most likely under the marginal of joint `joint`'s origin."""
        cols = self._origin(joint)
        learned = np.flatnonzero(self.codec.learned)
        dims = [int(np.flatnonzero(learned == c)[0]) for c in cols]
        z = (points - self.codec.mean[cols]) / self.codec.std[cols]
        mu = mix.mu[0, :, dims].numpy()  # (m, 3)
        sigma = mix.sigma[0, :, dims].numpy()
        log_pi = mix.log_pi[0].numpy()
        diff = (z[:, None, :] - mu[None]) / sigma[None]
        log_n = -0.5 * (diff**2).sum(-1) - np.log(sigma).sum(-1)[None]
        score = np.logaddexp.reduce(log_pi[None] + log_n, axis=1)
        return points[int(np.argmax(score))]

    def describe(
        self,
        depth: NDArray[np.floating],
        mask: NDArray[np.bool_] | None = None,
        estimator: Estimator = "most-likely",
        samples: int = 0,
        seed: int = 0,
        refine: bool = False,
        detail: tuple[NDArray[np.floating], CameraIntrinsics] | None = None,
    ) -> dict[str, Any]:
        """The JSON `artic predict` prints (see docs/kinematics.md). With `refine`, the
        estimate is the geometric refinement's (`refine`, `detail` as there), and
        `refinement` says what it did; without, `refinement` says it was off."""
        mix = self.mixture(depth, mask)
        label = self._estimate(mix, depth, mask, estimator)
        refinement: dict[str, Any] = {"status": "off (--no-refine)", "refined": False}
        if refine:
            result = self.refine(mix, depth, mask, label, detail)
            label, refinement = result.label, result.as_json()
        col = {c: i for i, c in enumerate(self.codec.columns)}
        unit = "rad" if self.joint_type == "revolute" else "m"
        joints = []
        for j in range(self.dof):
            direction = np.array([label[col[c]] for c in joint_vector(j, "direction")])
            joints.append({
                "type": self.joint_type,
                "origin": [label[col[c]] for c in joint_vector(j, "origin")],
                "direction": (direction / max(np.linalg.norm(direction), 1e-12)).tolist(),
                "configuration": label[col[joint_column(j, "q")]],
                "configuration_unit": unit,
                "part_origin_in_axis_frame": [label[col[c]] for c in joint_vector(j, "part")],
            })  # fmt: skip
        out: dict[str, Any] = {
            "category": self.category,
            "frame": "camera body frame: x forward, y left, z up; metres, radians",
            "estimator": estimator,
            "joints": joints,
            "geometry": {
                "depth": label[col["depth"]],
                "width": label[col["width"]],
                "height": label[col["height"]],
                "chirality": 1 if label[col["chirality"]] >= 0 else -1,
                "pose": {k: label[col[f"pose_{k}"]] for k in ("x", "y", "z", "yaw")},
            },
            "estimate": dict(zip(self.codec.columns, label.tolist(), strict=True)),
            "mixture": {
                "columns": list(self.codec.columns),
                "weights": mix.log_pi[0].exp().tolist(),
                "means": self.codec.decode(mix.mu[0].numpy()).tolist(),
                "stds": self.codec.decode_scale(mix.sigma[0].numpy()).tolist(),
            },
            "refinement": refinement,
            "intervals": self.intervals(mix, label, bool(refinement["refined"])),
        }
        if samples > 0:
            draws = sample(mix, samples, torch.Generator().manual_seed(seed))
            out["samples"] = self.codec.decode(draws[0].numpy()).tolist()
        return out

    def intervals(self, mix: Mixture, label: NDArray[np.float64], refined: bool) -> dict[str, Any]:
        """`describe`'s `intervals`: central intervals of the returned estimate `label` (L,)
        at `INTERVAL_LEVELS`, lower and upper per column (`mixture.columns` order). The
        network's estimate: its mixture's marginal intervals. A refined estimate: the
        estimate +- k x the mixture's half-width, k from `refined_intervals.csv` beside the
        model (kinematics/intervals.py); none without that file (`of` says so)."""
        if refined and self.refined_scales is None:
            return {"of": "refined estimate: no refined_intervals.csv beside the model "
                          "(artic evaluate mdn writes one)", "levels": {}}  # fmt: skip
        levels: dict[str, dict[str, list[float]]] = {}
        for level, (lo, hi) in marginal_intervals(mix, INTERVAL_LEVELS).items():
            lower, upper = self.codec.decode(lo.numpy())[0], self.codec.decode(hi.numpy())[0]
            if refined:
                k = self._scale(level)
                if k is None:
                    continue
                lower, upper = (
                    b[0] for b in refined_interval(label[None], 0.5 * (upper - lower)[None], k)
                )
            levels[f"{level:g}"] = {"lower": lower.tolist(), "upper": upper.tolist()}
        of = "refined estimate: +- k x the mixture's half-width" if refined else "mixture"
        return {"of": of, "levels": levels}

    def _scale(self, level: float) -> NDArray[np.float64] | None:
        """The refined scales at `level` (a column the network does not learn, NaN: 0),
        None when the file has no such level."""
        for lv, k in (self.refined_scales or {}).items():
            if abs(lv - level) < 1e-9:
                return np.where(np.isnan(k), 0.0, k)
        return None

    def domain_warnings(
        self,
        label: NDArray[np.float64],
        weights: NDArray[np.float64],
        means: NDArray[np.float64],
        camera: CameraIntrinsics,
    ) -> list[str]:
        """One line per concern about an estimate `label` (L,) of an image seen by
        `camera`, with its mixture's weights (m,) and means (m, L) in label units (as
        `describe` prints them): (1) the estimate outside the training ranges (beyond
        `RANGE_TOLERANCE` of a range's width plus `RANGE_TOLERANCE_ABS`) or of a
        chirality the training data lacked; (2) `camera` not a training camera; (3) less
        than `SIDE_WEIGHT` of the mixture's weight on the estimate's hinge side. (1) needs
        the model's `domain`; (2) uses the training camera of any model."""
        out: list[str] = []
        col = {c: i for i, c in enumerate(self.codec.columns)}
        side = 1 if label[col["chirality"]] >= 0 else -1
        if self.domain is not None:
            value = {k: float(label[col[k]]) for k in self.domain.ranges if k in col}
            pose = [label[col[f"pose_{a}"]] for a in "xyz"]
            value["distance"] = float(np.linalg.norm(pose))
            outside = []
            for key, (lo, hi) in self.domain.ranges.items():
                tol = RANGE_TOLERANCE * (hi - lo) + RANGE_TOLERANCE_ABS
                if key in value and not lo - tol <= value[key] <= hi + tol:
                    unit = _unit(key, self.joint_type)
                    outside.append(f"{key} {value[key]:.3f} {unit} (trained {lo:.3f} to {hi:.3f})")
            if side not in self.domain.chiralities:
                outside.append(f"chirality {side:+d} (trained {self.domain.chiralities})")
            if outside:
                out.append(
                    "the estimate lies outside the training data: " + "; ".join(outside)
                    + " (an answer for an object unlike those trained on is unreliable)"
                )  # fmt: skip
        cameras = self.domain.cameras if self.domain is not None else [self.camera]
        if camera not in cameras:
            out.append(
                f"the image's camera ({_camera_text(camera)}) is not the training camera "
                f"({_camera_text(self.camera)}): the image was reprojected into it"
            )
        on_side = side_weight(side, weights, means, list(self.codec.columns))
        if on_side < SIDE_WEIGHT:
            out.append(
                f"the mixture is split between hinge sides: {on_side:.2f} of its weight on "
                f"chirality {side:+d} (the estimate's), {1 - on_side:.2f} on {-side:+d}"
            )
        return out


def predict_image(
    image: Path,
    category: str,
    camera: str,
    model: Path | None,
    mask: Path | None,
    samples: int,
    estimator: str,
    seed: int,
    started: float,
    refine: bool = True,
) -> dict[str, Any]:
    """Everything `artic predict` prints, as a dict: `describe` (with the geometric
    refinement when `refine`) of the depth image
    `image` (masked by `mask`, reprojected into the training camera when `camera`
    differs; `camera` a JSON file or a camera preset's name) with the category's model
    (`model`, else the store's choice: `artifacts.model_store.choose_model`), its inputs,
    warnings and timings since `started` (`time.perf_counter`)."""
    import time

    from artic.artifacts.depth_image import read_camera_arg_noting, read_depth, read_mask
    from artic.artifacts.model_store import choose_model
    from artic.geometry.camera import reproject
    from artic.kinematics import ESTIMATORS
    from artic.objects.categories import CATEGORIES

    if estimator not in ESTIMATORS:
        raise InputError(f"--estimator: '{estimator}' (available: {', '.join(ESTIMATORS)})")
    if category not in CATEGORIES:
        known = ", ".join(sorted(CATEGORIES))
        raise InputError(f"--category: unknown category '{category}' (available: {known})")
    depth = read_depth(image)
    cam, camera_notes = read_camera_arg_noting(camera)
    if depth.shape != (cam.height, cam.width):
        raise InputError(
            f"{camera}: intrinsics are for {cam.width}x{cam.height}, "
            f"{image} is {depth.shape[1]}x{depth.shape[0]}"
        )
    object_mask = read_mask(mask, depth.shape) if mask else None
    choice = choose_model("mdn", category, model, "--model")
    result_warnings = [choice.warning] if choice.warning else []
    result_warnings += camera_notes
    path = choice.path
    predictor = Predictor.load(path, category)
    reprojected = cam != predictor.camera
    if object_mask is not None:
        depth = np.where(object_mask, depth, 0).astype(np.float32)
        if not (depth > 0).any():
            raise InputError(f"{mask}: no valid depth pixel of {image} inside the mask")
    detail = None
    if reprojected:
        detail = (depth, cam)  # the handle, front and seam tests read it as taken
        depth = reproject(depth, cam, predictor.camera)
        if not (depth > 0).any():
            raise InputError(f"{image}: no pixel lands inside the training camera's view")
    t1 = time.perf_counter()
    result = predictor.describe(depth, None, estimator, samples, seed, refine, detail)  # type: ignore[arg-type]
    t2 = time.perf_counter()
    label = np.array([result["estimate"][c] for c in predictor.codec.columns])
    mixture = result["mixture"]
    result_warnings += predictor.domain_warnings(
        label, np.array(mixture["weights"]), np.array(mixture["means"]), cam
    )
    result["input"] = {
        "image": str(image),
        "model": str(path),
        "model_source": choice.source,  # given | local (artifacts/models/) | shipped
        "camera": camera if Path(camera).is_file() else f"preset {camera}",
        "reprojected_to_training_camera": bool(reprojected),
    }
    result["warnings"] = result_warnings
    for warning in result_warnings:  # once the answer is there: errors stay one line
        log.warning("predict: %s", warning)
    result["timing_s"] = {"load_and_prepare": round(t1 - started, 4), "predict": round(t2 - t1, 4)}
    return result
