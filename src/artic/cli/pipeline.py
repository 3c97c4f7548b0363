"""`artic pipeline NAME`: run the stages of `stages/NAME.yaml` in order.

A pipeline file (`artic.config.pipeline_file`: its schema, `vars` and `${...}`
substitution) maps stage names to `{cmd, overrides, deps, outs, resources}`; `cmd` is a
registered stage's name (`cli/registry.py`), or an alias of one (`render-depth` with
`render=scan`). Each stage runs in this process through the same runner as its
subcommand, so an up-to-date stage is skipped by its own manifest check. `deps` must be
produced by an earlier stage or exist already; `outs` must name the folder the stage
writes. With `launcher=local|slurm` the stages run as submitit jobs instead
(`cli/launcher.py`, which also answers `--status`); each stage's line echoes the command
that runs it alone.
"""

from __future__ import annotations

import logging
import shlex
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from artic.cli.registry import StageEntry, load_stage, resolve, say_alias, stage_entries
from artic.cli.stage_runner import resolved_config, run_stage
from artic.config import pipeline_file
from artic.config.launcher import LauncherConfig
from artic.config.pipeline_file import (
    Pipeline,
    PipelineStage,
    common_folder,
    norm,
    overrides_taken,
    parse_pipeline,
    pipeline_path,
    relative_out,
)
from artic.config.pipeline_file import parse_vars as parse_vars
from artic.errors import InputError

log = logging.getLogger("artic")


def load_pipeline(path: Path, values: dict[str, str] | None = None) -> Pipeline:
    """The pipeline file `path`, checked against the stage registry (`load_pipeline`)."""
    return pipeline_file.load_pipeline(path, stage_entries(), values)


def run_pipeline(
    name: str,
    force: bool = False,
    dry_run: bool = False,
    values: dict[str, str] | None = None,
    launcher: LauncherConfig | None = None,
    status: bool = False,
    extra: list[str] | None = None,
) -> None:
    """Run (or, with `dry_run`, list; with `status`, report on) the pipeline `name`.
    `launcher`: None or inline runs the stages here, else as submitit jobs
    (`cli/launcher.py`); `extra`: KEY=VALUE setting a variable the file declares, else an
    override added to every stage that accepts it (`stage_overrides`)."""
    path = pipeline_path(name)
    declared = parse_pipeline(path.read_text(), str(path)).vars
    # KEY=VALUE of a variable the file declares sets it (`artic bootstrap experiment=quick`)
    as_vars = {k: v for k, _, v in (o.partition("=") for o in extra or []) if k in declared}
    extra = [o for o in extra or [] if o.partition("=")[0] not in as_vars]
    pipeline = load_pipeline(path, {**(values or {}), **as_vars})
    planned = _plan(path, pipeline, extra)
    console = Console()
    verbose = logging.getLogger().isEnabledFor(logging.INFO)  # not under --quiet
    if status:
        _print_status(name, path, planned, console)
        return
    if launcher is not None and launcher.name != "inline" and not dry_run:
        from artic.cli.launcher import launch

        jobs = launch(path, planned, launcher, force=force, say=log.info)
        if not jobs:
            log.info("pipeline %s: every stage is up to date; nothing submitted", name)
        elif launcher.name == "slurm":
            log.info(
                "pipeline %s: %d stage(s) submitted; artic pipeline %s --status",
                name,
                len(jobs),
                name,
            )
        return
    rows = [(stage_name, out) for stage_name, *_, out in planned]
    table, common = _table(name, path, rows, not dry_run, console.width)
    for stage_name, spec, entry, stage, out in planned:
        if dry_run:
            table.add_row(stage_name, "planned", relative_out(out, common))
            continue
        if verbose:
            console.print(
                f"[bold]{stage_name}[/]: {escape(command_line(entry, spec.overrides))}",
                soft_wrap=True,
            )
        t0 = time.perf_counter()
        result = run_stage(stage, list(spec.overrides), force=force)
        say_alias(spec.cmd, entry)
        if result.status == "partial":
            raise InputError(f"{path}: stage {stage_name} did not finish: {result.message}")
        table.add_row(
            stage_name, result.status, f"{time.perf_counter() - t0:.1f}", relative_out(out, common)
        )
    if verbose or dry_run:
        console.print(table)


Planned = tuple[str, PipelineStage, StageEntry, Any, str]


def _plan(path: Path, pipeline: Pipeline, extra: list[str]) -> list[Planned]:
    """Every stage's config composed and validated before the first one runs (a later
    stage's inputs may not exist yet: they are checked when that stage runs)."""
    from artic.config.compose import validate

    planned: list[Planned] = []
    given = stage_overrides(path, pipeline, extra)
    for stage_name, spec in pipeline.stages.items():
        entry = resolve(spec.cmd, spec.overrides)
        stage = load_stage(entry.name)
        if given[stage_name]:
            spec = spec.model_copy(update={"overrides": [*spec.overrides, *given[stage_name]]})
        try:
            raw = resolved_config(stage, spec.overrides)
            validate(stage.schema, raw)
        except InputError as err:
            raise InputError(f"{path}: stage {stage_name}: {err}") from None
        out = str(raw["out"])
        if spec.outs and norm(out) not in {norm(o) for o in spec.outs}:
            raise InputError(f"{path}: stage {stage_name}: writes {out}, not listed in its outs")
        planned.append((stage_name, spec, entry, stage, out))
    return planned


def stage_overrides(path: Path, pipeline: Pipeline, extra: list[str]) -> dict[str, list[str]]:
    """Which of the overrides `extra` (`seeds=2`) each stage takes (`overrides_taken`:
    those its config composes with)."""

    def compose(spec: PipelineStage, more: list[str]) -> dict[str, Any]:
        return resolved_config(load_stage(resolve(spec.cmd, spec.overrides).name), more)

    return overrides_taken(str(path), pipeline, extra, compose)


def command_line(entry: StageEntry, overrides: list[str]) -> str:
    """The command that runs a pipeline stage alone (`artic evaluate bootstrap ...`: the
    stage's command words from the registry, shell-quoted overrides)."""
    return shlex.join(["artic", *entry.command, *overrides])


def _table(
    name: str, path: Path, rows: list[tuple[str, str]], with_seconds: bool, width: int
) -> tuple[Table, str]:
    """The summary table of `rows` (stage, out), readable at 80 columns (`width`):
    outputs relative to their common folder (named in the title), kept whole when the
    line has room, else folded onto a second line, never cut."""
    common = common_folder([out for _, out in rows])
    title = f"pipeline {name} ({path})" + (f"\noutputs under {common}/" if common else "")
    table = Table(title=title, title_justify="left")
    table.add_column("stage", overflow="fold")
    table.add_column("status", no_wrap=True)
    if with_seconds:
        table.add_column("s", justify="right", no_wrap=True)
    widest = max((len(relative_out(out, common)) for _, out in rows), default=0)
    # the other columns at their widest ("complete", "1234.5"), padding and borders
    columns = 4 if with_seconds else 3
    stage = max((len(s) for s, _ in rows), default=5)
    fixed = stage + len("complete") + (6 if with_seconds else 0) + 2 * columns + columns + 1
    table.add_column("output", overflow="fold", min_width=max(1, min(widest, width - fixed)))
    return table, common


def _print_status(name: str, path: Path, planned: list[Planned], console: Console) -> None:
    """Per stage: done / running / failed / missing shards / waiting / not started, from
    the output folders and the launcher's job records; a failed job's last log lines."""
    from artic.artifacts.cluster import slurm_state
    from artic.artifacts.job_records import describe, job_states, tail
    from artic.cli.launcher import stage_progress

    table = Table(title=f"pipeline {name} ({path})", title_justify="left")
    table.add_column("stage", overflow="fold")
    table.add_column("state", no_wrap=True)
    table.add_column("details", overflow="fold")
    failures = []
    for stage_name, spec, _entry, stage, out in planned:
        jobs = job_states(Path(out), slurm_state)
        shards = jobs[0].shards if jobs else 1
        progress = stage_progress(stage, list(spec.overrides), shards)
        state, details = describe(progress, jobs)
        table.add_row(stage_name, state, details)
        if state == "failed":
            failures += [(stage_name, j) for j in jobs if j.state != "COMPLETED"]
    console.print(table)
    for stage_name, job in failures:
        lines = tail(job.stderr)
        if lines:
            console.print(f"[red]{stage_name}[/]: job {job.id}, last lines of {job.stderr}:")
            console.print("\n".join(lines), markup=False, highlight=False, soft_wrap=True)
