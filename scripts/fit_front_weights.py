"""Fit the yaw step's front weights (`artic.hierarchy.canonical.PROFILE_WEIGHTS`) on a
category's training scans, for maintainers (docs/hierarchy.md, "Scan frame and yaw").

    .venv/bin/python scripts/fit_front_weights.py SCANS [SCANS...] --category office_chair \
        [--kinds noisy] [--max-poses N] [--seed 0]

SCANS: `render-scan` output folders of the category (the scans its models trained on;
several: the same objects scanned with other cameras, so that the weights do not learn
one sensor's sampling). Each training-split scan of `--kinds` is turned by a random yaw
(drawn from `--seed`; one per scan), its front step's features taken as `canonical_yaw`
sees them with the category's settings (`canonical.yaw_config`: an office chair's planes
from its legs), and the side that faces the object frame's -x labelled its front
(`canonical.front_example`); the weights are `canonical.fit_front_weights` on those of
every folder (L2 1e-3). Prints the weights as a Python array to paste into canonical.py,
and per folder how often they choose the front on its training scans and on its test
split's (turned the same way), beside the weights in use.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from artic.artifacts.scan_dataset import ScanDataset
from artic.hierarchy.canonical import (
    PROFILE_WEIGHTS,
    FrontExample,
    fit_front_weights,
    front_example,
    front_probabilities,
    yaw_config,
)


def examples(
    ds: ScanDataset,
    split: str,
    kinds: list[str],
    max_poses: int | None,
    category: str,
    seed: list[int],
) -> list[FrontExample]:
    """One example per scan of `split`, each turned by its own seeded yaw."""
    settings = yaw_config(category)
    out = []
    for row in ds.select(split, kinds, ds.object_ids(split)):
        if max_poses is not None and row.pose >= max_poses:
            continue
        rng = np.random.default_rng([*seed, row.object_id, row.pose, kinds.index(row.kind)])
        yaw = float(rng.uniform(-math.pi, math.pi))
        out.append(front_example(ds.cloud(row).points, yaw, settings))
    return out


def accuracy(found: list[FrontExample], weights: np.ndarray) -> float:
    chosen = [int(np.argmax(front_probabilities(e.features, weights))) for e in found]
    return float(np.mean([c == e.front for c, e in zip(chosen, found, strict=True)]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scans", type=Path, nargs="+")
    parser.add_argument("--category", required=True)
    parser.add_argument("--kinds", nargs="+", default=["noisy"])
    parser.add_argument("--max-poses", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    sets = []
    for k, folder in enumerate(args.scans):
        ds = ScanDataset.open_category(folder, args.category)
        seed = [args.seed, k]
        sets.append((folder, *(examples(ds, split, args.kinds, args.max_poses, args.category, seed)
                               for split in ("train", "test"))))  # fmt: skip
    train = [e for _, found, _ in sets for e in found]
    weights = fit_front_weights(np.stack([e.features for e in train]),
                                np.array([e.front for e in train]))  # fmt: skip
    rows = ",\n".join("        [" + ", ".join(f"{w:.4g}" for w in row) + "]" for row in weights)
    print(f"np.array(\n    [\n{rows},\n    ]\n)")  # noqa: T201
    in_use = PROFILE_WEIGHTS[yaw_config(args.category).profile]
    for folder, found, test in sets:
        fitted = f"{accuracy(found, weights):.4f} / {accuracy(test, weights):.4f}"
        used = f"{accuracy(found, in_use):.4f} / {accuracy(test, in_use):.4f}"
        counts = f"{len(found)} training / {len(test)} test scans"
        print(f"{folder}: front chosen on {counts}: fitted {fitted}, in use {used}")  # noqa: T201


if __name__ == "__main__":
    main()
