"""One output writer: how an output folder is checked, identified and published, shared
by the stage runner (`cli/stage_runner.run_stage`) and by segment / build-hierarchy /
infer-hierarchy (`artifacts/scan_outputs.OutputFolder`).

Everything is written into the work area (`artifacts.workdir.WorkDir`, the sibling
`DIR.partial/`), the log copied into its `artic.log`; `publish` lists its content into
`manifest.json` and renames it into place under the work area's lock.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from artic.artifacts.formats import write_json
from artic.artifacts.hashing import sha256_json
from artic.artifacts.manifest import (
    MANIFEST,
    InputRecord,
    Manifest,
    list_outputs,
    now_iso,
    outputs_hash,
    package_versions,
    read_manifest,
    verify_outputs,
)
from artic.artifacts.workdir import WorkDir
from artic.config.schemas import NON_OUTPUT_KEYS
from artic.errors import InputError


def config_hash_of(stage: str, config: dict[str, Any], input_keys: Iterable[str]) -> str:
    """The config hash of a stage output: the resolved config without the keys that do
    not change the outputs (`NON_OUTPUT_KEYS` and the paths of the stage's inputs)."""
    skip = set(NON_OUTPUT_KEYS) | set(input_keys)
    return sha256_json(
        {"stage": stage, "config": {k: v for k, v in config.items() if k not in skip}}
    )


def check_out(out: Path) -> None:
    """`out` must be a folder or not exist yet, under folders: InputError otherwise."""
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                if p == out:
                    raise InputError(f"out: {out} is a file, not a folder")
                raise InputError(f"out: cannot write to {out} ({p} is a file)")
            return


def up_to_date(out: Path, config_hash: str, input_hashes: dict[str, str]) -> Manifest | None:
    """The manifest of `out` when it is up to date (every file checked), else None."""
    if not (out / MANIFEST).is_file():
        return None
    previous = read_manifest(out)
    same_inputs = {k: r.content_hash for k, r in previous.inputs.items()} == input_hashes
    if previous.config_hash != config_hash or not same_inputs:
        return None
    verify_outputs(out, previous)
    return previous


def check_integrity(folder: Path, manifest: Manifest, input_keys: Iterable[str] | None) -> None:
    """A manifest edited by hand is refused: its config must give its config hash (as
    the stage that wrote it computes it) and its outputs listing its content hash.
    `input_keys`: the input names of the stage that wrote it (None: not a registered
    stage, whose config hash is not checked)."""
    where = folder / MANIFEST
    if outputs_hash(manifest.outputs) != manifest.content_hash:
        raise InputError(
            f"{where}: content_hash does not match the listed outputs (edited by hand?); "
            "rerun the stage that made it with --force"
        )
    if input_keys is None:
        return
    keys = set(input_keys)
    # outputs made before 2026-11-26 included the input paths in the hash
    accepted = {config_hash_of(manifest.stage, manifest.config, k) for k in (keys, set())}
    if manifest.config_hash not in accepted:
        raise InputError(
            f"{where}: config does not match config_hash (edited by hand?); "
            "rerun the stage that made it with --force"
        )


def log_to(path: Path) -> logging.Handler:
    """Copy the log (every level, with tracebacks) into `path`, the folder's artic.log."""
    handler = logging.FileHandler(path)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    logging.getLogger().addHandler(handler)
    return handler


def stop_log(handler: logging.Handler) -> None:
    """Stop copying the log into the folder (idempotent)."""
    logging.getLogger().removeHandler(handler)
    handler.close()


@dataclass(frozen=True)
class ManifestHead:
    """What a manifest says about how an output was made: the stage (or command), its
    resolved config and config hash, the seed and the inputs."""

    stage: str
    config: dict[str, Any]
    config_hash: str
    seed: int
    inputs: dict[str, InputRecord]
    #: the config-group options the config was composed from (debug, experiment, ...)
    choices: dict[str, str] = field(default_factory=dict)


def publish(
    work: WorkDir, head: ManifestHead, stats: dict[str, float | int | str], started: str, t0: float
) -> Manifest:
    """Write `manifest.json` (every file of the work area, its content hash, the
    versions, the times) into the work area, then rename it to the output folder, under
    the work area's lock. `started`/`t0`: `now_iso()` / `time.perf_counter()` at the
    start of the run."""
    with work.locked():
        outputs = list_outputs(work.path)
        manifest = Manifest(
            stage=head.stage,
            config=head.config,
            config_hash=head.config_hash,
            seed=head.seed,
            inputs=head.inputs,
            choices=head.choices,
            outputs=outputs,
            content_hash=outputs_hash(outputs),
            versions=package_versions(),
            started_at=started,
            finished_at=now_iso(),
            wall_time_s=round(time.perf_counter() - t0, 3),
            stats=stats,
        )
        write_json(work.path / MANIFEST, manifest.model_dump(mode="json"))
        work.publish()
    return manifest
