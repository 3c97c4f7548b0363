"""Chapter 4 training speed: one segmenter training step with the PointNet++ neighbourhoods
computed in the forward pass (as before issue 18) and with them precomputed per cloud
(`pointnet2.backbone_index`, cached on disk by `hierarchy.cloud_cache`).

The network is `experiment=ch4_cpu`'s (composed from conf/train_segmenter/ with that
experiment: width 0.25, centroids 256/64, `inference.n_points` 1,024 points,
`train.batch_size` 8), untrained, on random box-shaped clouds; one torch thread. Per step,
interleaved, median over `--steps` steps after 2 warm-up steps:

- `backbone`: PointNet2 forward + backward (a scalar of its outputs) on the normalised
  batch, neighbourhoods on the fly vs `index=` stacked from the clouds' cached indices;
- `segmenter`: the whole network (`PartSegmentationNet`, both heads' outputs summed into a
  scalar, backward) on the fly; with `index=` too when its forward takes one;
- per cloud: computing its features (normals + index, once per cloud) and loading them
  from a warm cache (each epoch).

Usage: python bench/segmenter_step.py [--steps 20] [--json out.json] [OVERRIDE ...]
(OVERRIDEs are train-segmenter's Hydra overrides on top of `experiment=ch4_cpu`, e.g.
`model.normals=true` or `model.head=votes`)
"""

from __future__ import annotations

import argparse
import inspect
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from artic.reproducibility import pin_numerics

pin_numerics()  # as the artic command does, before NumPy loads

import numpy as np  # noqa: E402


def _scalar(output: Any) -> Any:
    """A scalar depending on every floating tensor of a network's output record."""
    import torch

    tensors = output if isinstance(output, tuple) else (output,)
    return sum(
        t.float().square().mean() for t in tensors if torch.is_tensor(t) and t.is_floating_point()
    )


def measure(steps: int, overrides: list[str] | None = None) -> dict[str, Any]:
    """Median seconds per training step (forward + backward) with and without the cached
    index, and the per-cloud costs (module docstring)."""
    import torch

    from artic.config.compose import compose
    from artic.hierarchy.cloud_cache import cloud_features, compute_cloud_features
    from artic.hierarchy.config import SegmenterModelConfig
    from artic.hierarchy.pointnet2 import stack_indices
    from artic.hierarchy.segmentation import PartSegmentationNet, normalize_points

    torch.set_num_threads(1)
    cfg = compose("train_segmenter", ["experiment=ch4_cpu", *(overrides or [])])
    model_cfg = SegmenterModelConfig.model_validate(cfg["model"])
    config = model_cfg.network()
    n_points, batch = int(cfg["inference"]["n_points"]), int(cfg["train"]["batch_size"])
    torch.manual_seed(0)
    model = PartSegmentationNet(config).train()
    rng = np.random.default_rng(0)
    clouds = [
        (rng.uniform(0, 1, (n_points, 3)) * [0.8, 0.5, 1.2]).astype(np.float32)
        for _ in range(batch)
    ]
    points = torch.from_numpy(np.stack(clouds))
    xyz = normalize_points(points)
    normals = torch.nn.functional.normalize(torch.randn(batch, n_points, 3), dim=-1)
    features = normals if config.backbone.in_channels == 3 else None
    seg_kwargs: dict[str, Any] = {"normals": normals} if getattr(config, "normals", False) else {}

    with tempfile.TemporaryDirectory(prefix="artic-bench-") as tmp:
        cache = Path(tmp)
        compute_s, load_s = [], []
        for cloud in clouds:
            t0 = time.perf_counter()
            compute_cloud_features(cloud, config)
            compute_s.append(time.perf_counter() - t0)
            cloud_features(cloud, config, cache)  # write
            t0 = time.perf_counter()
            loaded = cloud_features(cloud, config, cache)  # read
            load_s.append(time.perf_counter() - t0)
        index = stack_indices([cloud_features(c, config, cache).neighbourhoods for c in clouds])
        del loaded

    def backbone(cached: bool) -> float:
        t0 = time.perf_counter()
        model.zero_grad(set_to_none=True)
        out = model.backbone(xyz, features, index=index if cached else None)
        _scalar(out).backward()
        return time.perf_counter() - t0

    takes_index = "index" in inspect.signature(model.forward).parameters

    def segmenter(cached: bool) -> float:
        t0 = time.perf_counter()
        model.zero_grad(set_to_none=True)
        kwargs = dict(seg_kwargs, index=index) if cached else seg_kwargs
        _scalar(model(points, **kwargs)).backward()
        return time.perf_counter() - t0

    runs: dict[str, list[float]] = {"backbone": [], "backbone_cached": [], "segmenter": []}
    if takes_index:
        runs["segmenter_cached"] = []
    for step in range(steps + 2):
        times = {
            "backbone": backbone(False),
            "backbone_cached": backbone(True),
            "segmenter": segmenter(False),
        }
        if takes_index:
            times["segmenter_cached"] = segmenter(True)
        if step >= 2:  # warm-up
            for name, seconds in times.items():
                runs[name].append(seconds)
    med = {name: statistics.median(v) for name, v in runs.items()}
    result: dict[str, Any] = {
        "network": {
            "width": model_cfg.width,
            "centroids": list(model_cfg.centroids),
            "points": n_points,
            "batch": batch,
            "head": getattr(config, "head", "masks"),
            "normals": bool(getattr(config, "normals", False)),
        },
        "overrides": list(overrides or []),
        "steps": steps,
        "threads": torch.get_num_threads(),
        "step_s": {name: round(s, 4) for name, s in med.items()},
        "backbone_speedup": round(med["backbone"] / med["backbone_cached"], 2),
        # the rest of the step unchanged: the on-the-fly step minus what the index saves
        "segmenter_speedup_estimate": round(
            med["segmenter"] / (med["segmenter"] - med["backbone"] + med["backbone_cached"]), 2
        ),
        "per_cloud_s": {
            "compute_features": round(statistics.median(compute_s), 4),
            "load_cached": round(statistics.median(load_s), 5),
        },
    }
    if takes_index:
        result["segmenter_speedup"] = round(med["segmenter"] / med["segmenter_cached"], 2)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--json", type=Path, default=None, help="also write the result here")
    parser.add_argument("overrides", nargs="*", help="train-segmenter overrides")
    args = parser.parse_args()
    result = measure(args.steps, args.overrides)
    text = json.dumps(result, indent=2)
    if args.json:
        args.json.write_text(text + "\n")
    sys.stdout.write(text + "\n")


if __name__ == "__main__":
    main()
