"""`artic pipeline NAME launcher=local|slurm`: how far each stage's output is (its config
read through the stage runner) and what each job runs; which jobs the stages become and
their submission are `artifacts/cluster.py` (`plan_jobs`, submitit), the records, an
output's progress and the status words `artifacts/job_records.py`.

Each job runs its stage the way its subcommand does (`stage_runner.run_stage`, the same
overrides), so the outputs are the same bytes as `launcher=inline`'s. A stage whose
resources ask for `shards: N > 1` becomes a job array of its shards (`shard.index=i
shard.count=N`: round-robin chunks; the work area's file locks let them run at once)
followed by one publish job, which publishes once every chunk is done (usually the last
shard has already done it; then it checks the output) or fails naming the shards that
are missing. `shards: chunks` is one shard per chunk of work (policy-search: one job per
seed). Submitting again runs only what is missing: a stage whose output is up to date is
not submitted, a sharded stage with finished chunks gets an array of its missing shards.
Everything is checked (configs, shard support, executor options, `sbatch` on PATH)
before the first job is submitted.
"""

from __future__ import annotations

import functools
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from artic.artifacts.cluster import JobFailed, JobSpec, StageJob, plan_jobs, submit
from artic.artifacts.job_records import output_progress
from artic.artifacts.output import config_hash_of
from artic.artifacts.workdir import Progress, shard_names
from artic.cli.stage_runner import InternalError
from artic.config.launcher import LauncherConfig
from artic.config.pipeline_file import PipelineStage

log = logging.getLogger("artic")


class JobsFailed(InternalError):
    """A job of a launched pipeline failed (exit code 1, one line naming the stage, the
    jobs, the last error line and the log)."""


# -- what a job runs ---------------------------------------------------------------------


def run_job(spec: JobSpec) -> str:
    """The body of every job (in the job's own process): the stage through the stage
    runner, as its subcommand runs it. Returns the runner's status."""
    from artic.cli.registry import load_stage
    from artic.cli.stage_runner import run_stage

    os.chdir(spec.cwd)
    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(message)s", stream=sys.stderr, force=True
    )
    stage = load_stage(spec.stage)
    overrides = list(spec.overrides)
    if spec.role == "publish":
        p = stage_progress(stage, overrides, spec.shards)
        if p.missing:
            raise JobsFailed(
                f"{p.out}: not published, {shard_names(p.missing, spec.shards)} did "
                f"not finish ({p.chunks_done} of {p.n_chunks} chunks done); submit the "
                "pipeline again to run them",
                None,
            )
    elif spec.role == "shard":
        overrides += [f"shard.index={spec.shard}", f"shard.count={spec.shards}"]
    result = run_stage(stage, overrides, force=spec.force and spec.role != "publish")
    log.info("%s %s: %s %s", spec.role, spec.stage, result.status, result.message)
    if spec.role != "shard" and result.status == "partial":
        raise JobsFailed(f"{result.out}: {result.message}", None)
    return result.status


# -- how far a stage is ------------------------------------------------------------------


def stage_progress(stage: Any, overrides: list[str], shards: int) -> Progress:
    """The progress of a stage's output for `shards` shards (read only)."""
    from artic.cli.stage_runner import resolved_config
    from artic.config.compose import validate

    raw = resolved_config(stage, overrides)
    cfg = validate(stage.schema, raw)
    config_hash = config_hash_of(stage.name, raw, stage.inputs)
    paths = functools.partial(stage.input_paths, cfg)
    return output_progress(Path(cfg.out), config_hash, paths, plan_chunks(stage, cfg), shards)


def plan_chunks(stage: Any, cfg: Any) -> int | None:
    """How many chunks the stage's work splits into: its plan with its inputs, else its
    plan from the config alone (policy-search's seeds), else 1 when its plan always has
    one chunk (`Stage.one_chunk`), else None (not known before its inputs exist)."""
    for inputs in (lambda: stage.input_paths(cfg), dict):
        try:
            return int(stage.plan(cfg, inputs()).n_chunks)
        except Exception:  # a plan that cannot be made yet: try the next
            continue
    return 1 if stage.one_chunk else None


# -- submission --------------------------------------------------------------------------


def launch(
    path: Path,
    planned: Sequence[tuple[str, PipelineStage, Any, Any, str]],
    launcher: LauncherConfig,
    force: bool = False,
    say: Any = print,
) -> list[StageJob]:
    """Submit the pipeline's stages that are not up to date (module docstring); `say`
    prints a line per stage. Returns the stages submitted."""
    stages = {name: (stage, list(spec.overrides)) for name, spec, _, stage, _ in planned}

    def progress(name: str, shards: int) -> Progress:
        return stage_progress(*stages[name], shards)

    jobs = plan_jobs(
        path, [(n, s, e.name, o) for n, s, e, _, o in planned], launcher, force, progress
    )
    try:
        submit(launcher, jobs, run_job, str(Path.cwd()), force, say)
    except JobFailed as err:
        raise JobsFailed(str(err), err.log) from None
    return jobs
