"""The inputs of `artic predict`: one depth image (`.npy` float metres, or a 16-bit PNG
in millimetres; 0 = no return), an optional object mask (PNG or .npy, nonzero = object)
and the camera intrinsics (a preset's name, or a JSON file: fx, fy, cx, cy, width,
height, or the layouts of ROS and Open3D, `geometry.camera.camera_from_mapping`). Each
reader raises an `InputError` of one line naming the file.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError

log = logging.getLogger(__name__)

#: a depth image (metres) whose median return is farther than this is in millimetres
MAX_DEPTH_M = 20.0


def _first_line(err: BaseException) -> str:
    lines = str(err).strip().splitlines()
    return lines[0] if lines else type(err).__name__


def _load_npy(path: Path, what: str) -> NDArray[Any]:
    """An .npy array without pickles; InputError naming the file if it cannot be read
    (truncated, not an .npy, an object array)."""
    try:
        return np.asarray(np.load(path, allow_pickle=False))
    except (ValueError, OSError, EOFError) as err:
        raise InputError(f"{path}: not a readable .npy {what} ({_first_line(err)})") from None


def read_depth(path: Path) -> NDArray[np.float32]:
    """Depth in metres from `.npy` (float metres) or 16-bit PNG (millimetres)."""
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if path.suffix.lower() == ".npy":
        data = _load_npy(path, "depth image")
        if data.dtype.kind in "iu":
            raise InputError(
                f"{path}: .npy depth must be float metres, got {data.dtype} (millimetres? "
                "divide by 1000 and save as float32, or save a 16-bit .png in millimetres)"
            )
        if data.dtype.kind != "f":
            raise InputError(f"{path}: .npy depth must be float metres, got {data.dtype}")
        depth = data.astype(np.float32)
        returns = depth[np.isfinite(depth) & (depth > 0)]
        if returns.size and float(np.median(returns)) > MAX_DEPTH_M:
            raise InputError(
                f"{path}: .npy depth must be float metres, but its median is "
                f"{float(np.median(returns)):.0f} (> {MAX_DEPTH_M:.0f} m: millimetres?); "
                "divide by 1000"
            )
    elif path.suffix.lower() == ".png":
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(path) as image:
                if image.mode not in ("I;16", "I;16B", "I;16L", "I"):
                    raise InputError(
                        f"{path}: depth PNG must be 16-bit millimetres, got mode {image.mode}"
                    )
                depth = np.asarray(image, dtype=np.float32) * np.float32(0.001)
        except UnidentifiedImageError:
            raise InputError(f"{path}: not a readable PNG") from None
        except (OSError, SyntaxError, ValueError, EOFError) as err:  # truncated, corrupt
            raise InputError(f"{path}: not a readable PNG ({_first_line(err)})") from None
    else:
        raise InputError(
            f"{path}: expected a .npy (metres) or 16-bit .png (millimetres) depth image"
        )
    if depth.ndim != 2:
        raise InputError(f"{path}: depth must be one (H, W) image, got shape {depth.shape}")
    if np.isnan(depth).any() or np.isinf(depth).any():
        raise InputError(f"{path}: depth contains NaN or infinite values")
    if (depth < 0).any():
        raise InputError(f"{path}: depth contains negative values")
    if not (depth > 0).any():
        raise InputError(f"{path}: depth is all zeros (no returns)")
    return depth


def read_mask(path: Path, shape: tuple[int, ...]) -> NDArray[np.bool_]:
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    if path.suffix.lower() == ".npy":
        mask = _load_npy(path, "mask")
        if mask.dtype.kind not in "biuf":
            raise InputError(f"{path}: mask must be numeric or boolean, got {mask.dtype}")
    else:
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(path) as image:
                mask = np.asarray(image)
        except UnidentifiedImageError:
            raise InputError(f"{path}: not a readable mask image") from None
        except (OSError, SyntaxError, ValueError, EOFError) as err:  # truncated, corrupt
            raise InputError(f"{path}: not a readable mask image ({_first_line(err)})") from None
    if mask.ndim == 3:
        mask = mask[..., 0]
    if mask.shape != shape:
        raise InputError(f"{path}: mask is {mask.shape}, depth image is {shape}")
    inside = np.asarray(mask) != 0
    if not inside.any():
        raise InputError(f"{path}: the mask covers no pixel (nonzero = the object)")
    if inside.all():
        raise InputError(f"{path}: the mask covers every pixel (nonzero = the object only)")
    return inside


def camera_presets() -> dict[str, Path]:
    """The named cameras (`kinect_v1`, `thesis_sim`, ...): conf/common/camera/*.yaml."""
    from artic.config.compose import conf_dir

    return {p.stem: p for p in sorted((conf_dir() / "common" / "camera").glob("*.yaml"))}


def read_camera_arg(value: str) -> Any:
    """`--camera`: a camera preset's name, or a camera JSON file (`read_camera`).
    An existing file wins over a preset of the same name."""
    intrinsics, notes = read_camera_arg_noting(value)
    for note in notes:
        log.warning("%s", note)
    return intrinsics


def read_camera_arg_noting(value: str) -> tuple[Any, list[str]]:
    """`read_camera_arg` with the warning about the file's ignored fields returned (at
    most one line) instead of logged, for a caller that reports it with its answer."""
    import yaml

    from artic.geometry.camera import CameraIntrinsics

    path = Path(value)
    if path.is_file() or path.suffix.lower() in (".json", ".yaml", ".yml") or "/" in value:
        return read_camera_noting(path)
    presets = camera_presets()
    if value not in presets:
        raise InputError(
            f"--camera {value}: neither a JSON file nor a camera preset "
            f"(presets: {', '.join(presets)})"
        )
    return CameraIntrinsics.model_validate(yaml.safe_load(presets[value].read_text())), []


def read_camera(path: Path) -> Any:
    """`CameraIntrinsics` from a camera JSON file (or YAML: `.yaml`, `.yml`, as ROS
    camera_info files are) in any layout `camera_from_mapping` reads (artic's six
    fields, ROS CameraInfo `K`, ROS camera_info's `camera_matrix`, Open3D's
    `intrinsic_matrix`); fields it does not use are ignored with one warning line
    (logger `artic`) naming the file and them. Missing or invalid intrinsics:
    InputError "FILE: field FIELD: why"."""
    intrinsics, notes = read_camera_noting(path)
    for note in notes:
        log.warning("%s", note)
    return intrinsics


def read_camera_noting(path: Path) -> tuple[Any, list[str]]:
    """`read_camera` with the warning (at most one line) returned instead of logged."""
    import yaml

    from artic.geometry.camera import CameraFieldError, camera_from_mapping

    if not path.is_file():
        raise InputError(f"{path}: no such file")
    as_yaml = path.suffix.lower() in (".yaml", ".yml")  # ROS camera_info files are YAML
    try:
        text = path.read_text()
        read = camera_from_mapping(yaml.safe_load(text) if as_yaml else json.loads(text))
    except json.JSONDecodeError as err:
        raise InputError(f"{path}: not JSON ({err.msg})") from None
    except yaml.YAMLError as err:
        raise InputError(f"{path}: not YAML ({_first_line(err)})") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: not a readable camera file ({_first_line(err)})") from None
    except CameraFieldError as err:
        raise InputError(f"{path}: {err}") from None
    notes = []
    if read.ignored:
        notes.append(
            f"{path}: ignored field{'s' if len(read.ignored) > 1 else ''} "
            f"{', '.join(read.ignored)} (read {read.layout} intrinsics: "
            f"{', '.join(f'{k}={v}' for k, v in read.intrinsics.model_dump().items())})"
        )
    return read.intrinsics, notes
