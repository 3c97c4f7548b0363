"""A finished policy-search output folder (`artic policy-search`, docs/formats.md) read
back: its validated config, its learning curve and each seed's final policy as an
`ActionFn`; and the statistics over seeds of Figure 5.2 (`curve_stats`,
`bootstrap_verdict`)."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from artic.artifacts.manifest import read_manifest, verify_file
from artic.errors import InputError
from artic.learning.search import CURVE, CURVE_COLUMNS, PolicySearchConfig, algorithm_of, seed_dir


@dataclass(frozen=True)
class SearchOutput:
    """A finished policy-search folder: its validated config and manifest."""

    folder: Path
    cfg: PolicySearchConfig
    manifest: Any

    @classmethod
    def open(cls, folder: Path) -> SearchOutput:
        manifest = read_manifest(folder, expected_stage="policy-search")
        try:
            cfg = PolicySearchConfig.model_validate(manifest.config)
        except ValueError as err:
            raise InputError(
                f"{folder}: config in its manifest does not validate ({err})"
            ) from None
        verify_file(folder, manifest, CURVE)
        return cls(folder, cfg, manifest)

    def curve(self) -> np.ndarray:
        """(rows, 7) learning_curve.csv as floats (columns `CURVE_COLUMNS`)."""
        with (self.folder / CURVE).open(newline="") as f:
            rows = list(csv.reader(f))
        if not rows or rows[0] != CURVE_COLUMNS:
            raise InputError(f"{self.folder / CURVE}: expected the columns {CURVE_COLUMNS}")
        return np.array([[float(v) for v in r] for r in rows[1:]], dtype=np.float64).reshape(
            -1, len(CURVE_COLUMNS)
        )

    def final_actor(self, index: int) -> Any:
        """The `ActionFn` of seed `index`'s final policy (mean action, no exploration)."""
        task = self.cfg.task
        if algorithm_of(self.cfg) == "pi2cma":
            from artic.learning.rollout import dmp_actor
            from artic.policies.dmp import DMPFile

            path = verify_file(self.folder, self.manifest, f"{seed_dir(index)}/dmp.json")
            dmp = DMPFile.from_json_dict(json.loads(path.read_text()))
            k_p = self.cfg.pi2cma_policy.k_p
            return dmp_actor(dmp.params, dmp.cfg, task.control_dt, task.horizon, k_p)
        from artic.artifacts.model_file import load_torch_file
        from artic.learning.rollout import gaussian_actor
        from artic.policies.gaussian_mlp import GaussianMLPPolicy

        path = verify_file(self.folder, self.manifest, f"{seed_dir(index)}/policy.pt")
        saved = load_torch_file(path, "policy file")  # weights_only: tensors and plain data
        try:
            h = saved["hparams"]
            policy = GaussianMLPPolicy(h["obs_dim"], h["act_dim"], tuple(h["hidden"]),
                                       min_log_std=h["min_log_std"])  # fmt: skip
            policy.load_state_dict(saved["state_dict"])
        except (KeyError, TypeError, ValueError, RuntimeError) as err:
            raise InputError(f"{path}: policy does not load ({type(err).__name__})") from None
        return gaussian_actor(policy)


def curve_stats(curve: np.ndarray) -> np.ndarray:
    """(updates, 4) rows [update, rollouts, mean, sem] of the normalised return over seeds
    for a learning_curve table (rows, 7); updates that not every seed reached are left out."""
    seeds = np.unique(curve[:, 0])
    out = []
    for u in np.unique(curve[:, 1]):
        at = curve[curve[:, 1] == u]
        if len(at) != len(seeds):
            continue
        x = at[:, 4]
        sem = x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else 0.0
        out.append([u, at[0, 2], x.mean(), sem])
    return np.array(out, dtype=np.float64).reshape(-1, 4)


def bootstrap_verdict(
    stats: dict[str, np.ndarray], reach_fraction: float, reach_within: int
) -> dict[str, Any]:
    """Figure 5.2's two verdicts from the `curve_stats` of each init: whether the
    bootstrapped mean beats the random one at every common update (and where it does
    not), and the first update at which it reaches `reach_fraction` of its final value
    (None if that is <= 0), and whether that is within `reach_within` updates."""
    b, r = stats["bootstrap"], stats["random"]
    common = sorted(set(b[:, 0]) & set(r[:, 0]))
    bm = dict(zip(b[:, 0], b[:, 2], strict=True))
    rm = dict(zip(r[:, 0], r[:, 2], strict=True))
    behind = [int(u) for u in common if not bm[u] > rm[u]]
    final = float(b[-1, 2])
    reached = [int(u) for u, m in zip(b[:, 0], b[:, 2], strict=True) if m >= reach_fraction * final]
    reach = reached[0] if final > 0 and reached else None
    return {
        "beats_every_update": not behind and bool(common),
        "behind_at": behind,
        "reach_update": reach,
        "reach_ok": reach is not None and reach <= reach_within,
    }
