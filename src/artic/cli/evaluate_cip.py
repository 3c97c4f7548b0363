"""`artic evaluate cip`: Fig. 7.3 and 7.4 (thesis section 7.4) and the targets of issue 21
from the train-cip folders of the tasks (`runs.<task>=`; null leaves a task out). The
config and the runs read back are `artic.learning.cip_evaluate`; the statistics, the
targets and the plots are `artic.evaluation.cip_report`.

One chunk. Outputs: `success.csv` (scale, task, setting, episode, success_best_mean,
success_best_se, violation_rate; the 4-task mean as task `mean`), `table.md`,
`fig_7_3.png` (best-to-date success), `fig_7_4.png` (violation rate).
"""

from __future__ import annotations

from pathlib import Path

from artic.artifacts.formats import read_csv, write_csv
from artic.cli.stage_runner import Plan, Stage
from artic.evaluation import cip_report as report
from artic.learning.cip_evaluate import CipRun, EvaluateCipConfig


def _runs(inputs: dict[str, Path]) -> dict[str, CipRun]:
    return {task: CipRun.open(folder, task) for task, folder in inputs.items()}


def _plan(cfg: EvaluateCipConfig, inputs: dict[str, Path]) -> Plan:
    _runs(inputs)  # bad input before any output
    return Plan([1], "reports")


def evaluate_chunk(cfg: EvaluateCipConfig, inputs: dict[str, Path], chunk: int, tmp: Path) -> int:
    """success.csv, table.md and the two figures."""
    runs = _runs(inputs)
    rows = report.success_rows({t: r.scale for t, r in runs.items()},
                               {t: r.curve for t, r in runs.items()})  # fmt: skip
    write_csv(tmp / "success.csv", report.SUCCESS_COLUMNS, rows)
    sources = {t: f"{r.folder} (scale {r.scale})" for t, r in runs.items()}
    (tmp / "table.md").write_text(report.report_markdown(rows, sources))
    report.curve_figure(tmp / "fig_7_3.png", rows, 4, "best-to-date success")
    report.curve_figure(tmp / "fig_7_4.png", rows, 6, "violation rate")
    return 1


def _finalize(
    cfg: EvaluateCipConfig, inputs: dict[str, Path], work: Path
) -> dict[str, float | int | str]:
    rows = read_csv(work / "success.csv")[1:]
    end = report.last_episode(rows)
    return {f"{r[1]} {r[2]}": f"success {float(r[4]):.2f} (episode {end})"
            for r in rows if int(r[3]) == end}  # fmt: skip


STAGE: Stage[EvaluateCipConfig] = Stage(
    name="evaluate-cip",
    command="evaluate cip",
    help=(
        "Fig. 7.3, 7.4: success and violations of the seven settings on the four tasks.\n\n"
        "Example: artic evaluate cip"
    ),
    conf="evaluate_cip",
    schema=EvaluateCipConfig,
    plan=_plan,
    chunk=evaluate_chunk,
    finalize=_finalize,
    one_chunk=True,
    inputs={"door": "train-cip", "drawer": "train-cip", "slide": "train-cip", "lever": "train-cip"},
    input_paths=lambda cfg: cfg.input_paths(),
)
