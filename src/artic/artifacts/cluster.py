"""Stage jobs through submitit (the engine under Hydra's submitit launcher): what
`artic pipeline NAME launcher=local|slurm` submits. `plan_jobs` decides which stages and
shards, from each stage output's progress; `cli/launcher.py` reads that progress through
the stage runner and gives the function each job runs.

A stage is one job, or an array of shard jobs and one publish job after them. With
SLURM the whole pipeline is one submission: a stage's jobs wait for the final jobs of
the stages whose outputs it reads (`--dependency=afterok`), a publish job for its array
(`afterany`, so that it runs and names a failed shard). With the local executor (separate
processes on this machine, no dependencies) each stage is submitted once the one before
it is done, its shards at once. Every job is recorded in the stage's `<out>.jobs/jobs.json`
as soon as it is submitted (`artifacts.job_records`), beside the jobs' logs.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from artic.artifacts.job_records import job_outcome, jobs_folder, last_error, record_jobs
from artic.artifacts.workdir import Progress, shard_names
from artic.config.launcher import LauncherConfig, Resources, executor_parameters
from artic.config.pipeline_file import PipelineStage, norm
from artic.errors import InputError


@dataclass(frozen=True)
class JobSpec:
    """One job: stage `stage` (a registered name) with `overrides`, run in `cwd`;
    `role`: the whole stage, one shard of `shards`, or the publish job after them."""

    stage: str
    overrides: tuple[str, ...]
    cwd: str
    role: str  # "stage" | "shard" | "publish"
    shard: int = 0
    shards: int = 1
    force: bool = False

    @property
    def name(self) -> str:
        return f"shard.index={self.shard}" if self.role == "shard" else self.role


@dataclass
class StageJob:
    """One stage of a launch (pipeline stage `name` running registered stage `stage`
    into `out`): what to submit and, once submitted, its jobs."""

    name: str
    stage: str
    overrides: tuple[str, ...]
    deps: list[str]
    outs: list[str]
    out: Path
    resources: Resources
    shards: int
    todo: list[int]  # shards to submit (0-based); [0] for a single job
    jobs: list[dict[str, Any]] = field(default_factory=list)
    final_id: str | None = None  # the job the stages after it wait for

    @property
    def folder(self) -> Path:
        return jobs_folder(self.out)


class JobFailed(Exception):
    """A job failed (`log`: its stderr)."""

    def __init__(self, message: str, log: Path) -> None:
        super().__init__(message)
        self.log = log


#: what a job runs: a module-level function of its JobSpec (pickled by reference)
JobFn = Callable[[JobSpec], Any]


def plan_jobs(
    path: Path,
    planned: Sequence[tuple[str, PipelineStage, str, str]],
    launcher: LauncherConfig,
    force: bool,
    progress: Callable[[str, int], Progress],
) -> list[StageJob]:
    """The jobs of each stage not up to date (`planned`: name, spec, registered stage and
    out of each stage of pipeline file `path`; `progress(name, shards)`: how far stage
    `name`'s output is for `shards` shards, read only); shards asked of a stage with fewer
    chunks are bad input. A stage reading an output that this launch makes again is
    submitted whole (its job skips it if it is still up to date then)."""
    launch: list[StageJob] = []
    remade: set[str] = set()
    for name, spec, stage, out in planned:
        after_remade = bool({norm(d) for d in spec.deps} & remade)
        resources = launcher.resources(name, spec.resources)
        status = progress(name, 1)
        n_chunks, wanted = status.n_chunks, resources.shards or 1
        if wanted == "chunks" and n_chunks is None:
            raise InputError(
                f"{path}: stage {name}: shards: chunks, but its plan needs inputs that are "
                "not made yet; give a number of shards"
            )
        shards = n_chunks if wanted == "chunks" and n_chunks is not None else int(wanted)
        if shards > 1 and n_chunks is not None and n_chunks < shards:
            what = "no shard support (one chunk of work)" if n_chunks == 1 else "fewer chunks"
            raise InputError(
                f"{path}: stage {name} ({spec.cmd}) has {what}; asked for {shards} shards"
            )
        if status.state == "done" and not force and not after_remade:
            continue
        remade.update({norm(o) for o in (*spec.outs, out)})
        todo = list(range(shards))
        if shards > 1 and not force and not after_remade:
            todo = progress(name, shards).missing or todo
        overrides = tuple(spec.overrides)
        launch.append(
            StageJob(
                name, stage, overrides, spec.deps, spec.outs, Path(out), resources, shards, todo
            )
        )
    return launch


def submit(
    launcher: LauncherConfig,
    stages: Sequence[StageJob],
    fn: JobFn,
    cwd: str,
    force: bool = False,
    say: Callable[[str], Any] = print,
) -> None:
    """Submit `stages` in order (each job runs `fn(spec)` in `cwd`). Every executor is
    made and its parameters checked (by submitit) before the first submission: a
    parameter it rejects, or `sbatch` not on PATH, is bad input and nothing is
    submitted. With the local executor, waits for every job; JobFailed if one fails."""
    if launcher.name == "slurm":
        for tool in ("sbatch", "srun"):
            if shutil.which(tool) is None:
                raise InputError(
                    f"launcher=slurm: `{tool}` is not on PATH (run on the cluster's login "
                    "node, or use launcher=local)"
                )
    made = [job.folder for job in stages if not job.folder.exists()]
    try:
        executors = [_executor(launcher, job) for job in stages]
    except InputError:
        for folder in made:  # nothing submitted, nothing left behind
            shutil.rmtree(folder, ignore_errors=True)
        raise
    for job, executor in zip(stages, executors, strict=True):
        if launcher.name == "slurm":
            _submit_slurm(job, executor, stages, fn, cwd, force)
            say(_said(job))
        else:
            _run_local(job, executor, fn, launcher.poll_s, cwd, force, say)


def _executor(launcher: LauncherConfig, job: StageJob) -> Any:
    import submitit

    job.folder.mkdir(parents=True, exist_ok=True)
    executor = submitit.AutoExecutor(folder=job.folder, cluster=launcher.name)
    try:
        executor.update_parameters(
            **executor_parameters(launcher, job.resources, f"artic-{job.name}")
        )
    except (ValueError, NameError, AssertionError, TypeError) as err:
        first = (str(err).strip().splitlines() or [type(err).__name__])[0]
        raise InputError(f"launcher={launcher.name}: stage {job.name}: {first}") from None
    return executor


def _specs(job: StageJob, cwd: str, force: bool) -> tuple[list[JobSpec], JobSpec | None]:
    """The specs of the stage's (shard) jobs and of its publish job (None: one job)."""
    overrides = job.overrides
    if not any(o.startswith("runtime.workers=") for o in overrides):
        # a job's worker processes: the CPUs it asked for (runtime never changes bytes)
        overrides += (f"runtime.workers={job.resources.cpus_per_task or 1}",)
    if job.shards == 1:
        return [JobSpec(job.stage, overrides, cwd, "stage", force=force)], None
    shards = [JobSpec(job.stage, overrides, cwd, "shard", i, job.shards, force) for i in job.todo]
    return shards, JobSpec(job.stage, overrides, cwd, "publish", 0, job.shards)


def _record(job: StageJob, launcher: str, submitted: Sequence[tuple[JobSpec, Any]]) -> None:
    """Add submitted jobs to the stage's jobs.json (the first of a launch starts a new
    submission)."""
    new = not job.jobs
    for spec, sub in submitted:
        job.jobs.append(
            {
                "id": str(sub.job_id),
                "role": spec.role,
                "shard": spec.shard,
                "shards": spec.shards,
                "stdout": str(sub.paths.stdout),
                "stderr": str(sub.paths.stderr),
            }
        )
    record_jobs(job.out, launcher, job.jobs, new)


def _said(job: StageJob) -> str:
    ids = [j["id"] for j in job.jobs]
    if job.shards == 1:
        return f"{job.name}: job {ids[0]}"
    shards = (
        f"{job.shards} shards" if len(job.todo) == job.shards else shard_names(job.todo, job.shards)
    )
    array = ids[0].split("_")[0] if len(ids) > 2 else ids[0]
    return f"{job.name}: {shards} as array job {array}, then publish job {ids[-1]}"


def _depends_on(job: StageJob, stages: Sequence[StageJob]) -> list[str]:
    """Ids of the final jobs of the submitted stages whose outputs `job` reads."""
    deps = {norm(d) for d in job.deps}
    return [
        other.final_id
        for other in stages
        if other is not job
        and other.final_id is not None
        and deps & {norm(o) for o in (*other.outs, str(other.out))}
    ]


def _submit_slurm(
    job: StageJob, executor: Any, stages: Sequence[StageJob], fn: JobFn, cwd: str, force: bool
) -> None:
    waits = _depends_on(job, stages)
    if waits:
        executor.update_parameters(slurm_dependency="afterok:" + ":".join(waits))
    main, publish = _specs(job, cwd, force)
    with executor.batch():
        subs = [executor.submit(fn, spec) for spec in main]
    submitted = list(zip(main, subs, strict=True))
    if publish is not None:
        array_id = str(subs[0].job_id).split("_")[0]
        executor.update_parameters(slurm_dependency=f"afterany:{array_id}")
        submitted.append((publish, executor.submit(fn, publish)))
    _record(job, "slurm", submitted)
    job.final_id = str(submitted[-1][1].job_id)


def _run_local(
    job: StageJob,
    executor: Any,
    fn: JobFn,
    poll_s: float,
    cwd: str,
    force: bool,
    say: Callable[[str], Any],
) -> None:
    main, publish = _specs(job, cwd, force)
    submitted = []
    for spec in main:  # the local executor starts each job as it is submitted
        sub = executor.submit(fn, spec)
        _record(job, "local", [(spec, sub)])
        submitted.append((spec, sub))
    say(f"{job.name}: jobs {', '.join(str(sub.job_id) for _, sub in submitted)}")
    _wait([sub for _, sub in submitted], poll_s)
    if publish is not None:
        pub = executor.submit(fn, publish)
        _record(job, "local", [(publish, pub)])
        submitted.append((publish, pub))
        _wait([pub], poll_s)
    failed = [(spec, sub) for spec, sub in submitted if not _succeeded(sub)]
    if failed:
        log = Path(str(failed[-1][1].paths.stderr))
        names = ", ".join(f"{sub.job_id} ({spec.name})" for spec, sub in failed)
        raise JobFailed(
            f"stage {job.name}: job {names} failed: {last_error(log)}; --status shows every stage",
            log,
        )


def _wait(subs: Sequence[Any], poll_s: float) -> None:
    while not all(sub.done() for sub in subs):
        time.sleep(poll_s)


def _succeeded(sub: Any) -> bool:
    return job_outcome(Path(str(sub.paths.result_pickle))) == "success"


def slurm_state(folder: Path, job_id: str) -> str:
    """A SLURM job's state from the accounting (`sacct`, through submitit); UNKNOWN where
    there is no sacct or it does not answer."""
    import logging

    import submitit

    if shutil.which("sacct") is None:
        return "UNKNOWN"
    logging.getLogger("submitit").setLevel(logging.ERROR)  # its warnings, once per job
    try:
        return str(submitit.SlurmJob(folder=folder, job_id=job_id).state)
    except Exception:  # the accounting did not answer
        return "UNKNOWN"
