"""What `artic segment`, `build-hierarchy` and `infer-hierarchy` write (docs/formats.md,
"Hierarchies (Chapter 4)"): the JSON documents and text files, and the output folder.

An output folder is written atomically, by the stages' own writer (`artifacts.output`):
everything goes into the sibling `DIR.partial/` (`artifacts.workdir.WorkDir`), which
replaces `DIR` only when complete, with a `manifest.json` naming the command, its
options, the input file and models with their sha256, and every output file. An existing
`DIR` is replaced only when it is an earlier output of the same command; any other
non-empty folder is refused. Without `--out`, DIR is `<stem>_segmented/` (segment) or
`<stem>_hierarchy/` beside the input, and for the parts.ply of a segment output
`X_segmented/`, `X_hierarchy/` beside it.
"""

from __future__ import annotations

import json
import logging
import shutil
import time
from pathlib import Path
from typing import Any

import numpy as np

from artic.artifacts.hashing import sha256_file, sha256_json
from artic.artifacts.manifest import LOG, MANIFEST, InputRecord, Manifest, now_iso, read_manifest
from artic.artifacts.output import ManifestHead, config_hash_of, log_to, publish, stop_log
from artic.artifacts.workdir import WorkDir
from artic.errors import InputError

log = logging.getLogger("artic")


def dumps(document: dict[str, Any]) -> str:
    """JSON text: indented, except that arrays (per-point labels) sit on one line."""
    arrays = {k: v for k, v in document.items() if isinstance(v, np.ndarray)}
    plain = {k: (f"@@{k}@@" if k in arrays else v) for k, v in document.items()}
    text = json.dumps(plain, indent=2, allow_nan=False)
    for k, v in arrays.items():
        text = text.replace(f'"@@{k}@@"', json.dumps(v.tolist(), separators=(",", ":")))
    return text + "\n"


def write_document(path: Path, document: dict[str, Any]) -> None:
    """A JSON document (hierarchy.json, segmentation.json) as `dumps` gives it."""
    path.write_text(dumps(document))


def write_text_files(folder: Path, files: dict[str, str]) -> None:
    """Text files under `folder`, by relative path (object.urdf, meshes/...)."""
    for rel, text in files.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_text(text)


def default_out(path: Path, command: str) -> Path:
    """The output folder when --out is not given (module doc)."""
    if command == "segment":
        return path.parent / f"{path.stem}_segmented"
    folder = path.parent
    if command == "build-hierarchy" and (folder / MANIFEST).is_file():
        try:
            stage = read_manifest(folder).stage
        except InputError:
            stage = ""
        if stage == "segment":
            return folder.parent / f"{folder.name.removesuffix('_segmented')}_hierarchy"
    return folder / f"{path.stem}_hierarchy"


def check_output_folder(out: Path, command: str) -> None:
    """Refuse to write over anything but an earlier output of `command` (InputError)."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out: {out} is a file, expected a folder")
    if not out.is_dir() or not any(out.iterdir()):
        return
    if not (out / MANIFEST).is_file():
        raise InputError(
            f"--out: {out} exists and is not an artic output folder; "
            "choose another --out or remove it"
        )
    stage = read_manifest(out).stage
    if stage != command:
        raise InputError(
            f"--out: {out} holds the output of 'artic {stage}', not of 'artic {command}'; "
            "choose another --out"
        )
    log.info("replacing the previous output in %s", out)


class OutputFolder:
    """`DIR.partial/` to write into, then the manifest and the atomic rename (`publish`),
    through the stages' own writer (`artifacts.output`: `log_to`, `publish`, with
    `artifacts.workdir.WorkDir` and its lock): the same files and manifest fields as a
    stage's output.

    command: the manifest's stage name. options: the command's settings (its config).
    inputs: name -> file read (hashed into the manifest).
    """

    def __init__(
        self, out: Path, command: str, options: dict[str, Any], inputs: dict[str, Path]
    ) -> None:
        check_output_folder(out, command)
        self.out, self.command, self.options = out, command, options
        self.inputs = {
            name: InputRecord(path=str(path), stage="file", content_hash=sha256_file(path))
            for name, path in inputs.items()
        }
        self.started, self.t0 = now_iso(), time.perf_counter()
        self.work = WorkDir(out)
        self.work.prepare(sha256_json({"command": command, "options": options}), fresh=True)
        self.path = self.work.path
        self.handler = log_to(self.path / LOG)

    def close_log(self) -> None:
        stop_log(self.handler)

    def abandon(self) -> None:
        """After bad input: remove the work area (nothing is published)."""
        self.close_log()
        with self.work.locked():
            self.work.leave()
            shutil.rmtree(self.path, ignore_errors=True)

    def publish(self, seed: int, stats: dict[str, float | int | str]) -> Manifest:
        """Write manifest.json and move the folder into place."""
        self.close_log()
        # the options name no output folder, shard or runtime: all of them are hashed
        config_hash = config_hash_of(self.command, self.options, ())
        head = ManifestHead(self.command, self.options, config_hash, seed, self.inputs)
        return publish(self.work, head, stats, self.started, self.t0)
