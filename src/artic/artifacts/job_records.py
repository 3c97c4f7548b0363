"""The cluster jobs of one stage output, as files beside its work folder: where they are
kept, what `artic pipeline NAME --status` reads, and how a stage's state is put in words.

`artic pipeline NAME launcher=local|slurm` (`artifacts/cluster.py`) gives each stage output
`out` a submitit folder `<out>.jobs/` beside `<out>.partial/`: the jobs' stdout/stderr
(`<job id>_0_log.out/.err`), their result files (`<job id>_0_result.pkl`, written by
submitit: ("success", value) or ("error", traceback)) and `jobs.json`, the jobs of every
submission (`{"submissions": [{"launcher", "at", "jobs": [{"id", "role", "shard",
"shards", "stdout", "stderr"}]}]}`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from artic.artifacts.formats import write_json
from artic.artifacts.manifest import MANIFEST, read_manifest
from artic.artifacts.workdir import Progress, progress_of, shard_names
from artic.errors import InputError

#: the record of the submissions of one stage, in its submitit folder
JOBS_JSON = "jobs.json"
#: lines of a failed job's log shown by --status
TAIL_LINES = 8


def jobs_folder(out: Path) -> Path:
    """The submitit folder of output `out`: `<out>.jobs/`, beside `<out>.partial/`."""
    return out.with_name(out.name + ".jobs")


def read_jobs(out: Path) -> dict[str, Any]:
    """The jobs.json of output `out` ({} when it has none or it cannot be read)."""
    try:
        data = json.loads((jobs_folder(out) / JOBS_JSON).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def record_jobs(out: Path, launcher: str, jobs: list[dict[str, Any]], new: bool) -> None:
    """Write `jobs` (all the jobs of this launch so far) as the last submission of `out`
    (`new`: as a new submission)."""
    record = read_jobs(out)
    submissions = record.setdefault("submissions", [])
    if new or not submissions:
        at = datetime.now(UTC).isoformat(timespec="seconds")
        submissions.append({"launcher": launcher, "at": at, "jobs": []})
    submissions[-1]["jobs"] = jobs
    write_json(jobs_folder(out) / JOBS_JSON, record)


def job_outcome(result_file: Path) -> str | None:
    """ "success" or "error" from a submitit result file, None when there is none."""
    import pickle

    try:
        with result_file.open("rb") as f:
            outcome = pickle.load(f)[0]
    except (OSError, EOFError, pickle.UnpicklingError, IndexError, TypeError):
        return None
    return str(outcome)


def result_file(stderr: Path, job_id: str) -> Path:
    """The result file of job `job_id` whose stderr is `stderr` (task 0)."""
    return stderr.with_name(f"{job_id}_0_result.pkl")


def tail(path: Path, n: int = TAIL_LINES) -> list[str]:
    """The last `n` lines of a file ([] when it cannot be read)."""
    try:
        with path.open("rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - 64 * 1024))
            text = f.read().decode("utf-8", "replace")
    except OSError:
        return []
    return text.splitlines()[-n:]


def last_error(log: Path) -> str:
    """The last line of a failed job's log that is not part of a traceback's frames."""
    for line in reversed(tail(log, 40)):
        if line.strip() and not line.startswith(("  ", "Traceback")):
            return line.strip()
    return "no log (killed before it started?)"


@dataclass(frozen=True)
class JobState:
    """One recorded job and its state (COMPLETED, FAILED, RUNNING, PENDING, UNKNOWN, ...)."""

    id: str
    role: str  # "stage", "shard" or "publish"
    shard: int
    shards: int
    state: str
    stderr: Path

    @property
    def name(self) -> str:
        return f"shard.index={self.shard}" if self.role == "shard" else self.role


def job_states(out: Path, slurm_state: Callable[[Path, str], str]) -> list[JobState]:
    """The jobs of the last submission of output `out` and their states: from their
    result files; else `slurm_state(folder, id)` for a SLURM job, or whether a local
    job's process (its id is the pid) still lives."""
    submissions = read_jobs(out).get("submissions") or []
    if not submissions:
        return []
    last = submissions[-1]
    states = []
    for j in last.get("jobs", []):
        stderr = Path(j["stderr"])
        outcome = job_outcome(result_file(stderr, j["id"]))
        if outcome is not None:
            state = "COMPLETED" if outcome == "success" else "FAILED"
        elif last.get("launcher") == "slurm":
            state = slurm_state(stderr.parent, j["id"])
        else:
            state = "RUNNING" if _alive(j["id"]) else "FAILED"
        states.append(JobState(j["id"], j["role"], j["shard"], j["shards"], state, stderr))
    return states


def _alive(pid: str) -> bool:
    try:
        os.kill(int(pid), 0)
    except (ValueError, ProcessLookupError, PermissionError):
        return False
    return True


def output_progress(
    out: Path,
    config_hash: str,
    input_paths: Callable[[], dict[str, Path]],
    n_chunks: int | None,
    shards: int,
) -> Progress:
    """The progress of stage output `out` for `shards` shards (read only): "waiting" while
    an input of `input_paths()` (which may read an input to find the others) cannot be
    found or has no manifest yet, else `progress_of` the config and the inputs' content
    hashes."""
    hashes: dict[str, str] = {}
    try:
        paths = input_paths()
    except (InputError, OSError):
        return Progress(out, "waiting", n_chunks=n_chunks)
    for name, path in paths.items():
        if not (Path(path) / MANIFEST).is_file():
            return Progress(out, "waiting", n_chunks=n_chunks)
        hashes[name] = read_manifest(Path(path)).content_hash
    return progress_of(out, config_hash, hashes, n_chunks, shards)


_ACTIVE = {"RUNNING", "PENDING", "REQUEUED", "CONFIGURING", "COMPLETING", "SUSPENDED"}


def describe(progress: Progress, jobs: Sequence[JobState]) -> tuple[str, str]:
    """A stage's state in a word (done, running, pending, failed, submitted, missing,
    waiting, not started) and its details (chunks, missing shards, job ids)."""
    if progress.state == "done":
        return "done", ""
    active = [j for j in jobs if j.state.split()[0] in _ACTIVE]
    failed = [j for j in jobs if j.state.split()[0] not in _ACTIVE | {"COMPLETED", "UNKNOWN"}]
    unknown = [j for j in jobs if j.state == "UNKNOWN"]
    shards = jobs[0].shards if jobs else 1
    chunks = missing = ""
    if progress.state == "partial" and progress.n_chunks:
        chunks = f"{progress.chunks_done}/{progress.n_chunks} chunks"
    if progress.state == "partial" and progress.missing and shards > 1:
        missing = f"missing {shard_names(progress.missing, shards)}"
    if active:
        word = "running" if any(j.state.startswith("RUNNING") for j in active) else "pending"
        return word, ", ".join(x for x in (chunks, "jobs " + _ids(active)) if x)
    if failed:
        names = ", ".join(f"{j.id} ({j.name}: {j.state.lower()})" for j in failed)
        return "failed", ", ".join(x for x in (missing or chunks, names) if x)
    if unknown:
        return "submitted", f"jobs {_ids(unknown)}: state unknown (no sacct here)"
    if progress.state == "partial":
        return "missing", missing or chunks
    if progress.state == "waiting":
        return "waiting", "inputs not made yet"
    return "not started", ""


def _ids(jobs: Sequence[JobState]) -> str:
    return ", ".join(j.id for j in jobs)
