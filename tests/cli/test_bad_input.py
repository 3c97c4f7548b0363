"""Bad input over every subcommand (issue 15, "Errors" in README.md): exit code 2, exactly
one non-empty line on stderr naming the field or the file, no traceback anywhere, and
nothing left behind (no output folder, no `<out>.partial/`, no file under the test's
folder that was not there before). Then the internal-error contract (one line, the
traceback in a log file) and valid unusual input (unicode and spaces in paths, a
millimetre cloud with --scale auto, 5 million points).

Each case builds its input files under `tmp_path/in/` and returns the command line and a
fragment the one stderr line must contain; the CLI runs in-process (`run_cli`) with the
working directory at `tmp_path`, so default output folders would show up in the listing.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from artic.artifacts.formats import write_json, write_npz
from artic.artifacts.manifest import MANIFEST, list_outputs, outputs_hash
from artic.artifacts.ply import read_ply, write_ply
from box_clouds import box_cloud
from cli_runner import run_cli
from fake_outputs import write_manifest

# --------------------------------------------------------------------------- inputs


@dataclass
class Env:
    """What a case may use: its folder, the session's tiny datasets, file makers."""

    tmp: Path
    request: pytest.FixtureRequest

    @property
    def inputs(self) -> Path:
        path = self.tmp / "in"
        path.mkdir(exist_ok=True)
        return path

    @property
    def out(self) -> str:
        return f"out={self.tmp / 'out'}"

    @property
    def objects(self) -> Path:
        return Path(self.request.getfixturevalue("tiny_objects"))

    @property
    def depth(self) -> Path:
        return Path(self.request.getfixturevalue("tiny_depth"))

    @property
    def hierarchy_objects(self) -> Path:
        return Path(self.request.getfixturevalue("tiny_hierarchy_objects"))

    def file(self, name: str, data: bytes | str) -> Path:
        path = self.inputs / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data.encode() if isinstance(data, str) else data)
        return path

    def npy(self, name: str, array: np.ndarray) -> Path:
        path = self.inputs / name
        np.save(path, array)
        return path

    def ply(self, name: str, points: np.ndarray, part: np.ndarray | None = None) -> Path:
        path = self.inputs / name
        write_ply(path, points, part_id=part)
        return path

    def forged(self, src: Path, name: str, change: Callable[[Path], None]) -> Path:
        """A copy of stage output `src` with `change` applied and its manifest's file
        list updated to match, so that only the reader can notice what is wrong."""
        folder = self.inputs / name
        shutil.copytree(src, folder)
        change(folder)
        manifest = json.loads((folder / MANIFEST).read_text())
        outputs = list_outputs(folder)
        manifest["outputs"] = {k: v.model_dump() for k, v in outputs.items()}
        manifest["content_hash"] = outputs_hash(outputs)
        write_json(folder / MANIFEST, manifest)
        return folder

    def demos(self, name: str, task: str = "drawer", corrupt: bool = False) -> Path:
        """A plan-demos output folder with two demos (the first one garbage if `corrupt`)."""
        folder = self.inputs / name
        folder.mkdir()
        entries = []
        for k in range(2):
            t = np.arange(12) * 0.05
            q = np.tile(np.linspace(0, 0.5, 12)[:, None], (1, 7))
            arrays = {"t": t, "q_robot": q, "qd_robot": np.gradient(q, axis=0) / 0.05}
            arrays |= {"q_object": np.linspace(0, 0.2, 12)[:, None], "ee_pose": np.zeros((12, 7))}
            write_npz(folder / f"demo_{k:03d}.npz", arrays)
            entries.append({"index": k, "file": f"demo_{k:03d}.npz", "status": "ok",
                            "reason": "", "planning_time_s": 0.1, "steps": 12})  # fmt: skip
        if corrupt:
            (folder / "demo_000.npz").write_bytes(b"PK\x03\x04 this is not a zip archive")
        write_json(folder / "demos.json", {
            "task": task, "n_requested": 2, "control_dt": 0.05, "n_joints": 7,
            "kinematic_model": {"source": "true"}, "planner": "RRTConnect", "demos": entries,
        })  # fmt: skip
        write_manifest(folder, "plan-demos", {"task": {"name": task}, "out": str(folder)})
        return folder

    def camera(self) -> Path:
        """Intrinsics of the tiny depth images (64x64)."""
        info = json.loads((self.depth / "dataset.json").read_text())
        return self.file("camera.json", json.dumps(info["camera"]))

    def depth_image(self) -> np.ndarray:
        """A valid depth image in metres, the camera's size."""
        info = json.loads((self.depth / "dataset.json").read_text())
        h, w = info["camera"]["height"], info["camera"]["width"]
        image = np.zeros((h, w), np.float32)
        image[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4] = 1.5
        return image

    def predict(self, image: Path, *extra: str) -> list[str]:
        """`artic predict IMAGE` with the tiny camera and a model file that must not be
        opened (every check of the image, mask and camera comes first)."""
        model = self.file("model.pt", b"never read")
        return ["predict", str(image), "--category", "microwave", "--camera",
                str(self.camera()), "--model", str(model), *extra]  # fmt: skip


@pytest.fixture(scope="session")
def tiny_hierarchy_objects(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """generate-dataset dataset=hierarchy debug=tiny: objects with 18 poses each."""
    out = tmp_path_factory.mktemp("hier") / "storage_furniture"
    code, _, err = run_cli(
        "generate-dataset", "debug=tiny", "dataset=hierarchy", "category=storage_furniture",
        f"out={out}",
    )  # fmt: skip
    assert code == 0, err
    return out


def _cloud(n: int = 3000) -> np.ndarray:
    return box_cloud(n)[0]


def _truncated_png(env: Env, name: str, mode: str = "I;16") -> Path:
    path = env.inputs / name
    data = (env.depth_image() * 1000).astype(np.uint16)
    Image.fromarray(data if mode == "I;16" else (data > 0).astype(np.uint8) * 255).save(path)
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])
    return path


def _png8(env: Env) -> Path:
    path = env.inputs / "grey.png"
    Image.fromarray((env.depth_image() > 0).astype(np.uint8) * 200).save(path)
    return path


def _truncated_npy(env: Env, name: str, array: np.ndarray) -> Path:
    path = env.npy(name, array)
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])
    return path


def _garbage(path: Path) -> None:
    path.write_bytes(b"PK\x03\x04" + os.urandom(64))


def _bad_pipeline(env: Env, text: str) -> Path:
    return env.file("pipe.yaml", text)


# --------------------------------------------------------------------------- the cases

Build = Callable[[Env], tuple[list[str], str]]
CASES: dict[str, Build] = {
    # generate-dataset
    "gen/unknown category": lambda e: (["generate-dataset", "category=sofa", e.out], "sofa"),
    "gen/negative objects": lambda e: (
        ["generate-dataset", "dataset.objects=-5", e.out], "dataset.objects"),
    "gen/objects not a number": lambda e: (
        ["generate-dataset", "dataset.objects=many", e.out], "dataset.objects"),
    "gen/unknown key": lambda e: (["generate-dataset", "no_such_key=1", e.out], "no_such_key"),
    "gen/shard index >= count": lambda e: (
        ["generate-dataset", "shard.index=3", "shard.count=2", e.out], "shard"),
    "gen/negative seed": lambda e: (["generate-dataset", "seed=-1", e.out], "seed"),
    "gen/negative workers": lambda e: (
        ["generate-dataset", "runtime.workers=-1", e.out], "runtime.workers"),
    "gen/min > max": lambda e: (
        ["generate-dataset", "category.geometry.depth=[0.6,0.5]", e.out],
        "category.geometry.depth"),
    "gen/unknown dataset group": lambda e: (
        ["generate-dataset", "dataset=nonesuch", e.out], "nonesuch"),
    "gen/unknown debug group": lambda e: (
        ["generate-dataset", "debug=huge", e.out], "debug"),
    "gen/out is a file": lambda e: (
        ["generate-dataset", "debug=tiny", f"out={e.file('taken.txt', 'mine')}"], "taken.txt"),
    # render-depth
    "depth/no dataset": lambda e: (["render-depth", e.out], "dataset"),
    "depth/missing dataset": lambda e: (
        ["render-depth", f"dataset={e.tmp / 'absent'}", e.out], "absent"),
    "depth/empty folder": lambda e: (
        ["render-depth", f"dataset={e.inputs}", e.out], "not a stage output"),
    "depth/dataset is a file": lambda e: (
        ["render-depth", f"dataset={e.file('x.txt', 'x')}", e.out], "x.txt"),
    "depth/wrong stage": lambda e: (
        ["render-depth", f"dataset={e.depth}", e.out], "render-depth"),
    "depth/malformed manifest": lambda e: (
        ["render-depth", f"dataset={e.file('m/manifest.json', '{').parent}", e.out],
        "manifest.json"),
    "depth/zero configurations": lambda e: (
        ["render-depth", f"dataset={e.objects}", "render.configurations=0", e.out],
        "render.configurations"),
    "depth/unknown backend": lambda e: (
        ["render-depth", f"dataset={e.objects}", "render.backend=mitsuba", e.out],
        "render.backend"),
    "depth/unknown encoding": lambda e: (
        ["render-depth", f"dataset={e.objects}", "render.depth_encoding=png", e.out],
        "render.depth_encoding"),
    "depth/unknown camera": lambda e: (
        ["render-depth", f"dataset={e.objects}", "camera=hubble", e.out], "hubble"),
    "depth/unknown noise": lambda e: (
        ["render-depth", f"dataset={e.objects}", "noise=loud", e.out], "loud"),
    "depth/corrupt spec.json": lambda e: (
        ["render-depth", "debug=tiny", e.out, "dataset=" + str(e.forged(
            e.objects, "objs", lambda f: (f / "objects/000000/spec.json").write_text("{")))],
        "000000/spec.json"),
    "depth/corrupt urdf": lambda e: (
        ["render-depth", "debug=tiny", "render.backend=pybullet", e.out, "dataset=" + str(
            e.forged(e.objects, "objs", lambda f: (f / "objects/000000/object.urdf")
                     .write_text("<robot name='x'><link")))],
        "000000/object.urdf"),
    "depth/malformed index.csv": lambda e: (
        ["render-depth", "debug=tiny", e.out, "dataset=" + str(e.forged(
            e.objects, "objs", lambda f: (f / "index.csv").write_text(
                "object_id,split,category,dof,chirality\nzero,train,microwave,1,1\n")))],
        "index.csv"),
    # render-depth render=scan
    "scan/missing dataset": lambda e: (
        ["render-depth", "render=scan", f"dataset={e.tmp / 'absent'}", e.out], "absent"),
    "scan/wrong stage": lambda e: (
        ["render-depth", "render=scan", f"dataset={e.depth}", e.out], "render-depth"),
    "scan/more poses than the dataset has": lambda e: (
        ["render-depth", "render=scan", "debug=tiny", f"dataset={e.hierarchy_objects}",
         "render.configurations=30", e.out], "render.configurations"),
    "scan/zero views": lambda e: (
        ["render-depth", "render=scan", f"dataset={e.objects}", "render.views.views=0", e.out],
        "render.views.views"),
    "scan/negative clean points": lambda e: (
        ["render-depth", "render=scan", f"dataset={e.objects}", "render.clean_points=-1",
         e.out], "render.clean_points"),
    "scan/pybullet backend": lambda e: (
        ["render-depth", "render=scan", f"dataset={e.objects}", "render.backend=pybullet",
         e.out], "render.backend"),
    "scan/unknown key": lambda e: (
        ["render-depth", "render=scan", f"dataset={e.objects}", "render.colour=red", e.out],
        "colour"),
    # train-mdn
    "mdn/missing depth": lambda e: (
        ["train-mdn", f"depth={e.tmp / 'absent'}", e.out], "absent"),
    "mdn/objects as depth": lambda e: (
        ["train-mdn", f"depth={e.objects}", e.out], "generate-dataset"),
    "mdn/other category": lambda e: (
        ["train-mdn", "category=drawer", f"depth={e.depth}", e.out], "not drawer"),
    "mdn/zero epochs": lambda e: (
        ["train-mdn", f"depth={e.depth}", "train.epochs=0", e.out], "train.epochs"),
    "mdn/negative lr": lambda e: (
        ["train-mdn", f"depth={e.depth}", "train.lr=-1", e.out], "train.lr"),
    "mdn/unknown device": lambda e: (
        ["train-mdn", f"depth={e.depth}", "train.device=tpu", e.out], "train.device"),
    "mdn/components not a number": lambda e: (
        ["train-mdn", f"depth={e.depth}", "model.components=abc", e.out], "model.components"),
    "mdn/val_every 1": lambda e: (
        ["train-mdn", f"depth={e.depth}", "train.val_every=1", e.out], "train.val_every"),
    "mdn/unknown schedule": lambda e: (
        ["train-mdn", f"depth={e.depth}", "train.schedule=linear", e.out], "train.schedule"),
    "mdn/corrupt shard": lambda e: (
        ["train-mdn", "debug=tiny", e.out, "depth=" + str(e.forged(
            e.depth, "dep", lambda f: _garbage(f / "shards/shard-00000.npz")))],
        "shard-00000.npz"),
    "mdn/malformed dataset.json": lambda e: (
        ["train-mdn", "debug=tiny", e.out, "depth=" + str(e.forged(
            e.depth, "dep", lambda f: (f / "dataset.json").write_text("[1, 2")))],
        "dataset.json"),
    # evaluate mdn
    "evaluate mdn/missing model": lambda e: (
        ["evaluate", "mdn", f"depth={e.depth}", f"model={e.tmp / 'absent'}", e.out], "absent"),
    "evaluate mdn/depth as model": lambda e: (
        ["evaluate", "mdn", f"depth={e.depth}", f"model={e.depth}", e.out], "model"),
    "evaluate mdn/missing depth": lambda e: (
        ["evaluate", "mdn", f"depth={e.tmp / 'absent'}", e.out], "absent"),
    "evaluate mdn/level 1.5": lambda e: (
        ["evaluate", "mdn", "evaluate.levels=[1.5]", e.out], "evaluate.levels"),
    "evaluate mdn/level 0": lambda e: (
        ["evaluate", "mdn", "evaluate.levels=[0.5,0]", e.out], "evaluate.levels"),
    "evaluate mdn/no levels": lambda e: (
        ["evaluate", "mdn", "evaluate.levels=[]", e.out], "evaluate.levels"),
    "evaluate mdn/negative icp images": lambda e: (
        ["evaluate", "mdn", "evaluate.icp_images=-1", e.out], "evaluate.icp_images"),
    "evaluate mdn/zero batch": lambda e: (
        ["evaluate", "mdn", "evaluate.batch_size=0", e.out], "evaluate.batch_size"),
    "evaluate mdn/other objects": lambda e: (
        ["evaluate", "mdn", f"depth={e.depth}", e.out, "objects=" + str(e.forged(
            e.objects, "other", lambda f: (f / "objects/000000/spec.json").write_text("{}")))],
        "is not the dataset"),
    "evaluate mdn/missing objects": lambda e: (
        ["evaluate", "mdn", f"depth={e.depth}", f"objects={e.tmp / 'absent'}", e.out],
        "absent"),
    "evaluate mdn/depth as objects": lambda e: (
        ["evaluate", "mdn", f"depth={e.depth}", f"objects={e.depth}", e.out], "objects"),
    # train-segmenter
    "segmenter/missing scans": lambda e: (
        ["train-segmenter", f"scans={e.tmp / 'absent'}", e.out], "absent"),
    "segmenter/objects as scans": lambda e: (
        ["train-segmenter", f"scans={e.objects}", e.out], "generate-dataset"),
    "segmenter/depth as scans": lambda e: (
        ["train-segmenter", f"scans={e.depth}", e.out], "render-depth"),
    "segmenter/unknown category": lambda e: (
        ["train-segmenter", "category=sofa", e.out], "sofa"),
    "segmenter/zero epochs": lambda e: (
        ["train-segmenter", "train.epochs=0", e.out], "train.epochs"),
    "segmenter/unknown norm": lambda e: (
        ["train-segmenter", "model.norm=group", e.out], "model.norm"),
    # train-hierarchy
    "hierarchy/missing scans": lambda e: (
        ["train-hierarchy", f"scans={e.tmp / 'absent'}", e.out], "absent"),
    "hierarchy/objects as scans": lambda e: (
        ["train-hierarchy", f"scans={e.objects}", e.out], "generate-dataset"),
    "hierarchy/unknown key": lambda e: (
        ["train-hierarchy", "model.depth_of_field=3", e.out], "depth_of_field"),
    "hierarchy/zero layers": lambda e: (
        ["train-hierarchy", "model.num_layers=0", e.out], "model.num_layers"),
    "hierarchy/unknown category": lambda e: (
        ["train-hierarchy", "category=lamp_post", e.out], "lamp_post"),
    # evaluate hierarchy
    "evaluate hierarchy/missing scans": lambda e: (
        ["evaluate", "hierarchy", f"scans={e.tmp / 'absent'}", e.out], "absent"),
    "evaluate hierarchy/depth as scans": lambda e: (
        ["evaluate", "hierarchy", f"scans={e.depth}", e.out], "render-depth"),
    "evaluate hierarchy/iou above 1": lambda e: (
        ["evaluate", "hierarchy", "evaluate.iou_threshold=1.5", e.out],
        "evaluate.iou_threshold"),
    "evaluate hierarchy/unknown kind": lambda e: (
        ["evaluate", "hierarchy", "evaluate.kinds=[blurry]", e.out], "evaluate.kinds"),
    "evaluate hierarchy/zero objects per chunk": lambda e: (
        ["evaluate", "hierarchy", "evaluate.objects_per_chunk=0", e.out],
        "evaluate.objects_per_chunk"),
    # plan-demos
    "plan/unknown task": lambda e: (["plan-demos", "task=sofa", e.out], "sofa"),
    "plan/unknown --task": lambda e: (["plan-demos", "--task", "sofa", e.out], "sofa"),
    "plan/two tasks": lambda e: (
        ["plan-demos", "task=tball", "--task", "drawer", e.out], "--task drawer"),
    "plan/zero demos": lambda e: (["plan-demos", "demos.count=0", e.out], "demos.count"),
    "plan/unknown model source": lambda e: (
        ["plan-demos", "model.source=guess", e.out], "model.source"),
    "plan/unknown planner": lambda e: (
        ["plan-demos", "planner.name=prm", e.out], "planner.name"),
    "plan/negative time budget": lambda e: (
        ["plan-demos", "planner.time_budget_s=-1", e.out], "planner.time_budget_s"),
    # fit-dmp
    "dmp/missing demos": lambda e: (["fit-dmp", f"demos={e.tmp / 'absent'}", e.out], "absent"),
    "dmp/objects as demos": lambda e: (
        ["fit-dmp", f"demos={e.objects}", e.out], "generate-dataset"),
    "dmp/zero max demos": lambda e: (["fit-dmp", "max_demos=0", e.out], "max_demos"),
    "dmp/zero basis": lambda e: (["fit-dmp", "dmp.n_basis=0", e.out], "dmp.n_basis"),
    "dmp/demos of another task": lambda e: (
        ["fit-dmp", "task=microwave", f"demos={e.demos('d', 'drawer')}", e.out], "drawer"),
    "dmp/corrupt demo file": lambda e: (
        ["fit-dmp", "debug=tiny", "task=drawer", f"demos={e.demos('d', corrupt=True)}", e.out],
        "demo_000.npz"),
    "dmp/two tasks": lambda e: (
        ["fit-dmp", "task=tball", "--task", "drawer", e.out], "task=tball"),
    # policy-search
    "policy/unknown init": lambda e: (["policy-search", "init=lucky", e.out], "init"),
    "policy/unknown algorithm": lambda e: (
        ["policy-search", "algorithm=sgd", e.out], "algorithm"),
    "policy/missing dmp": lambda e: (
        ["policy-search", "--task", "drawer", f"dmp={e.tmp / 'absent'}", e.out], "absent"),
    "policy/objects as dmp": lambda e: (
        ["policy-search", "--task", "drawer", f"dmp={e.objects}", e.out], "generate-dataset"),
    "policy/zero seeds": lambda e: (["policy-search", "seeds=0", e.out], "seeds"),
    "policy/negative updates": lambda e: (["policy-search", "updates=-1", e.out], "updates"),
    "policy/unknown --task": lambda e: (["policy-search", "--task", "sofa", e.out], "sofa"),
    # evaluate bootstrap
    "evaluate bootstrap/missing runs": lambda e: (
        ["evaluate", "bootstrap", f"bootstrap={e.tmp / 'absent'}", e.out], "absent"),
    "evaluate bootstrap/objects as runs": lambda e: (
        ["evaluate", "bootstrap", f"bootstrap={e.objects}", e.out], "generate-dataset"),
    "evaluate bootstrap/zero episodes": lambda e: (
        ["evaluate", "bootstrap", "episodes=0", e.out], "episodes"),
    "evaluate bootstrap/fraction above 1": lambda e: (
        ["evaluate", "bootstrap", "reach_fraction=2", e.out], "reach_fraction"),
    "evaluate bootstrap/two tasks": lambda e: (
        ["evaluate", "bootstrap", "task=tball", "--task", "drawer", e.out], "task=tball"),
    # predict
    "predict/missing image": lambda e: (e.predict(e.tmp / "absent.npy"), "absent.npy"),
    "predict/empty image": lambda e: (e.predict(e.file("empty.npy", b"")), "empty.npy"),
    "predict/truncated npy": lambda e: (
        e.predict(_truncated_npy(e, "cut.npy", e.depth_image())), "cut.npy"),
    "predict/truncated png": lambda e: (e.predict(_truncated_png(e, "cut.png")), "cut.png"),
    "predict/8-bit png": lambda e: (e.predict(_png8(e)), "16-bit"),
    "predict/text as png": lambda e: (e.predict(e.file("fake.png", "hello")), "fake.png"),
    "predict/millimetre npy (integers)": lambda e: (
        e.predict(e.npy("mm.npy", (e.depth_image() * 1000).astype(np.uint16))), "metres"),
    "predict/millimetre npy (floats)": lambda e: (
        e.predict(e.npy("mmf.npy", e.depth_image() * 1000)), "millimetres"),
    "predict/NaN depth": lambda e: (
        e.predict(e.npy("nan.npy", np.full((64, 64), np.nan, np.float32))), "NaN"),
    "predict/negative depth": lambda e: (
        e.predict(e.npy("neg.npy", -e.depth_image())), "negative"),
    "predict/3-D depth": lambda e: (
        e.predict(e.npy("cube.npy", np.ones((2, 64, 64), np.float32))), "cube.npy"),
    "predict/wrong size": lambda e: (
        e.predict(e.npy("small.npy", np.ones((32, 64), np.float32))), "camera.json"),
    "predict/unknown suffix": lambda e: (e.predict(e.file("d.tiff", "x")), "d.tiff"),
    "predict/truncated mask npy": lambda e: (
        e.predict(e.npy("d.npy", e.depth_image()), "--mask",
                  str(_truncated_npy(e, "mask.npy", np.ones((64, 64), np.uint8)))), "mask.npy"),
    "predict/truncated mask png": lambda e: (
        e.predict(e.npy("d.npy", e.depth_image()), "--mask",
                  str(_truncated_png(e, "mask.png", "L"))), "mask.png"),
    "predict/mask of another size": lambda e: (
        e.predict(e.npy("d.npy", e.depth_image()), "--mask",
                  str(e.npy("m.npy", np.ones((8, 8), np.uint8)))), "m.npy"),
    "predict/camera not json": lambda e: (
        ["predict", str(e.npy("d.npy", e.depth_image())), "--category", "microwave",
         "--camera", str(e.file("cam.json", "{fx")), "--model", str(e.file("m.pt", "x"))],
        "cam.json"),
    "predict/camera without fx": lambda e: (
        ["predict", str(e.npy("d.npy", e.depth_image())), "--category", "microwave",
         "--camera", str(e.file("cam.json", '{"fy": 1}')), "--model", str(e.file("m.pt", "x"))],
        "cam.json"),
    "predict/unknown category": lambda e: (
        [*e.predict(e.npy("d.npy", e.depth_image()))[:2], "--category", "sofa", "--camera",
         str(e.camera())], "sofa"),
    "predict/unknown estimator": lambda e: (
        e.predict(e.npy("d.npy", e.depth_image()), "--estimator", "mode"), "--estimator"),
    "predict/negative samples": lambda e: (
        e.predict(e.npy("d.npy", e.depth_image()), "--samples", "-1"), "--samples"),
    # segment
    "segment/missing scan": lambda e: (["segment", str(e.tmp / "absent.ply")], "absent.ply"),
    "segment/empty scan": lambda e: (["segment", str(e.file("e.ply", b""))], "e.ply"),
    "segment/text as ply": lambda e: (["segment", str(e.file("t.ply", "hello\n"))], "t.ply"),
    "segment/NaN point": lambda e: (
        ["segment", str(e.ply("nan.ply", np.vstack([_cloud(), [[np.nan, 0, 0]]])))], "nan.ply"),
    "segment/millimetres": lambda e: (
        ["segment", str(e.ply("mm.ply", _cloud() * 1000))], "millimetres"),
    "segment/truncated body": lambda e: (
        ["segment", str(_truncated_npy_free_ply(e))], "cut.ply"),
    "segment/negative scale": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--scale", "-3"], "--scale"),
    "segment/zero max points": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--max-points", "0"], "--max-points"),
    "segment/max points not a number": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--max-points", "lots"], "--max-points"),
    "segment/bad category name": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--category", "Big Box"], "--category"),
    "segment/no default model": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--category", "lamp"],
        "no segmenter model for lamp (none shipped); make one with `artic pipeline ch4`"),
    "segment/out is a file": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--out", str(e.file("o.txt", "mine"))],
        "o.txt"),
    "segment/unknown option": lambda e: (
        ["segment", str(e.ply("s.ply", _cloud())), "--colour", "red"], "--colour"),
    # build-hierarchy
    "build/no part ids": lambda e: (
        ["build-hierarchy", str(e.ply("p.ply", _cloud())), "--model", str(e.file("m.pt", "x"))],
        "no part_id"),
    "build/missing parts": lambda e: (["build-hierarchy", str(e.tmp / "absent.ply")], "absent"),
    "build/inf point": lambda e: (
        ["build-hierarchy", str(e.ply("inf.ply", np.vstack([_cloud(), [[0, np.inf, 0]]])))],
        "inf.ply"),
    "build/bad scale": lambda e: (
        ["build-hierarchy", str(e.ply("p.ply", *box_cloud(800))), "--scale", "mm"], "--scale"),
    "build/no default model": lambda e: (
        ["build-hierarchy", str(e.ply("p.ply", *box_cloud(800))), "--category", "lamp"],
        "no hierarchy model for lamp (none shipped); make one with `artic pipeline ch4`"),
    # infer-hierarchy
    "infer/missing scan": lambda e: (["infer-hierarchy", str(e.tmp / "absent.ply")], "absent"),
    "infer/points coincide": lambda e: (
        ["infer-hierarchy", str(e.ply("pt.ply", np.zeros((600, 3), np.float32)))], "pt.ply"),
    "infer/no vertices": lambda e: (
        ["infer-hierarchy", str(e.ply("none.ply", np.zeros((0, 3), np.float32)))], "none.ply"),
    "infer/foreign out folder": lambda e: (
        ["infer-hierarchy", str(e.ply("s.ply", _cloud())), "--out",
         str(e.file("mine/notes.txt", "keep").parent)], "not an artic output folder"),
    "infer/no default segmenter": lambda e: (
        ["infer-hierarchy", str(e.ply("s.ply", _cloud())), "--category", "lamp"],
        "no segmenter model for lamp (none shipped); make one with `artic pipeline ch4`"),
    "infer/ascii body malformed": lambda e: (
        ["infer-hierarchy", str(e.file("a.ply", "ply\nformat ascii 1.0\nelement vertex 2\n"
                                       "property float x\nproperty float y\nproperty float z\n"
                                       "end_header\n0 0 0\n1 one 1\n"))], "a.ply"),
    # pipeline
    "pipeline/unknown name": lambda e: (["pipeline", "nonesuch"], "nonesuch"),
    "pipeline/undeclared variable": lambda e: (["pipeline", "smoke", "colour=red"], "colour"),
    "pipeline/malformed variable": lambda e: (["pipeline", "bootstrap", "task"], "task"),
    "pipeline/invalid yaml": lambda e: (
        ["pipeline", str(_bad_pipeline(e, "stages: [unclosed\n"))], "pipe.yaml"),
    "pipeline/unknown cmd": lambda e: (
        ["pipeline", str(_bad_pipeline(e, "stages:\n  a:\n    cmd: teleport\n"))], "teleport"),
    "pipeline/unknown field": lambda e: (
        ["pipeline", str(_bad_pipeline(e, "stages:\n  a:\n    cmd: fit-dmp\n    retry: 3\n"))],
        "retry"),
    "pipeline/missing dep": lambda e: (
        ["pipeline", str(_bad_pipeline(
            e, f"stages:\n  a:\n    cmd: fit-dmp\n    deps: [{e.tmp / 'absent'}]\n"))], "absent"),
    "pipeline/typo in the second stage": lambda e: (
        ["pipeline", str(_bad_pipeline(
            e, "stages:\n"
            f"  gen:\n    cmd: generate-dataset\n    overrides: [debug=tiny, out={e.tmp}/o]\n"
            f"    outs: [{e.tmp}/o]\n"
            f"  depth:\n    cmd: render-depth\n    overrides: [dataset={e.tmp}/o, out={e.tmp}/d,"
            " render.configurationz=3]\n"))], "configurationz"),
    # bootstrap
    "bootstrap/unknown task": lambda e: (["bootstrap", "--task", "sofa"], "sofa"),
    "bootstrap/unknown option": lambda e: (["bootstrap", "--tasks", "drawer"], "--tasks"),
    "bootstrap/extra argument": lambda e: (["bootstrap", "drawer"], "drawer"),
    # train-rmp and evaluate rmp (Chapter 6)
    "train-rmp/unknown task": lambda e: (["train-rmp", "--task", "sofa", e.out], "sofa"),
    "train-rmp/Chapter 5 task": lambda e: (["train-rmp", "--task", "drawer", e.out], "task.name"),
    "train-rmp/unknown controller": lambda e: (
        ["train-rmp", "controllers=[osc]", e.out], "controllers"),
    "train-rmp/kp min above max": lambda e: (["train-rmp", "vices.kp_min=400", e.out], "kp_min"),
    "train-rmp/zero sphere radius": lambda e: (
        ["train-rmp", "task.obstacles.radius=0", e.out], "task.obstacles.radius"),
    "evaluate rmp/missing policies": lambda e: (
        ["evaluate", "rmp", "tasks=[door]", f"policies.door={e.tmp / 'absent'}", e.out], "absent"),
    "evaluate rmp/objects as policies": lambda e: (
        ["evaluate", "rmp", "tasks=[door]", f"policies.door={e.objects}", e.out],
        "generate-dataset"),
    "evaluate rmp/unknown task": lambda e: (["evaluate", "rmp", "tasks=[sofa]", e.out], "tasks"),
}  # fmt: skip


def _truncated_npy_free_ply(env: Env) -> Path:
    """A binary PLY whose body stops halfway."""
    path = env.ply("cut.ply", _cloud())
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) - 5000])
    return path


def listing(root: Path) -> set[str]:
    return {p.relative_to(root).as_posix() for p in root.rglob("*")}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_exits_2_with_one_line_naming_it(name, tmp_path, request, monkeypatch):
    env = Env(tmp_path, request)
    args, fragment = CASES[name](env)
    monkeypatch.chdir(tmp_path)
    before = listing(tmp_path)
    code, stdout, stderr = run_cli(*args)
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert code == 2, (name, code, stderr)
    assert len(lines) == 1, (name, stderr)
    assert fragment in lines[0], (name, lines[0])
    assert "Traceback" not in stdout + stderr
    assert listing(tmp_path) == before, (name, sorted(listing(tmp_path) - before))


@pytest.mark.parametrize(
    ("args", "fragment"),
    [
        (["render-depth", "dataset=/nonexistent/objects"], "/nonexistent/objects"),
        (["predict", "absent.npy", "--category", "microwave", "--camera", "c.json"], "absent.npy"),
        (["evaluate", "mdn", "evaluate.levels=[1.5]"], "evaluate.levels"),
        (["plan-demos", "task=tball", "--task", "drawer"], "task=tball"),
        (["segment", "absent.ply", "--max-points", "x"], "--max-points"),
    ],
)
def test_bad_input_in_a_real_process(args, fragment, tmp_path):
    """The installed entry point: exit status 2 and one stderr line (not Typer's panels)."""
    artic = Path(sys.executable).parent / "artic"
    done = subprocess.run(
        [str(artic), *args], cwd=tmp_path, capture_output=True, text=True, timeout=120,
        check=False,
    )  # fmt: skip
    lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
    assert done.returncode == 2, done.stderr
    assert len(lines) == 1 and fragment in lines[0], done.stderr
    assert "Traceback" not in done.stdout + done.stderr
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- internal errors


def _one_internal_line(stderr: str) -> Path:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("internal error: "), stderr
    assert "Traceback" not in stderr
    assert lines[0].endswith(")") and "(traceback in " in lines[0], lines[0]
    log = Path(lines[0].rsplit("(traceback in ", 1)[1][:-1])
    assert "Traceback (most recent call last)" in log.read_text()
    return log


def test_internal_error_outside_a_stage_goes_to_a_tmp_log(tmp_path, monkeypatch):
    import tempfile

    import artic.kinematics.predict

    def boom(*args, **kwargs):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(artic.kinematics.predict, "predict_image", boom)
    code, _, stderr = run_cli("predict", "x.npy", "--category", "microwave", "--camera", "c")
    assert code == 1
    log = _one_internal_line(stderr)
    assert log == tmp_path / f"artic-{os.getpid()}.log"
    assert "RuntimeError: boom second line" in stderr


def test_internal_error_in_a_stage_goes_to_its_log(tmp_path, monkeypatch):
    import artic.artifacts.workers as runner

    def boom(*args, **kwargs):
        raise ZeroDivisionError("chunk exploded")

    monkeypatch.setattr(runner, "_run_chunk", boom)
    out = tmp_path / "objs"
    code, _, stderr = run_cli("generate-dataset", "debug=tiny", f"out={out}")
    assert code == 1
    log = _one_internal_line(stderr)
    assert log.name == "artic.log" and "chunk exploded" in stderr


def test_internal_error_in_segment_goes_to_its_log(tmp_path, monkeypatch, models):
    import artic.hierarchy.infer

    def boom(*args, **kwargs):
        raise KeyError("lost")

    monkeypatch.setattr(artic.hierarchy.infer, "segment_scan", boom)
    scan = tmp_path / "s.ply"
    write_ply(scan, _cloud())
    code, _, stderr = run_cli("segment", str(scan), "--model", str(models[0]))
    assert code == 1
    assert _one_internal_line(stderr).name == "artic.log"


# --------------------------------------------------------------------------- valid unusual input


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    from test_infer_hierarchy import save_models

    return save_models(tmp_path_factory.mktemp("models"))


def test_unicode_and_spaces_in_paths(tmp_path, models):
    seg, lab = models
    folder = tmp_path / "my scans ü"
    folder.mkdir()
    points, part = box_cloud(3000)
    scan = folder / "scän 1.ply"
    write_ply(scan, points, part_id=part)
    code, _, err = run_cli("infer-hierarchy", str(scan), "--segmenter", str(seg),
                           "--labeller", str(lab))  # fmt: skip
    assert code == 0, err
    out = folder / "scän 1_hierarchy"
    ply = read_ply(out / "parts.ply")
    assert np.array_equal(ply.points, points)
    assert "source sc\\xe4n 1.ply" in ply.comments
    code, _, err = run_cli("segment", str(scan), "--model", str(seg))
    assert code == 0, err
    parts = folder / "scän 1_segmented" / "parts.ply"
    assert read_ply(parts).part_id is not None
    built = folder / "büilt hierarchy"
    code, _, err = run_cli("build-hierarchy", str(parts), "--model", str(lab), "--out", str(built))
    assert code == 0, err
    assert (built / "object.urdf").is_file()


def test_millimetre_cloud_with_scale_auto(tmp_path, models):
    points, part = box_cloud(3000)
    scan = tmp_path / "mm.ply"
    write_ply(scan, points * 1000.0, part_id=part)
    code, _, err = run_cli("segment", str(scan), "--model", str(models[0]), "--scale", "auto")
    assert code == 0, err
    assert "divided by 1000" in err
    ply = read_ply(tmp_path / "mm_segmented" / "parts.ply")
    assert np.allclose(ply.points, points, atol=1e-6)


def test_five_million_points(tmp_path, models):
    """About 15 s on 2 cores: under the 20 s that would make it `slow`."""
    rng = np.random.default_rng(0)
    points, part = box_cloud(20_000)
    pick = rng.integers(0, len(points), 5_000_000)
    big = (points[pick] + rng.normal(0, 1e-3, (len(pick), 3))).astype(np.float32)
    scan = tmp_path / "big.ply"
    write_ply(scan, big, part_id=part[pick])
    seg, lab = models
    code, _, err = run_cli("infer-hierarchy", str(scan), "--segmenter", str(seg),
                           "--labeller", str(lab), "--max-points", "100000")  # fmt: skip
    assert code == 0, err
    assert "5000000 points; working on a random subset of 100000" in err
    doc = json.loads((tmp_path / "big_hierarchy" / "hierarchy.json").read_text())
    assert len(doc["point_part_id"]) == 5_000_000


def test_corrupt_npz_is_named_by_the_reader(tmp_path):
    from artic.artifacts.formats import read_npz
    from artic.errors import InputError

    path = tmp_path / "x.npz"
    path.write_bytes(zlib.compress(b"not an npz"))
    with pytest.raises(InputError, match=r"x\.npz: not a readable \.npz"):
        read_npz(path)
    write_npz(path, {"a": np.zeros(3)})
    with pytest.raises(InputError, match=r"x\.npz: \.npz has no array b"):
        read_npz(path, ("b",))
