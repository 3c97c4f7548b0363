"""`write_manifest`: make a folder of hand-written files a stage output, for tests that
need an input of a stage without running it (e.g. plan-demos' demos)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from artic.artifacts.formats import write_json
from artic.artifacts.manifest import MANIFEST, Manifest, list_outputs, now_iso, outputs_hash
from artic.artifacts.output import config_hash_of


def write_manifest(folder: Path, stage: str, config: dict[str, Any]) -> None:
    """The manifest of `folder`'s files as `stage` with `config` would have written it
    (hashes computed as the stage runner does, so downstream stages accept it)."""
    outputs = list_outputs(folder)
    manifest = Manifest(
        stage=stage, config=config, config_hash=config_hash_of(stage, config, ()), seed=0,
        inputs={}, outputs=outputs, content_hash=outputs_hash(outputs), versions={},
        started_at=now_iso(), finished_at=now_iso(), wall_time_s=0.0, stats={},
    )  # fmt: skip
    write_json(folder / MANIFEST, manifest.model_dump(mode="json"))
