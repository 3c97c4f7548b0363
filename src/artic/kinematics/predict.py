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
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from artic.errors import InputError
from artic.geometry.camera import CameraIntrinsics
from artic.kinematics import Estimator
from artic.kinematics.config import MDN_KIND, MdnModelMeta
from artic.kinematics.mdn import KinematicsMDN, Mixture, densest, most_likely, sample
from artic.kinematics.preprocess import InputPipeline
from artic.kinematics.targets import TargetCodec
from artic.objects.labels import joint_column, joint_vector

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Predictor:
    category: str
    model: KinematicsMDN
    codec: TargetCodec
    camera: CameraIntrinsics
    dof: int
    joint_type: str

    @classmethod
    def load(cls, path: Path, category: str | None = None) -> Predictor:
        """From a `train-mdn` model file (of `category` when given); InputError naming the
        file when it is of another kind, category or format."""
        from artic.artifacts.model_file import load_model_file

        return cls.from_payload(load_model_file(path, MDN_KIND, category), path)

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
    ) -> dict[str, Any]:
        """The JSON `artic predict` prints (see docs/kinematics.md)."""
        mix = self.mixture(depth, mask)
        label = self._estimate(mix, depth, mask, estimator)
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
        }
        if samples > 0:
            draws = sample(mix, samples, torch.Generator().manual_seed(seed))
            out["samples"] = self.codec.decode(draws[0].numpy()).tolist()
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
) -> dict[str, Any]:
    """Everything `artic predict` prints, as a dict: `describe` of the depth image
    `image` (masked by `mask`, reprojected into the training camera when `camera`
    differs; `camera` a JSON file or a camera preset's name) with the category's model
    (`model`, else the store's choice: `artifacts.model_store.choose_model`), its inputs,
    warnings and timings since `started` (`time.perf_counter`)."""
    import time

    from artic.artifacts.depth_image import read_camera_arg, read_depth, read_mask
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
    cam = read_camera_arg(camera)
    result_warnings: list[str] = []
    if depth.shape != (cam.height, cam.width):
        raise InputError(
            f"{camera}: intrinsics are for {cam.width}x{cam.height}, "
            f"{image} is {depth.shape[1]}x{depth.shape[0]}"
        )
    object_mask = read_mask(mask, depth.shape) if mask else None
    choice = choose_model("mdn", category, model, "--model")
    if choice.warning:
        result_warnings.append(choice.warning)
    path = choice.path
    predictor = Predictor.load(path, category)
    reprojected = cam != predictor.camera
    if object_mask is not None:
        depth = np.where(object_mask, depth, 0).astype(np.float32)
    if reprojected:
        depth = reproject(depth, cam, predictor.camera)
        if not (depth > 0).any():
            raise InputError(f"{image}: no pixel lands inside the training camera's view")
    t1 = time.perf_counter()
    result = predictor.describe(depth, None, estimator, samples, seed)  # type: ignore[arg-type]
    t2 = time.perf_counter()
    result["input"] = {
        "image": str(image),
        "model": str(path),
        "model_source": choice.source,  # given | local (artifacts/models/) | shipped
        "camera": camera if Path(camera).is_file() else f"preset {camera}",
        "reprojected_to_training_camera": bool(reprojected),
    }
    if result_warnings:
        result["warnings"] = result_warnings
        for warning in result_warnings:  # once the answer is there: errors stay one line
            log.warning("predict: %s", warning)
    result["timing_s"] = {"load_and_prepare": round(t1 - started, 4), "predict": round(t2 - t1, 4)}
    return result
