"""Model files and checkpoints load with `weights_only=True`: a file holding anything but
tensors and plain data is refused (exit 2, one line naming it) without running any of
it; truncated or corrupt files are refused by name; what artic saves reads back exactly."""

from __future__ import annotations

import dataclasses
import io
import json
import pathlib
import pickle
import re
from pathlib import Path

import numpy as np
import pytest
import torch

from artic.artifacts.model_file import (
    FORMAT,
    load_model_file,
    load_torch_file,
    plain,
    save_model_file,
    save_torch_file,
)
from artic.artifacts.ply import write_ply
from artic.errors import InputError
from box_clouds import box_cloud
from cli_runner import run_cli

KIND = "kinematics-mdn"
UNSAFE = "not a safe artic model file (refused: contains objects other than tensors and plain data)"


class Payload:
    """Unpickled unsafely, creates the marker file: what a malicious model file does."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        return (pathlib.Path.touch, (pathlib.Path(self.marker),))


@dataclasses.dataclass
class Point:
    x: float


def evil_files(folder: Path, marker: Path) -> dict[str, Path]:
    """Files that run code when unpickled with weights_only=False."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {
        "torch zip": folder / "evil.pt",
        "plain pickle": folder / "evil.pkl",
        "hidden in meta": folder / "meta.pt",
    }
    torch.save(Payload(marker), files["torch zip"])
    with files["plain pickle"].open("wb") as f:
        pickle.dump(Payload(marker), f)
    model = {"format": FORMAT, "kind": KIND, "category": "microwave", "hparams": {},
             "state_dict": {}, "meta": {"codec": Payload(marker)}}  # fmt: skip
    torch.save(model, files["hidden in meta"])
    return files


def tiny_model_payload() -> tuple[dict[str, torch.Tensor], dict[str, object]]:
    torch.manual_seed(0)
    state = torch.nn.Linear(3, 2).state_dict()
    meta = {
        "codec": {"columns": ["a", "b"], "mean": [0.1 + 0.2, 1 / 3], "learned": [True, False]},
        "dof": 1,
        "shape": (2, 3),
        "none": None,
        "nested": [{"x": float("inf")}, [1, 2.5e-300]],
    }
    return state, meta


def test_model_file_round_trips_exactly_through_weights_only(tmp_path: Path) -> None:
    state, meta = tiny_model_payload()
    path = tmp_path / "model.pt"
    save_model_file(path, KIND, "microwave", {"width": 4}, state, meta)
    raw = torch.load(path, weights_only=True)  # plain torch can read it safely too
    assert raw["meta"] == meta and raw["hparams"] == {"width": 4}
    payload = load_model_file(path, KIND, "microwave")
    assert payload["meta"] == meta and payload["format"] == FORMAT
    assert list(payload["state_dict"]) == list(state)
    for name, tensor in state.items():
        assert torch.equal(payload["state_dict"][name], tensor)
    assert not list(tmp_path.glob("*.tmp"))


def test_plain_converts_numpy_exactly_and_refuses_objects() -> None:
    values = np.array([0.1, 1 / 3, np.pi, 5e-324], dtype=np.float64)
    out = plain({"a": values, "s": np.float64(1 / 3), "i": np.int64(7), "b": np.bool_(True),
                 "f32": np.float32(0.1), "t": (np.int64(1), [np.float64(2.5)])})  # fmt: skip
    assert out["a"] == values.tolist() and np.array_equal(np.asarray(out["a"]), values)
    assert type(out["s"]) is float and out["s"] == 1 / 3
    assert type(out["i"]) is int and type(out["b"]) is bool
    assert out["f32"] == float(np.float32(0.1)) and out["t"] == (1, [2.5])
    assert type(out["t"]) is tuple
    for bad, where in [
        ({"p": Point(1.0)}, "payload['p']: Point"),
        ({"path": [Path("x")]}, "payload['path'][0]: PosixPath"),
        ({"rng": np.random.default_rng(0)}, "payload['rng']: Generator"),
        ({(1, 2): 3}, "key (1, 2)"),
        ({"ld": np.longdouble(1)}, "payload['ld']: longdouble"),
        ({"s": np.array(["a"])}, "payload['s']: ndarray"),
    ]:
        with pytest.raises(TypeError, match=re.escape(where)):
            plain(bad)


def test_saving_an_unsafe_payload_is_a_programming_error(tmp_path: Path) -> None:
    state, _ = tiny_model_payload()
    with pytest.raises(TypeError, match=r"meta.*Point"):
        save_model_file(tmp_path / "m.pt", KIND, "microwave", {}, state, {"x": Point(1.0)})
    assert not list(tmp_path.iterdir())


def test_unsafe_files_are_refused_without_running_them(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    for name, path in evil_files(tmp_path / "files", marker).items():
        with pytest.raises(InputError) as err:
            load_model_file(path, KIND, "microwave")
        assert str(err.value) == f"{path}: {UNSAFE}", name
        with pytest.raises(InputError, match="not a safe artic checkpoint"):
            load_torch_file(path, "checkpoint")
        assert not marker.exists(), name
    # the test files are really malicious: an unsafe load runs them
    torch.load(tmp_path / "files" / "evil.pt", weights_only=False)
    assert marker.exists()


def test_old_model_with_numpy_arrays_is_refused_by_name(tmp_path: Path) -> None:
    state, meta = tiny_model_payload()
    path = tmp_path / "old.pt"
    old = {"format": FORMAT, "kind": KIND, "category": "microwave", "hparams": {},
           "state_dict": state, "meta": meta | {"mean": np.zeros(3)}}  # fmt: skip
    torch.save(old, path)
    with pytest.raises(InputError, match=f"{path}: not a safe artic model file"):
        load_model_file(path, KIND)


def test_truncated_and_corrupt_files_are_refused_by_name(tmp_path: Path) -> None:
    state, meta = tiny_model_payload()
    good = tmp_path / "good.pt"
    save_model_file(good, KIND, "microwave", {}, state, meta)
    data = good.read_bytes()
    cases = {
        "truncated.pt": data[: len(data) // 2],
        "garbage.pt": b"not a model at all",
        "empty.pt": b"",
        "flipped.pt": data[:200] + bytes(b ^ 0xFF for b in data[200:400]) + data[400:],
    }
    for name, content in cases.items():
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(InputError) as err:
            load_model_file(path, KIND)
        message = str(err.value)
        assert message.startswith(f"{path}: not a ") and "\n" not in message, (name, message)
        with pytest.raises(InputError, match=f"{path}: not a"):
            load_torch_file(path, "checkpoint")
    (tmp_path / "list.pt").write_bytes(torch_bytes([1, 2]))
    with pytest.raises(InputError, match="not an artic model file"):
        load_model_file(tmp_path / "list.pt", KIND)


def torch_bytes(value: object) -> bytes:
    buffer = io.BytesIO()
    torch.save(value, buffer)
    return buffer.getvalue()


def test_checkpoint_round_trip_keeps_state_dicts_and_rng_state(tmp_path: Path) -> None:
    model = torch.nn.Sequential(torch.nn.Linear(2, 3), torch.nn.BatchNorm1d(3))
    optimizer = torch.optim.Adam(model.parameters())
    model(torch.randn(4, 2)).sum().backward()
    optimizer.step()
    rng = np.random.default_rng(5)
    rng.random(3)
    weights = np.random.default_rng(1).standard_normal(4)
    payload = {
        "model": model.state_dict(),
        "optimizer": optimizer.state_dict(),
        "numpy_rng": rng.bit_generator.state,
        "torch_rng": torch.get_rng_state(),
        "weights": torch.from_numpy(weights),
        "rows": [[0, 1, np.float64(0.1)]],
    }
    path = tmp_path / "state.pt"
    save_torch_file(path, payload)
    back = load_torch_file(path, "checkpoint")
    assert back["model"]._metadata == model.state_dict()._metadata
    fresh = torch.nn.Sequential(torch.nn.Linear(2, 3), torch.nn.BatchNorm1d(3))
    fresh.load_state_dict(back["model"])
    torch.optim.Adam(fresh.parameters()).load_state_dict(back["optimizer"])
    assert back["optimizer"]["param_groups"] == optimizer.state_dict()["param_groups"]
    restored = np.random.default_rng()
    restored.bit_generator.state = back["numpy_rng"]
    assert np.array_equal(restored.random(5), rng.random(5))
    assert torch.equal(back["torch_rng"], payload["torch_rng"])
    assert back["weights"].numpy().tobytes() == weights.tobytes()
    assert back["rows"] == [[0, 1, 0.1]] and type(back["rows"][0][2]) is float


@pytest.fixture
def depth_image(tmp_path: Path) -> tuple[Path, Path]:
    depth = tmp_path / "depth.npy"
    np.save(depth, np.full((32, 32), 1.0, dtype=np.float32))
    camera = tmp_path / "camera.json"
    camera.write_text(json.dumps({"fx": 30.0, "fy": 30.0, "cx": 15.5, "cy": 15.5,
                                  "width": 32, "height": 32}))  # fmt: skip
    return depth, camera


def test_predict_refuses_a_malicious_model_with_exit_2(tmp_path: Path, depth_image) -> None:
    depth, camera = depth_image
    marker = tmp_path / "pwned"
    for name, path in evil_files(tmp_path / "files", marker).items():
        code, _, err = run_cli("predict", str(depth), "--category", "microwave",
                               "--camera", str(camera), "--model", str(path))  # fmt: skip
        lines = err.strip().splitlines()
        assert code == 2, (name, err)
        assert lines == [f"error: {path}: {UNSAFE}"], (name, err)
        assert not marker.exists(), name


def test_predict_refuses_a_truncated_model_with_exit_2(tmp_path: Path, depth_image) -> None:
    depth, camera = depth_image
    state, meta = tiny_model_payload()
    path = tmp_path / "model.pt"
    save_model_file(path, KIND, "microwave", {}, state, meta)
    path.write_bytes(path.read_bytes()[:-100])
    code, _, err = run_cli("predict", str(depth), "--category", "microwave",
                           "--camera", str(camera), "--model", str(path))  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{path}: not a readable model file" in err and "Traceback" not in err


def test_infer_hierarchy_refuses_a_malicious_segmenter_with_exit_2(tmp_path: Path) -> None:
    scan = tmp_path / "cabinet.ply"
    points, part = box_cloud(600)
    write_ply(scan, points, part_id=part)
    marker = tmp_path / "pwned"
    evil = evil_files(tmp_path / "files", marker)["torch zip"]
    out = tmp_path / "out"
    code, _, err = run_cli("infer-hierarchy", str(scan), "--out", str(out),
                           "--segmenter", str(evil), "--labeller", str(evil))  # fmt: skip
    assert code == 2, err
    assert err.strip().splitlines() == [f"error: {evil}: {UNSAFE}"], err
    assert not marker.exists()
    assert not out.exists() and not out.with_name("out.partial").exists()
