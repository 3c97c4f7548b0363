"""`make bench`: the foundation's benchmarks, measured in one run.

1. Depth backends on the same scenes: raycast (Open3D) vs pybullet (TinyRenderer)
   images/s at 128x128 and 640x480, interleaved repeats, medians; and how closely they
   agree (fraction of pixels both hit that are within 1 mm).
2. End to end: `artic generate-dataset` + `artic render-depth` (default config: noise on,
   16 images per object, all CPUs) at two dataset sizes: labelled images/s and the peak
   resident memory of any one process (bounded: it must not grow with the dataset).

3. The Chapter 3 network: training images/s, forward latency and throughput, and the
   wall time of an `artic predict` process.
4. Chapter 4 inference on a 20,000-point scan: segmentation, graph labelling and tree
   extraction (+ joint axes) in-process (default-size networks, untrained weights), and
   the wall time of an `artic infer-hierarchy` process with the shipped models (imports
   and model loading included; issue 18's target: 3 s on an idle machine); and per
   category, the command with that category's shipped models on a 20,000-point scan of
   one of its generated objects: compute after loading (target 1 s) and wall.
5. Chapter 5: simulated control steps per second of each task's environment (random
   actions) and the median planning time per demo of `artic plan-demos` (10 demos, one
   worker, the default config; target under 2 s).
6. Numerics: the Chapter 3 MDN's training step and batch forward (64x64 crops, width 32,
   two threads) with the kernels artic pins (`artic.reproducibility`) and with each
   library's own choice for this CPU, in fresh processes, interleaved: the price of the
   same bytes on every CPU.
7. Chapter 4 training (`--only segmenter`): a segmenter step of either head with the
   PointNet++ neighbourhoods computed in the forward pass and cached per cloud.
8. Chapter 3's geometric refinement (`--only refine`): with the shipped models of the
   refined categories on new objects of theirs (thesis_sim camera), the refinement's time
   per image in-process (median; target 200 ms) and the wall time of an `artic predict`
   process with and without it (target 3 s on an idle machine).

The benchmarks run with the kernels pinned, as the `artic` command does.
Prints a Markdown report and writes bench/results/latest.json.
Usage: python bench/run_all.py [--objects 550 2200] [--scenes 24] [--repeats 5]
       [--only backends|e2e|network|hierarchy|segmenter|planning|numerics|refine]
(--scenes: objects over the three categories, each rendered at 16 configurations)
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from artic.reproducibility import pin_numerics

pin_numerics()  # as the artic command does, before NumPy loads

import numpy as np  # noqa: E402

from artic.objects.model import ArticulatedObject  # noqa: E402
from artic.render.backend import RenderedImage  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ARTIC = [sys.executable, "-m", "artic", "-q"]
CONFIGURATIONS = 16  # images per object, as render-depth
#: the benchmarks `--only` selects (all by default)
PARTS = ("backends", "e2e", "network", "hierarchy", "segmenter", "planning", "numerics", "refine")


def backend_benchmark(scenes_n: int, repeats: int, tmp: Path) -> list[dict[str, object]]:
    """Both backends on the same work as `render-depth`: each object at 16 configurations."""
    from artic.artifacts.object_dataset import ObjectDataset
    from artic.geometry.camera import CameraIntrinsics
    from artic.objects.categories import build
    from artic.objects.tree import latin_hypercube
    from artic.render.backend import make_backend

    scenes: list[tuple[ArticulatedObject, np.ndarray, Path]] = []  # object, (16, dof) qs, URDF
    for category in ("microwave", "cabinet2", "drawer"):
        out = tmp / f"objects-{category}"
        subprocess.run(
            [
                *ARTIC,
                "generate-dataset",
                f"category={category}",
                f"dataset.objects={scenes_n // 3}",
                f"out={out}",
            ],
            check=True,
        )
        ds = ObjectDataset.open(out)
        for row in ds.rows:
            spec = ds.spec(row.object_id)
            rng = np.random.default_rng(row.object_id)
            qs = latin_hypercube(rng, CONFIGURATIONS, list(spec.joint_limits))
            scenes.append((build(spec), qs, ds.urdf(row.object_id)))
    n_images = CONFIGURATIONS * len(scenes)
    cameras = {
        "128x128": CameraIntrinsics(fx=140, fy=140, cx=63.5, cy=63.5, width=128, height=128),
        "640x480": CameraIntrinsics(fx=525, fy=525, cx=319.5, cy=239.5, width=640, height=480),
    }
    results = []
    for res, cam in cameras.items():
        rates: dict[str, list[float]] = {"raycast": [], "pybullet": []}
        images: dict[str, list[RenderedImage]] = {}
        for _ in range(repeats):
            for name in ("raycast", "pybullet"):  # interleaved; fresh backend: no warm caches
                with make_backend(name, cam, threads=1) as backend:
                    t0 = time.perf_counter()
                    images[name] = [
                        image for o, qs, u in scenes for image in backend.render_many(o, qs, u)
                    ]
                    rates[name].append(n_images / (time.perf_counter() - t0))
        pairs = list(zip(images["raycast"], images["pybullet"], strict=True))
        both = [(a.depth > 0) & (b.depth > 0) for a, b in pairs]
        hits = sum(int(m.sum()) for m in both)
        close = sum(
            int((np.abs(a.depth - b.depth)[m] <= 0.001).sum())
            for (a, b), m in zip(pairs, both, strict=True)
        )
        same_part = sum(
            int((a.part_mask == b.part_mask)[m].sum())
            for (a, b), m in zip(pairs, both, strict=True)
        )
        one_only = sum(int(((a.depth > 0) != (b.depth > 0)).sum()) for a, b in pairs)
        ray_med, pb_med = statistics.median(rates["raycast"]), statistics.median(rates["pybullet"])
        results.append(
            {
                "resolution": res,
                "images": n_images,
                "repeats": repeats,
                "raycast_images_per_s": round(ray_med, 1),
                "pybullet_images_per_s": round(pb_med, 1),
                "speedup": round(ray_med / pb_med, 2),
                "agree_within_1mm": round(close / max(hits, 1), 5),
                "same_part_id": round(same_part / max(hits, 1), 5),
                "hit_by_one_only_per_hit_by_both": round(one_only / max(hits, 1), 5),
            }
        )
    return results


def end_to_end(objects: int, tmp: Path) -> dict[str, object]:
    """generate-dataset + render-depth of one category, measured in a fresh process so
    that its children's peak memory is theirs alone (a fork of this process would count
    the backend benchmark's images)."""
    child = subprocess.run(
        [sys.executable, __file__, "--e2e-child", str(objects), str(tmp)],
        check=True,
        capture_output=True,
        text=True,
    )
    result: dict[str, object] = json.loads(child.stdout.strip().splitlines()[-1])
    return result


def _e2e_child(objects: int, tmp: Path) -> None:
    objs, depth = tmp / f"e2e-objects-{objects}", tmp / f"e2e-depth-{objects}"
    t0 = time.perf_counter()
    subprocess.run(
        [
            *ARTIC,
            "generate-dataset",
            "category=microwave",
            f"dataset.objects={objects}",
            f"out={objs}",
        ],
        check=True,
    )
    t1 = time.perf_counter()
    subprocess.run([*ARTIC, "render-depth", f"dataset={objs}", f"out={depth}"], check=True)
    t2 = time.perf_counter()
    info = json.loads((depth / "dataset.json").read_text())
    print(
        json.dumps(
            {
                "objects": objects,
                "images": info["images"],
                "generate_s": round(t1 - t0, 1),
                "render_s": round(t2 - t1, 1),
                "images_per_s": round(info["images"] / (t2 - t0), 1),
                "render_images_per_s": round(info["images"] / (t2 - t1), 1),
                "peak_rss_mib": round(
                    resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1
                ),
            }
        )
    )


def network_benchmark(tmp: Path) -> list[dict[str, object]]:
    """The Chapter 3 MDN on this CPU, per crop size and width: training images/s (batch
    64: crop, forward, Adam step), latency at batch 1 (crop + forward, median of 30) and
    throughput at batch 64, and the wall time of a whole `artic predict` process
    (imports, model loading, one image)."""
    import torch

    from artic.artifacts.model_file import save_model_file
    from artic.artifacts.workers import available_cpus
    from artic.geometry.camera import CameraIntrinsics
    from artic.kinematics.mdn import KinematicsMDN, mdn_nll
    from artic.kinematics.preprocess import InputPipeline
    from artic.kinematics.targets import TargetCodec
    from artic.objects.labels import label_columns

    torch.set_num_threads(available_cpus())
    cam = CameraIntrinsics(fx=140, fy=140, cx=63.5, cy=63.5, width=128, height=128)
    columns = label_columns(1)
    codec = TargetCodec.fit(columns, np.random.default_rng(0).normal(size=(100, len(columns))))
    results = []
    rng = np.random.default_rng(0)
    depth = np.zeros((64, 128, 128), np.float32)
    for k in range(64):  # boxes of 30-90 px at 1-3 m
        r, c, size = *rng.integers(0, 60, 2), rng.integers(30, 90)
        depth[k, r : r + size, c : c + size] = rng.uniform(1, 3)
    for size, width in ((128, 64), (64, 64), (64, 32)):
        torch.manual_seed(0)
        model = KinematicsMDN(codec.dim, 20, width, input_size=size)
        model = model.to(memory_format=torch.channels_last)
        pipeline = InputPipeline(cam, size)
        opt = torch.optim.Adam(model.parameters(), 1e-3)
        y = torch.randn(64, codec.dim)
        times = []
        for _ in range(6):
            t0 = time.perf_counter()
            x = pipeline(depth).to(torch.device("cpu"), channels_last=True)
            loss = mdn_nll(model(*x), y)
            opt.zero_grad()
            loss.backward()
            opt.step()
            times.append(time.perf_counter() - t0)
        model.eval()
        with torch.no_grad():
            for _ in range(3):
                model(*pipeline(depth[:1]))
            single = []
            for _ in range(30):
                t0 = time.perf_counter()
                model(*pipeline(depth[:1]))
                single.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            model(*pipeline(depth))
            batch = 64 / (time.perf_counter() - t0)
        path = tmp / f"mdn-{size}-{width}.pt"
        meta = {"codec": codec.to_dict(), "camera": cam.model_dump(), "dof": 1,
                "joint_type": "revolute"}  # fmt: skip
        save_model_file(
            path, "kinematics-mdn", "microwave", model.hparams, model.state_dict(), meta
        )
        np.save(tmp / "depth.npy", depth[0])
        (tmp / "camera.json").write_text(cam.model_dump_json())
        walls = []
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run(
                [*ARTIC, "predict", str(tmp / "depth.npy"), "--category", "microwave",
                 "--camera", str(tmp / "camera.json"), "--model", str(path)],
                check=True, capture_output=True,
            )  # fmt: skip
            walls.append(time.perf_counter() - t0)
        results.append({
            "input": f"{size}x{size} crop", "width": width,
            "train_images_per_s": round(64 / statistics.median(times[1:]), 1),
            "forward_batch1_ms": round(1000 * statistics.median(single), 2),
            "forward_batch64_images_per_s": round(batch, 1),
            "predict_process_wall_s": round(statistics.median(walls), 2),
        })  # fmt: skip
    return results


def _cabinet_scan(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) points on the surfaces of a cabinet (body, two doors, two drawers, four
    handles: 9 parts touching each other) and (n,) part ids."""
    boxes = [((0.0, 0.0, 0.5), (0.5, 0.8, 1.0))]  # (centre, size), metres
    boxes += [((-0.26, y, 0.75), (0.02, 0.38, 0.48)) for y in (-0.2, 0.2)]  # doors
    boxes += [((-0.2, 0.0, z), (0.5, 0.76, 0.22)) for z in (0.13, 0.37)]  # drawers
    boxes += [((-0.29, y, 0.75), (0.04, 0.02, 0.15)) for y in (-0.05, 0.05)]  # door handles
    boxes += [((-0.47, 0.0, z), (0.04, 0.2, 0.02)) for z in (0.13, 0.37)]  # drawer handles
    part = rng.integers(0, len(boxes), n)
    points = np.empty((n, 3))
    for k, (centre, size) in enumerate(boxes):
        idx = np.flatnonzero(part == k)
        u = rng.uniform(-0.5, 0.5, (len(idx), 3))
        face = rng.integers(0, 3, len(idx))
        u[np.arange(len(idx)), face] = np.sign(u[np.arange(len(idx)), face]) * 0.5
        points[idx] = np.asarray(centre) + u * np.asarray(size)
    return points.astype(np.float32), part.astype(np.int64)


_GRAPH_STEPS = ("graph", "labelling", "tree", "joints")


def _infer_hierarchy_runs(scan: Path, outs: list[Path], *options: str) -> list[float]:
    """Wall times of `artic infer-hierarchy scan --out o *options` for each o of `outs`, in
    turn (the first warms the file cache: callers leave it out of their medians)."""
    walls = []
    for out in outs:
        t0 = time.perf_counter()
        subprocess.run(
            [*ARTIC, "infer-hierarchy", str(scan), *options, "--out", str(out)],
            check=True, capture_output=True,
        )  # fmt: skip
        walls.append(time.perf_counter() - t0)
    return walls


def hierarchy_benchmark(tmp: Path, points: int = 20_000) -> dict[str, object]:
    """`infer-hierarchy` on a `points`-point scan with the default networks (untrained):
    in-process medians of 5 runs (models loaded) of the whole pipeline and of its steps;
    graph labelling + tree + axes also on the 9 true parts (an untrained segmenter finds
    one part); and the median wall time of 5 `artic infer-hierarchy` processes with the
    shipped models (after one not counted)."""
    import torch

    from artic.artifacts.ply import write_ply
    from artic.artifacts.workers import available_cpus
    from artic.hierarchy.gnn import GraphLabellingNet
    from artic.hierarchy.infer import HierarchyConfig, build_hierarchy, infer_hierarchy
    from artic.hierarchy.segmentation import PartSegmentationNet

    torch.set_num_threads(available_cpus())
    torch.manual_seed(0)
    segmenter, labeller = PartSegmentationNet().eval(), GraphLabellingNet().eval()
    cloud, part = _cabinet_scan(points, np.random.default_rng(0))
    cfg = HierarchyConfig()
    infer_hierarchy(cloud, segmenter, labeller, cfg)  # warm-up
    runs = [infer_hierarchy(cloud, segmenter, labeller, cfg) for _ in range(5)]
    steps = {k: statistics.median(r.timings[k] for r in runs) for k in runs[0].timings}
    built = [build_hierarchy(cloud, part, labeller, cfg) for _ in range(5)]
    true_parts = {k: statistics.median(b.timings[k] for b in built) for k in built[0].timings}
    scan = tmp / "scan.ply"
    write_ply(scan, cloud)
    # the user's journey: the shipped storage-furniture models (their labeller's program
    # ships too, artic.hierarchy.compiled); run 0 warms the file cache and is not counted
    walls = _infer_hierarchy_runs(scan, [tmp / f"h{i}" for i in range(6)])
    return {
        "points": points,
        "threads": available_cpus(),
        "segment_s": round(steps["subsample"] + steps["segment"] + steps["upsample"], 3),
        "label_tree_axes_s": round(sum(steps[k] for k in _GRAPH_STEPS), 3),
        "pipeline_s": round(steps["total"], 3),
        "parts_found": runs[0].num_parts,
        "true_parts": int(part.max()) + 1,
        "true_parts_graph_s": round(true_parts["graph"], 3),
        "true_parts_labelling_s": round(true_parts["labelling"], 3),
        "true_parts_tree_s": round(true_parts["tree"], 4),
        "true_parts_joints_s": round(true_parts["joints"], 3),
        "process_wall_s": round(statistics.median(walls[1:]), 2),
    }  # fmt: skip


#: the categories whose segmenter and graph network ship (models/; docs/models.md)
HIERARCHY_CATEGORIES = ("storage_furniture", "lamp", "office_chair")


def hierarchy_category_benchmark(tmp: Path, points: int = 20_000) -> list[dict[str, object]]:
    """`artic infer-hierarchy --category C` with each category's shipped models on a
    `points`-point clean scan of one of its objects (`generate-dataset dataset=hierarchy
    dataset.objects=4`, the one test object, `render-scan render.clean_points=points`, its
    first pose): the median of 5 processes (after one not counted) of the command's wall
    time and of the compute after loading (hierarchy.json's `timings_s.total`: yaw,
    segmentation with the model's own inference settings, graph, labelling, tree, axes).
    Issue 18's targets: compute under 1 s, wall at most 3 s on an idle machine."""
    rows: list[dict[str, object]] = []
    for category in HIERARCHY_CATEGORIES:
        objects, scans = tmp / f"objects_{category}", tmp / f"scans_{category}"
        for stage in (
            ["generate-dataset", "dataset=hierarchy", f"category={category}",
             "dataset.objects=4", f"out={objects}"],
            ["render-scan", f"dataset={objects}", "render.configurations=1",
             f"render.clean_points={points}", "render.preview_images=0", f"out={scans}"],
        ):  # fmt: skip
            subprocess.run([*ARTIC, *stage], check=True, capture_output=True)
        (scan,) = sorted((scans / "scans").glob("*_00_clean.ply"))[-1:]
        outs = [tmp / f"h_{category}{i}" for i in range(6)]
        walls = _infer_hierarchy_runs(scan, outs, "--category", category)
        results = [json.loads((out / "hierarchy.json").read_text()) for out in outs]
        computes = [float(r["timings_s"]["total"]) for r in results]
        parts = int(results[-1]["num_parts"])
        rows.append({
            "category": category,
            "points": points,
            "parts_found": parts,
            "compute_s": round(statistics.median(computes[1:]), 2),
            "process_wall_s": round(statistics.median(walls[1:]), 2),
        })  # fmt: skip
    return rows


def planning_benchmark(tmp: Path) -> list[dict[str, object]]:
    """Per Chapter 5 task: env control steps/s and plan-demos' median planning time."""
    from artic.sim.envs import measure_steps_per_second

    rows: list[dict[str, object]] = []
    for task in ("drawer", "microwave", "tball"):
        steps = [measure_steps_per_second(task, 1000, seed=s) for s in range(3)]
        out = tmp / "demos" / task
        cmd = [*ARTIC, "plan-demos", f"task={task}", "runtime.workers=1", f"out={out}"]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        wall = time.perf_counter() - t0
        timings = json.loads((out / "timings.json").read_text())
        per_demo = [float(d["planning_time_s"]) for d in timings["demos"]]
        demos = json.loads((out / "demos.json").read_text())["demos"]
        rows.append({
            "task": task,
            "env_steps_per_s": round(statistics.median(steps)),
            "demos_planned": sum(d["status"] == "ok" for d in demos),
            "demos": len(demos),
            "median_planning_s": round(statistics.median(per_demo), 3),
            "max_planning_s": round(max(per_demo), 3),
            "plan_demos_wall_s": round(wall, 1),
        })  # fmt: skip
    return rows


def numerics_benchmark(repeats: int) -> list[dict[str, object]]:
    """Pinned and native kernels, `repeats` interleaved fresh processes each: medians and
    the median of the per-repeat ratios (bench/numerics_child.py)."""
    runs: dict[str, list[dict[str, object]]] = {"pinned": [], "native": []}
    for _ in range(repeats):
        for mode in runs:
            child = [sys.executable, str(ROOT / "bench" / "numerics_child.py"), mode]
            out = subprocess.run(child, check=True, capture_output=True, text=True).stdout
            runs[mode].append(json.loads(out))
    rows = []
    for key in ("train_images_per_s", "forward_images_per_s"):
        pinned = [float(r[key]) for r in runs["pinned"]]  # type: ignore[arg-type]
        native = [float(r[key]) for r in runs["native"]]  # type: ignore[arg-type]
        rows.append({
            "measure": key, "pinned": round(statistics.median(pinned), 1),
            "native": round(statistics.median(native), 1),
            "pinned_over_native": round(
                statistics.median(p / n for p, n in zip(pinned, native, strict=True)), 3),
            "same_weights_every_run": len({r["weights_sha256"] for r in runs["pinned"]}) == 1,
        })  # fmt: skip
    return rows


def segmenter_benchmark() -> list[dict[str, object]]:
    """7. Chapter 4 training speed: a segmenter step (`experiment=ch4_cpu`, both heads) with
    the PointNet++ neighbourhoods computed in the forward pass and precomputed per cloud
    (bench/segmenter_step.py)."""
    from segmenter_step import measure

    return [measure(20, [f"model.head={head}"]) for head in ("masks", "votes")]


def refine_benchmark(tmp: Path, objects: int = 110) -> list[dict[str, object]]:
    """The refinement (kinematics/refine.py) with the shipped MDNs of the refined
    categories on `objects` new objects each (seed 1, two images per object, the test
    split): ms per image in-process (the network alone, and the refinement on top), and
    the wall time of `artic predict` processes (imports, model loading, one image)."""
    from artic.artifacts.depth_dataset import DepthDataset
    from artic.artifacts.model_store import choose_model
    from artic.kinematics.predict import Predictor
    from artic.kinematics.refine import SUPPORTED

    results: list[dict[str, object]] = []
    for category in SUPPORTED:
        objects_dir, depth_dir = tmp / f"refine-objects-{category}", tmp / f"refine-{category}"
        subprocess.run([*ARTIC, "generate-dataset", f"category={category}",
                        "experiment=ch3_cpu", f"dataset.objects={objects}", "seed=1",
                        f"out={objects_dir}"], check=True, capture_output=True)  # fmt: skip
        subprocess.run([*ARTIC, "render-depth", f"dataset={objects_dir}",
                        "render.configurations=2", f"out={depth_dir}"],
                       check=True, capture_output=True)  # fmt: skip
        model = choose_model("mdn", category, None, "--model").path
        predictor = Predictor.load(model, category)
        ds = DepthDataset.open(depth_dir)
        images = [d for shard in ds.shards() for d, test in zip(shard.depth, shard.test,
                                                                 strict=True) if test]  # fmt: skip
        predictor.describe(images[0], refine=True)  # warm-up: imports, first scenes
        network, refined = [], []
        for depth in images:
            t0 = time.perf_counter()
            predictor.describe(depth)
            t1 = time.perf_counter()
            predictor.describe(depth, refine=True)
            t2 = time.perf_counter()
            network.append(t1 - t0)
            refined.append((t2 - t1) - (t1 - t0))
        np.save(tmp / "refine.npy", images[0])
        (tmp / "refine-camera.json").write_text(ds.info.camera.model_dump_json())
        walls: dict[str, list[float]] = {"--refine": [], "--no-refine": []}
        for _ in range(3):
            for flag, wall in walls.items():
                t0 = time.perf_counter()
                subprocess.run([*ARTIC, "predict", str(tmp / "refine.npy"), "--category",
                                category, "--camera", str(tmp / "refine-camera.json"), flag],
                               check=True, capture_output=True)  # fmt: skip
                wall.append(time.perf_counter() - t0)
        results.append({
            "category": category, "images": len(images),
            "network_ms": round(1000 * statistics.median(network), 1),
            "refinement_ms": round(1000 * statistics.median(refined), 1),
            "refinement_ms_p90": round(1000 * float(np.percentile(refined, 90)), 1),
            "predict_wall_s": round(statistics.median(walls["--refine"]), 2),
            "predict_wall_no_refine_s": round(statistics.median(walls["--no-refine"]), 2),
        })  # fmt: skip
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, nargs="+", default=[550, 2200])
    parser.add_argument("--scenes", type=int, default=24)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--only",
        choices=PARTS,
        default=None,
    )
    parser.add_argument("--e2e-child", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.e2e_child:
        _e2e_child(int(args.e2e_child[0]), Path(args.e2e_child[1]))
        return
    with tempfile.TemporaryDirectory(prefix="artic-bench-") as tmp_dir:
        tmp = Path(tmp_dir)
        run = {args.only} if args.only else set(PARTS)
        backends = backend_benchmark(args.scenes, args.repeats, tmp) if "backends" in run else []
        e2e = [end_to_end(n, tmp) for n in sorted(args.objects)] if "e2e" in run else []
        network = network_benchmark(tmp) if "network" in run else []
        hierarchy = [hierarchy_benchmark(tmp)] if "hierarchy" in run else []
        per_category = hierarchy_category_benchmark(tmp) if "hierarchy" in run else []
        segmenter = segmenter_benchmark() if "segmenter" in run else []
        planning = planning_benchmark(tmp) if "planning" in run else []
        numerics = numerics_benchmark(args.repeats) if "numerics" in run else []
        refinement = refine_benchmark(tmp) if "refine" in run else []
    report = {
        "machine": {
            "cpus": len(__import__("os").sched_getaffinity(0)),
            "python": platform.python_version(),
            "platform": platform.platform(),
        },
        "backends": backends,
        "end_to_end": e2e,
        "network": network,
        "hierarchy": hierarchy,
        "hierarchy_categories": per_category,
        "segmenter": segmenter,
        "planning": planning,
        "numerics": numerics,
        "refine": refinement,
    }
    out = ROOT / "bench" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "latest.json").write_text(json.dumps(report, indent=2) + "\n")
    print(
        "| resolution | images | raycast img/s | pybullet img/s | speed-up | depth within 1 mm "
        "| same part id | hit by one backend only |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in backends:
        print(
            f"| {r['resolution']} | {r['images']} | {r['raycast_images_per_s']} "
            f"| {r['pybullet_images_per_s']} | {r['speedup']}x "
            f"| {100 * float(r['agree_within_1mm']):.3f}% | {100 * float(r['same_part_id']):.3f}% "
            f"| {100 * float(r['hit_by_one_only_per_hit_by_both']):.3f}% |"
        )
    print()
    print(
        "| objects | images | generate s | render s | labelled img/s "
        "| peak RSS of one process, MiB |"
    )
    print("|---|---|---|---|---|---|")
    for r in e2e:
        print(
            f"| {r['objects']} | {r['images']} | {r['generate_s']} | {r['render_s']} "
            f"| {r['images_per_s']} | {r['peak_rss_mib']} |"
        )

    print()
    print(
        "| input | width | train img/s | forward batch 1 | forward batch 64 | artic predict wall |"
    )
    print("|---|---|---|---|---|---|")
    for r in network:
        print(f"| {r['input']} | {r['width']} | {r['train_images_per_s']} "
              f"| {r['forward_batch1_ms']} ms | {r['forward_batch64_images_per_s']} img/s "
              f"| {r['predict_process_wall_s']} s |")  # fmt: skip

    print()
    print(
        "| scan points | segment | graph + labelling + tree + axes | pipeline (models loaded) "
        "| same, 9 true parts: graph / labelling / tree / axes | artic infer-hierarchy wall |"
    )
    print("|---|---|---|---|---|---|")
    for r in hierarchy:
        print(f"| {r['points']} | {r['segment_s']} s | {r['label_tree_axes_s']} s "
              f"| {r['pipeline_s']} s ({r['parts_found']} part(s) found) "
              f"| {r['true_parts_graph_s']} / {r['true_parts_labelling_s']} / "
              f"{r['true_parts_tree_s']} / {r['true_parts_joints_s']} s "
              f"| {r['process_wall_s']} s |")  # fmt: skip

    print()
    print("| category, shipped models | scan points | parts found | compute after loading "
          "| artic infer-hierarchy wall |")  # fmt: skip
    print("|---|---|---|---|---|")
    for r in per_category:
        print(f"| {r['category']} | {r['points']} | {r['parts_found']} | {r['compute_s']} s "
              f"| {r['process_wall_s']} s |")  # fmt: skip

    print()
    print("| segmenter head | step, neighbourhoods in the forward pass | step, cached | speed-up |")
    print("|---|---|---|---|")
    for r in segmenter:
        step = r["step_s"]
        print(f"| {r['network']['head']} | {step['segmenter']} s "
              f"| {step.get('segmenter_cached', 'n/a')} s "
              f"| {r.get('segmenter_speedup', r['segmenter_speedup_estimate'])}x |")  # fmt: skip

    print()
    print("| task | env control steps/s | demos planned | median planning s | max | wall s |")
    print("|---|---|---|---|---|---|")
    for r in planning:
        planned = f"{r['demos_planned']}/{r['demos']}"
        print(f"| {r['task']} | {r['env_steps_per_s']} | {planned} | {r['median_planning_s']} "
              f"| {r['max_planning_s']} | {r['plan_demos_wall_s']} |")  # fmt: skip

    print()
    print("| measure | pinned | native | pinned / native | same weights every pinned run |")
    print("|---|---|---|---|---|")
    for r in numerics:
        print(f"| {r['measure']} | {r['pinned']} | {r['native']} | {r['pinned_over_native']} "
              f"| {r['same_weights_every_run']} |")  # fmt: skip

    print()
    print("| category | test images | network ms | refinement ms (p90) | artic predict wall "
          "| with --no-refine |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for r in refinement:
        print(f"| {r['category']} | {r['images']} | {r['network_ms']} | {r['refinement_ms']} "
              f"({r['refinement_ms_p90']}) | {r['predict_wall_s']} s "
              f"| {r['predict_wall_no_refine_s']} s |")  # fmt: skip


if __name__ == "__main__":
    main()
