"""File formats written by stages, byte-for-byte deterministic.

`numpy.savez` stamps each zip entry with the current time, so two identical runs give
different bytes; `write_npz` fixes the timestamp so same inputs give the same file.
The result is an ordinary `.npz` that `numpy.load` reads.
"""

from __future__ import annotations

import csv
import io
import json
import os
import zipfile
import zlib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError

_EPOCH = (1980, 1, 1, 0, 0, 0)


def write_npz(path: Path, arrays: Mapping[str, NDArray[Any]], compress: bool = True) -> None:
    """Write `arrays` as an .npz (deflate-compressed by default) with fixed zip metadata."""
    method = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(path, "w", compression=method) as zf:
        for name in arrays:  # insertion order is the caller's, kept as given
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_EPOCH)
            info.compress_type = method
            info.external_attr = 0o644 << 16
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.ascontiguousarray(arrays[name]), allow_pickle=False)
            zf.writestr(info, buf.getvalue(), compresslevel=6 if compress else None)


def read_npz(path: Path, keys: Sequence[str] = ()) -> dict[str, NDArray[Any]]:
    """All arrays of an .npz, loaded eagerly (no pickles); InputError naming the file if
    it cannot be decoded (truncated, not a zip, an object array) or lacks one of `keys`."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, zlib.error) as err:
        text = str(err).strip().splitlines()
        reason = text[0] if text else type(err).__name__
        raise InputError(f"{path}: not a readable .npz file ({reason})") from None
    missing = [k for k in keys if k not in arrays]
    if missing:
        raise InputError(f"{path}: .npz has no array {', '.join(missing)}")
    return arrays


def read_json(path: Path) -> Any:
    """The JSON document in `path`; InputError naming the file if it cannot be read or
    parsed (the library reads its JSON files through this, never by itself)."""
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        text = str(err).strip().splitlines()
        raise InputError(f"{path}: not a readable JSON file ({text[0] if text else err})") from None


def read_csv(path: Path) -> list[list[str]]:
    """The rows of a CSV file, header first; InputError naming the file if unreadable."""
    try:
        with path.open(newline="", encoding="utf-8") as f:
            return list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as err:
        raise InputError(f"{path}: not a readable CSV file ({err})") from None


def write_json(path: Path, value: Any) -> None:
    """Pretty JSON with sorted keys and a final newline (deterministic)."""
    path.write_text(json.dumps(value, indent=2, sort_keys=True, allow_nan=False) + "\n")


def write_png(path: Path, image: NDArray[np.uint8]) -> None:
    """An (H, W, 3) uint8 image as PNG (PIL, no timestamp: same image, same bytes)."""
    from PIL import Image

    Image.fromarray(image).save(path, format="PNG")


def write_csv(path: Path, columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """CSV with a header; floats written with `repr` so they round-trip exactly."""
    with path.open("w", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_cell(v) for v in row])


def _cell(value: Any) -> Any:
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, np.integer):
        return int(value)
    return value


def replace_file(src: Path, dst: Path) -> None:
    """Atomically move `src` over `dst` (same file system)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    os.replace(src, dst)
