"""The user's journeys on the shipped models (`make demo`, after the smoke pipeline).

1. Chapter 4: a freshly generated storage-furniture object, scanned, then
   `artic infer-hierarchy scan.ply` with the default (shipped) models: the inferred
   kinematic tree beside the true one.
2. Chapter 3: a freshly generated microwave, rendered, then `artic predict depth.png` with
   the default (shipped) model: the predicted axis and opening beside the truth, the
   errors beside the model card's mean errors on withheld objects, and whether the truth
   lies inside the prediction's 90% intervals.

Every step is a real `artic` command, printed before it runs; the objects are new (seed
2026; the shipped models were trained on seed 0). Outputs go to artifacts/demo/.
Usage: python scripts/demo.py [--out artifacts/demo]
"""

from __future__ import annotations

import argparse
import json
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from artic.artifacts.depth_dataset import DepthDataset
from artic.artifacts.model_store import choose_model
from artic.artifacts.scan_dataset import ScanDataset
from artic.evaluation.kinematics import configuration_unit, kinematic_errors

ARTIC = str(Path(sys.executable).parent / "artic")
SEED = 2026


def run(*args: str, capture: bool = False) -> str:
    """`artic ARGS`, echoed; its stdout when `capture`. A failure ends the demo."""
    print(f"\n$ artic {shlex.join(args)}", flush=True)  # noqa: T201
    done = subprocess.run([ARTIC, "-q", *args], text=True, capture_output=capture)
    if done.returncode != 0:
        sys.stderr.write(done.stderr if capture else "")
        raise SystemExit(f"demo: artic {args[0]} failed (exit {done.returncode})")
    return done.stdout if capture else ""


def _joints(tree: dict[str, Any]) -> list[str]:
    """`revolute (rotating part)` per joint, sorted: part numbers differ between the
    inferred and the true tree, the joints' kinds do not."""
    motion = tree["motion_types"]
    return sorted(
        f"{t} ({motion[b]} part)"
        for (_, b), t in zip(tree["edges"], tree["joint_types"], strict=True)
    )


def hierarchy_journey(out: Path) -> bool:
    objects, scans = out / "objects/storage_furniture", out / "scans/storage_furniture"
    run("generate-dataset", "dataset=hierarchy", "category=storage_furniture",
        "dataset.objects=4", f"seed={SEED}", f"out={objects}")  # fmt: skip
    run("render-scan", f"dataset={objects}", "render.configurations=1", f"out={scans}")
    data = ScanDataset.open(scans)
    row = next(r for r in data.rows if r.split == "test" and r.kind == "noisy")
    scan = scans / row.file
    result = out / f"hierarchy/{scan.stem}"
    run("infer-hierarchy", str(scan), "--out", str(result))
    inferred = json.loads((result / "hierarchy.json").read_text())
    truth = data.tree(row.object_id).to_dict()
    got, want = _joints(inferred), _joints(truth)
    print(f"\nChapter 4: kinematic tree of a new storage-furniture scan ({scan})")  # noqa: T201
    print(f"  {'':9} {'parts':>5}  joints")  # noqa: T201
    print(f"  {'inferred':9} {inferred['num_parts']:>5}  {', '.join(got) or '-'}")  # noqa: T201
    print(f"  {'truth':9} {truth['num_parts']:>5}  {', '.join(want) or '-'}")  # noqa: T201
    right = inferred["num_parts"] == truth["num_parts"] and got == want
    verdict = "right" if right else "WRONG"
    print(f"  parts and joints {verdict}; picture: {result / 'hierarchy.png'}")  # noqa: T201
    return right


def predict_journey(out: Path) -> bool:
    objects, depth = out / "objects/microwave", out / "depth/microwave"
    run("generate-dataset", "category=microwave", "experiment=ch3_cpu", "dataset.objects=11",
        f"seed={SEED}", f"out={objects}")  # fmt: skip
    run("render-depth", f"dataset={objects}", "render.configurations=2", f"out={depth}")
    data = DepthDataset.open(depth)
    shard = next(data.shards(decode=False))
    image = out / "predict/depth.png"
    image.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(shard.depth[0]).save(image)  # 16-bit millimetres, as a sensor writes
    args = ("predict", str(image), "--category", "microwave", "--camera", "thesis_sim")
    answer = json.loads(run(*args, capture=True))
    columns = data.label_columns
    truth = np.asarray(shard.labels[0], dtype=np.float64)
    estimate = np.array([answer["estimate"][c] for c in columns], dtype=np.float64)
    joint_type = answer["joints"][0]["type"]
    errors = kinematic_errors(estimate[None], truth[None], columns, 1, joint_type)
    col = {c: i for i, c in enumerate(columns)}
    joint = answer["joints"][0]
    unit = configuration_unit(joint_type)
    true_origin = [truth[col[f"j0_origin_{a}"]] for a in "xyz"]
    print(f"\nChapter 3: a new microwave seen by one depth image ({image})")  # noqa: T201
    print(f"  model: {answer['input']['model_source']} {answer['input']['model']}")  # noqa: T201
    print(f"  {'':10} axis origin (m, camera frame)   yaw (deg)  opening")  # noqa: T201
    for name, origin, yaw, q in (
        ("predicted", joint["origin"], answer["estimate"]["pose_yaw"], joint["configuration"]),
        ("truth", true_origin, truth[col["pose_yaw"]], truth[col["j0_q"]]),
    ):
        shown = ", ".join(f"{v:+.3f}" for v in origin)
        print(f"  {name:10} ({shown})   {np.degrees(yaw):+8.1f}   {np.degrees(q):5.1f} deg")  # noqa: T201
    card = choose_model("mdn", "microwave", None, "--model").model
    # predict refines by default: the card's refined figures when it has them
    figures = (
        "-"
        if card is None
        else card.figures.get(
            "Ours + refinement pos/rot/config", card.figures.get("Ours pos/rot/config", "-")
        )
    )
    print(  # noqa: T201
        f"  errors: axis position {errors['position_cm'][0]:.1f} cm, yaw "
        f"{errors['rotation_deg'][0]:.1f} deg, configuration {errors['configuration'][0]:.1f} "
        f"{unit}; the model card's means on withheld objects (pos cm / rot deg / config "
        f"{unit}): {figures}"
    )
    print(f"  {within_intervals(answer, truth, col)}")  # noqa: T201
    print(f"  pictures: {depth / 'preview.png'} (true axes drawn)")  # noqa: T201
    return True


#: the columns the demo checks against the predicted intervals: axis origin, yaw, opening
CHECKED = ("j0_origin_x", "j0_origin_y", "j0_origin_z", "pose_yaw", "j0_q")


def within_intervals(answer: dict[str, Any], truth: np.ndarray, col: dict[str, int]) -> str:
    """Whether the truth lies inside the prediction's 90% intervals (the model card's
    error as a distribution: on withheld objects these intervals hold the truth 90% of the
    time, `refined_intervals.csv`), per checked column."""
    level = answer["intervals"]["levels"].get("0.9")
    if not level:
        return f"no 90% intervals ({answer['intervals']['of']})"
    index = {name: i for i, name in enumerate(answer["estimate"])}  # the intervals' order
    lower, upper = level["lower"], level["upper"]
    outside = [c for c in CHECKED if not lower[index[c]] <= truth[col[c]] <= upper[index[c]]]
    verdict = "yes" if not outside else f"no, outside: {', '.join(outside)}"
    return (
        "truth inside the predicted 90% intervals of axis origin, yaw and opening (each "
        f"holds the truth on 90% of withheld objects): {verdict}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("artifacts/demo"))
    args = parser.parse_args()
    print("artic demo: the user's journeys on the shipped models (artic models)")  # noqa: T201
    run("models")
    hierarchy_journey(args.out)
    predict_journey(args.out)


if __name__ == "__main__":
    main()
