"""`artic fit-dmp`: DMPs fitted to motion-planned demonstrations (Algorithm 1, line 6).

Reads a plan-demos output folder (`demos.json` + `demo_*.npz`), fits one DMP per robot
joint by locally weighted regression over the successful demos (thesis section 5.2.1,
Eq. 2.4-2.7; `artic.policies.dmp.fit_dmp`), and writes:

- `dmp.json`: task, control dt, gains, basis and parameters (docs/formats.md, Chapter 5);
- `fit.csv`: per demo and joint (rad), the demo's range, the RMS reproduction error of
  the written DMP rolled out at the demo's time stamps (`rms`), and that of the fitted
  weights with the demo's own start, goal and duration (`rms_own`). With one demo the
  two agree and measure the fit alone; with several, `rms_own` also shows how far a
  demo's amplitude is from the pooled forcing (Eq. 2.7 does not scale f with g - y0);
- `fit.png` (if `plot`): each joint's demos and the DMP rollout.

One chunk (the fit is milliseconds); no sharding.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from artic.artifacts.demo_dataset import load_demos
from artic.artifacts.formats import write_csv, write_json
from artic.cli.stage_runner import Plan, Stage
from artic.policies.dmp import DMP_JSON, DMPFile, fit_dmp, rollout_dmp
from artic.policies.dmp_fit import FIT_COLUMNS, FitDmpConfig, fit_stats, reproduction_rows

FIT_CSV = "fit.csv"
FIT_PNG = "fit.png"


def _plan(cfg: FitDmpConfig, inputs: dict[str, Path]) -> Plan:
    demos = load_demos(inputs["demos"], cfg.task.name, cfg.max_demos)
    return Plan([len(demos.demos)], "demos")


def fit_chunk(cfg: FitDmpConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """Fit the DMPs; writes dmp.json, fit.csv (and fit.png) into tmp."""
    demos = load_demos(inputs["demos"], cfg.task.name, cfg.max_demos)
    params = fit_dmp([d.t for d in demos.demos], [d.q for d in demos.demos], cfg.dmp)
    record = DMPFile(cfg.task.name, demos.control_dt, params, cfg.dmp).to_json_dict()
    record["demos_used"] = [d.file for d in demos.demos]
    write_json(tmp / DMP_JSON, record)
    rows = reproduction_rows(demos.demos, params, cfg.dmp, demos.control_dt)
    write_csv(tmp / FIT_CSV, FIT_COLUMNS, rows)
    if cfg.plot:
        from artic.evaluation.plots import dmp_fit_plot

        longest = max(d.t.shape[0] for d in demos.demos)
        traj = rollout_dmp(params, cfg.dmp, demos.control_dt, longest)
        title = f"{demos.task}: DMPs ({cfg.dmp.n_basis} basis functions) vs demos"
        dmp_fit_plot(tmp / FIT_PNG, [(d.t, d.q) for d in demos.demos], (traj.t, traj.y), title)
    return len(demos.demos)


def _finalize(
    cfg: FitDmpConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    info = json.loads((work / DMP_JSON).read_text())
    with (work / FIT_CSV).open(newline="") as f:
        table = list(csv.DictReader(f))
    return {
        "task": cfg.task.name,
        "demos used": len(info["demos_used"]),
        "basis functions": cfg.dmp.n_basis,
        "tau (s)": round(float(info["tau"]), 4),
        **fit_stats(table),
    }


STAGE: Stage[FitDmpConfig] = Stage(
    name="fit-dmp",
    help=(
        "Dynamic movement primitives fitted to demonstrations by LWR (Eq. 2.4-2.7).\n\n"
        "Example: artic fit-dmp demos=artifacts/demos/drawer"
    ),
    task_option=True,
    conf="fit_dmp",
    schema=FitDmpConfig,
    plan=_plan,
    chunk=fit_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"demos": "plan-demos"},
    input_paths=lambda cfg: {"demos": Path(cfg.demos)},
)
