"""`manifest.json`: what a stage output holds and how it was made (the stage contract).

A manifest records the stage, the resolved config and its hash, each input's content
hash, every output file with its size and sha256, package versions, the seed, timings
and status. `content_hash` (the hash of the output listing, timing files left out) is
what downstream stages record as their input hash, so regenerating identical data does
not invalidate them.
"""

from __future__ import annotations

import platform
import subprocess
from datetime import UTC, datetime
from functools import cache
from importlib import metadata
from pathlib import Path
from typing import Any, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError

from artic import __version__
from artic.artifacts.hashing import sha256_file, sha256_json
from artic.errors import InputError
from artic.reproducibility import numerics_record

M = TypeVar("M", bound=BaseModel)

MANIFEST = "manifest.json"
LOG = "artic.log"
FORMAT_VERSION = 1
_TRACKED_PACKAGES = (
    "numpy",
    "scipy",
    "open3d",
    "pybullet",
    "trimesh",
    "yourdfpy",
    "hydra-core",
    "omegaconf",
    "pydantic",
    "pillow",
    "torch",
    "plyfile",
    "stable-baselines3",
    "gymnasium",
)


class FileRecord(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")
    size: int
    sha256: str


class InputRecord(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")
    path: str
    stage: str
    content_hash: str


class Manifest(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    format: int = FORMAT_VERSION
    stage: str
    status: Literal["complete"] = "complete"
    artic_version: str = __version__
    config: dict[str, Any]
    config_hash: str
    seed: int | None
    inputs: dict[str, InputRecord]
    #: the config-group options (`debug: tiny`, `experiment: ch3_cpu`); absent in older files
    choices: dict[str, str] = {}
    outputs: dict[str, FileRecord]
    content_hash: str
    versions: dict[str, str]
    started_at: str
    finished_at: str
    wall_time_s: float
    stats: dict[str, float | int | str]


def package_versions() -> dict[str, str]:
    """Versions of Python, artic and the numerical packages that shape the outputs, and
    the kernel pins in force (`artic.reproducibility`)."""
    out = {"python": platform.python_version(), "artic": __version__,
           "numerics": numerics_record()}  # fmt: skip
    commit = source_commit()
    if commit:
        out["artic_commit"] = commit
    for name in _TRACKED_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return out


@cache
def source_commit() -> str:
    """The git commit of the artic source running (`abc123def456`, `-dirty` appended when
    the checkout has uncommitted changes outside ignored files), or "" when artic is not
    running from a git checkout (an installed wheel)."""
    root = Path(__file__).resolve().parents[3]
    if not (root / ".git").exists() or not (root / "src" / "artic").is_dir():
        return ""
    try:
        git = ["git", "-C", str(root)]
        rev = [*git, "rev-parse", "--short=12", "HEAD"]
        head = subprocess.run(rev, capture_output=True, text=True, timeout=10, check=True)
        status = [*git, "status", "--porcelain", "--untracked-files=no"]
        dirty = subprocess.run(status, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""
    commit = head.stdout.strip()
    return f"{commit}-dirty" if dirty else commit


def now_iso() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def list_outputs(folder: Path) -> dict[str, FileRecord]:
    """Size and sha256 of every file under `folder` except the manifest and the log,
    keyed by POSIX relative path, sorted."""
    records: dict[str, FileRecord] = {}
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        rel = path.relative_to(folder).as_posix()
        if rel in (MANIFEST, LOG) or rel.startswith("."):
            continue
        records[rel] = FileRecord(size=path.stat().st_size, sha256=sha256_file(path))
    return records


#: output files that hold wall-clock times (documented in formats.md): listed and verified
#: like every output, but left out of `content_hash`, so a rerun that reproduces the same
#: data does not invalidate the stages downstream
TIMING_FILES = frozenset({"timings.csv", "timings.json"})


def is_timing_file(rel: str) -> bool:
    """Whether output `rel` (a POSIX relative path) is a timing file, by its file name."""
    return rel.rsplit("/", 1)[-1] in TIMING_FILES


def outputs_hash(outputs: dict[str, FileRecord]) -> str:
    """The content hash: sha256 of the listing of every output but the timing files."""
    return sha256_json({k: v.sha256 for k, v in outputs.items() if not is_timing_file(k)})


def read_manifest(folder: Path, expected_stage: str | None = None) -> Manifest:
    """The manifest of a finished stage output, or InputError naming what is wrong."""
    if not folder.exists():
        raise InputError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder")
    path = folder / MANIFEST
    if not path.is_file():
        raise InputError(f"{folder}: not a stage output (no {MANIFEST})")
    try:
        manifest = Manifest.model_validate_json(path.read_text())
    except (ValidationError, ValueError) as err:
        raise InputError(f"{path}: malformed manifest ({_first_line(err)})") from None
    if expected_stage is not None and manifest.stage != expected_stage:
        raise InputError(
            f"{folder}: written by stage '{manifest.stage}', expected a '{expected_stage}' output"
        )
    return manifest


def read_stage_config(folder: Path, stage: str, schema: type[M]) -> tuple[M, Manifest]:
    """The config a `stage` output was made with, validated by `schema`, and its manifest;
    InputError naming the folder when it is not such an output or its config does not
    validate (an output of another artic version)."""
    manifest = read_manifest(folder, expected_stage=stage)
    try:
        return schema.model_validate(manifest.config), manifest
    except ValueError as err:
        raise InputError(f"{folder}: config in its manifest does not validate ({err})") from None


def input_folder(folder: Path, manifest: Manifest, name: str) -> Path:
    """Where input `name` of the output `folder` is now. A manifest records an input's
    path as the run was given it; a relative one is relative to the folder the run was
    started from, which is `folder` with the run's own (relative) `out` taken off its
    end; when `folder` does not end in its `out` (it was moved), the path is taken as
    given (relative to this process's folder)."""
    if name not in manifest.inputs:
        raise InputError(f"{folder}: its manifest records no input '{name}'")
    recorded = Path(manifest.inputs[name].path)
    out = Path(str(manifest.config.get("out", "")))
    if recorded.is_absolute() or out.is_absolute() or not out.parts:
        return recorded
    here = folder.absolute().parts
    if len(here) > len(out.parts) and here[-len(out.parts) :] == out.parts:
        return Path(*here[: -len(out.parts)]) / recorded
    return recorded


def verify_file(folder: Path, manifest: Manifest, rel: str) -> Path:
    """Path of output `rel` after checking its size and sha256 against the manifest."""
    record = manifest.outputs.get(rel)
    path = folder / rel
    if record is None:
        raise InputError(f"{path}: not listed in {folder / MANIFEST}")
    if not path.is_file():
        raise InputError(f"{path}: missing (listed in {MANIFEST}); rerun the stage with --force")
    if path.stat().st_size != record.size or sha256_file(path) != record.sha256:
        raise InputError(
            f"{path}: corrupted (sha256 differs from {MANIFEST}); rerun the stage with --force"
        )
    return path


def verify_outputs(folder: Path, manifest: Manifest) -> None:
    """Check every listed output file; InputError at the first missing or corrupted one."""
    for rel in manifest.outputs:
        verify_file(folder, manifest, rel)


def _first_line(err: Exception) -> str:
    text = str(err).strip().splitlines()
    return text[0] if text else type(err).__name__
