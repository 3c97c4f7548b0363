"""PLY point clouds: the labelled scans `render-depth render=scan` writes, and the scans
users bring to `artic infer-hierarchy` (docs/formats.md, "Scans (Chapter 4)").

Written: binary little-endian, one `vertex` element with properties x, y, z (float32,
metres), then optionally part_id (int32), motion_type (uint8: 0 static, 1 rotating,
2 translating, 3 both) and confidence (float32), in that order. The bytes depend only on
the arrays and comments, so the same cloud gives the same file.

Read: ascii, binary_little_endian or binary_big_endian, any vertex properties (x, y, z
required; part_id, motion_type and confidence picked up when present, the rest kept in
`extra`), other elements (faces, ...) ignored. Bad files raise one-line `InputError`s;
suspicious ones (millimetre units, very large clouds) are reported as flags.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from artic.errors import InputError

#: bounding-box diagonal (in the file's units) above which a cloud is likely millimetres
MILLIMETRE_DIAGONAL = 20.0
#: PLY scalar type names -> numpy type characters (both spellings of the PLY spec)
_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
_FORMATS = {"ascii": "", "binary_little_endian": "<", "binary_big_endian": ">"}
_MAX_HEADER = 1 << 16  # bytes searched for end_header
_KNOWN = ("x", "y", "z", "part_id", "motion_type", "confidence")


@dataclass(frozen=True)
class PlyElement:
    """One element of a PLY header: name, count, and its properties as (name, PLY type);
    a list property's type is "list <count type> <item type>"."""

    name: str
    count: int
    properties: tuple[tuple[str, str], ...]

    @property
    def has_lists(self) -> bool:
        return any(t.startswith("list") for _, t in self.properties)


@dataclass(frozen=True)
class PlyHeader:
    """A parsed PLY header; `data_offset` is where the body starts, in bytes."""

    format: str
    elements: tuple[PlyElement, ...]
    comments: tuple[str, ...]
    data_offset: int

    def element(self, name: str) -> PlyElement | None:
        return next((e for e in self.elements if e.name == name), None)


@dataclass(frozen=True)
class PlyCloud:
    """A point cloud read from a PLY file.

    points: (N, 3) float32, in the file's units (metres for artic's own files).
    part_id, motion_type: (N,) int64 or None when the file has no such property.
    confidence: (N,) float32 or None. extra: the other vertex properties, (N,) each.
    diagonal: bounding-box diagonal in the file's units. likely_millimetres: diagonal >
    MILLIMETRE_DIAGONAL. too_many_points: N > the reader's max_points (downsample).
    """

    points: NDArray[np.float32]
    part_id: NDArray[np.int64] | None
    motion_type: NDArray[np.int64] | None
    confidence: NDArray[np.float32] | None
    comments: tuple[str, ...]
    diagonal: float
    likely_millimetres: bool
    too_many_points: bool
    extra: dict[str, NDArray[np.generic]] = field(default_factory=dict)

    @property
    def warnings(self) -> list[str]:
        """One line per flag raised, for a CLI to show."""
        out = []
        if self.likely_millimetres:
            out.append(
                f"units look like millimetres (bounding-box diagonal {self.diagonal:.1f}); "
                "divide by 1000"
            )
        if self.too_many_points:
            out.append(f"{len(self.points)} points; the cloud will be downsampled")
        return out


def encode_ply(
    points: NDArray[np.floating],
    part_id: NDArray[np.integer] | None = None,
    motion_type: NDArray[np.integer] | None = None,
    confidence: NDArray[np.floating] | None = None,
    comments: Sequence[str] = (),
) -> bytes:
    """The bytes of a binary little-endian PLY of (N, 3) `points` (metres) with the
    optional per-point (N,) properties; `comments` are single-line header comments
    (non-ASCII characters escaped, `ascii_comment`)."""
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {p.shape}")
    n = len(p)
    columns: list[tuple[str, str, NDArray[np.generic] | None]] = [
        ("part_id", "int", None if part_id is None else np.asarray(part_id)),
        ("motion_type", "uchar", None if motion_type is None else np.asarray(motion_type)),
        ("confidence", "float", None if confidence is None else np.asarray(confidence)),
    ]
    names = [("x", "float"), ("y", "float"), ("z", "float")]
    names += [(name, kind) for name, kind, values in columns if values is not None]
    dtype = np.dtype([(name, "<" + _TYPES[kind]) for name, kind in names])
    data = np.empty(n, dtype=dtype)
    for i, axis in enumerate("xyz"):
        data[axis] = p[:, i]
    for name, _, values in columns:
        if values is None:
            continue
        if values.shape != (n,):
            raise ValueError(f"{name} must be ({n},), got {values.shape}")
        if name == "motion_type" and n and (values.min() < 0 or values.max() > 255):
            raise ValueError("motion_type must fit in uint8")
        data[name] = values
    lines = ["ply", "format binary_little_endian 1.0"]
    for comment in comments:
        if "\n" in comment or "\r" in comment:
            raise ValueError("PLY comments must be single lines")
        lines.append(f"comment {ascii_comment(comment)}".rstrip())
    lines.append(f"element vertex {n}")
    lines += [f"property {kind} {name}" for name, kind in names]
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii") + data.tobytes()


def ascii_comment(text: str) -> str:
    """`text` for an ASCII PLY header: other characters (a file name like `scän.ply`)
    as Python escapes (`sc\\xe4n.ply`)."""
    return text.encode("ascii", errors="backslashreplace").decode("ascii")


def write_ply(
    path: Path,
    points: NDArray[np.floating],
    part_id: NDArray[np.integer] | None = None,
    motion_type: NDArray[np.integer] | None = None,
    confidence: NDArray[np.floating] | None = None,
    comments: Sequence[str] = (),
) -> None:
    """Write `encode_ply(...)` to `path`."""
    path.write_bytes(encode_ply(points, part_id, motion_type, confidence, comments))


def parse_header(raw: bytes, name: str = "PLY") -> PlyHeader:
    """Parse the header at the start of `raw`; InputError (naming `name`) if it is not a
    PLY header."""
    if not (raw.startswith(b"ply\n") or raw.startswith(b"ply\r\n")):
        raise InputError(f"{name}: not a PLY file (it does not start with 'ply')")
    end = raw.find(b"end_header", 0, _MAX_HEADER)
    if end < 0:
        raise InputError(f"{name}: PLY header has no end_header line")
    newline = raw.find(b"\n", end)
    if newline < 0:
        raise InputError(f"{name}: PLY header ends without a newline")
    try:
        text = raw[:end].decode("ascii")
    except UnicodeDecodeError:
        raise InputError(f"{name}: PLY header is not ASCII text") from None
    fmt: str | None = None
    comments: list[str] = []
    elements: list[tuple[str, int, list[tuple[str, str]]]] = []
    for number, line in enumerate(text.splitlines()[1:], start=2):
        words = line.split()
        if not words or words[0] in ("obj_info",):
            continue
        if words[0] == "comment":
            comments.append(line.strip()[len("comment") :].strip())
        elif words[0] == "format" and len(words) == 3 and words[1] in _FORMATS:
            fmt = words[1]
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements and _valid_property(words):
            elements[-1][2].append((words[-1], " ".join(words[1:-1])))
        else:
            raise InputError(f"{name}: PLY header line {number} not understood: {line.strip()!r}")
    if fmt is None:
        raise InputError(f"{name}: PLY header has no (known) format line")
    return PlyHeader(
        format=fmt,
        elements=tuple(PlyElement(n, c, tuple(p)) for n, c, p in elements),
        comments=tuple(comments),
        data_offset=newline + 1,
    )


def _valid_property(words: list[str]) -> bool:
    if len(words) == 3:
        return words[1] in _TYPES
    return len(words) == 5 and words[1] == "list" and words[2] in _TYPES and words[3] in _TYPES


def read_ply_header(path: Path) -> PlyHeader:
    """The header of the PLY file at `path` (reads at most the first 64 KiB)."""
    with _open(path) as f:
        return parse_header(f.read(_MAX_HEADER), str(path))


def _open(path: Path) -> BinaryIO:
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        return path.open("rb")
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None


def read_ply(path: Path, min_points: int = 1, max_points: int = 1_000_000) -> PlyCloud:
    """Read and check the vertices of a PLY point cloud (see the module docstring).

    InputError (one line naming the file) for: a missing or unreadable file, not a PLY,
    no vertex element or no vertices, missing x/y/z, a truncated or malformed body,
    NaN/inf coordinates, motion_type outside 0..3, fewer than `min_points` points.
    Flags (not errors): likely millimetres, more than `max_points` points.
    """
    with _open(path) as f:
        try:
            raw = f.read()
        except OSError as err:
            raise InputError(f"{path}: cannot read ({err.strerror})") from None
    header = parse_header(raw, str(path))
    vertex = header.element("vertex")
    if vertex is None:
        raise InputError(f"{path}: PLY file has no vertex element")
    if vertex.count == 0:
        raise InputError(f"{path}: PLY file has no vertices")
    names = [n for n, _ in vertex.properties]
    missing = [a for a in "xyz" if a not in names]
    if missing:
        raise InputError(f"{path}: vertex element has no {', '.join(missing)} property")
    if vertex.has_lists:
        raise InputError(f"{path}: vertex element has list properties; expected scalars only")
    if header.format == "ascii":
        table = _ascii_vertices(raw[header.data_offset :], header, vertex, str(path))
    else:
        table = _binary_vertices(raw, header, vertex, str(path))
    return _cloud(table, header.comments, str(path), min_points, max_points)


def _preceding(header: PlyHeader, vertex: PlyElement) -> list[PlyElement]:
    return list(header.elements[: header.elements.index(vertex)])


def _binary_vertices(
    raw: bytes, header: PlyHeader, vertex: PlyElement, name: str
) -> dict[str, NDArray[np.generic]]:
    order = _FORMATS[header.format]
    offset = header.data_offset
    for element in _preceding(header, vertex):
        if element.has_lists:
            raise InputError(f"{name}: element '{element.name}' with lists precedes the vertices")
        offset += element.count * _dtype(element, order).itemsize
    dtype = _dtype(vertex, order)
    if len(raw) < offset + vertex.count * dtype.itemsize:
        raise InputError(f"{name}: PLY body is truncated (expected {vertex.count} vertices)")
    data = np.frombuffer(raw, dtype=dtype, count=vertex.count, offset=offset)
    return {n: data[n] for n in dtype.names or ()}


def _dtype(element: PlyElement, order: str) -> np.dtype[np.void]:
    return np.dtype([(n, order + _TYPES[t]) for n, t in element.properties])


def _ascii_vertices(
    body: bytes, header: PlyHeader, vertex: PlyElement, name: str
) -> dict[str, NDArray[np.generic]]:
    skip = sum(e.count for e in _preceding(header, vertex))
    lines = body.decode("ascii", errors="replace").splitlines()
    lines = [ln for ln in lines if ln.strip()][skip : skip + vertex.count]
    width = len(vertex.properties)
    if len(lines) < vertex.count:
        raise InputError(f"{name}: PLY body is truncated (expected {vertex.count} vertices)")
    try:
        rows = [ln.split() for ln in lines]
        if any(len(r) != width for r in rows):
            raise ValueError
        values = np.array(rows, dtype=np.float64)
    except ValueError:
        raise InputError(f"{name}: vertex lines must hold {width} numbers each") from None
    return {n: values[:, i].astype(_TYPES[t]) for i, (n, t) in enumerate(vertex.properties)}


def _cloud(
    table: dict[str, NDArray[np.generic]],
    comments: tuple[str, ...],
    name: str,
    min_points: int,
    max_points: int,
) -> PlyCloud:
    xyz = np.stack([table[a].astype(np.float64) for a in "xyz"], axis=1)
    bad = int((~np.isfinite(xyz).all(axis=1)).sum())
    if bad:
        raise InputError(f"{name}: {bad} of {len(xyz)} points have NaN or infinite coordinates")
    if len(xyz) < min_points:
        raise InputError(f"{name}: {len(xyz)} points; at least {min_points} needed")
    motion = _labels(table, "motion_type", name)
    if motion is not None and (motion.min() < 0 or motion.max() > 3):
        raise InputError(f"{name}: motion_type values must be 0..3 (static..both)")
    confidence = table.get("confidence")
    diagonal = float(np.linalg.norm(xyz.max(axis=0) - xyz.min(axis=0)))
    return PlyCloud(
        points=xyz.astype(np.float32),
        part_id=_labels(table, "part_id", name),
        motion_type=motion,
        confidence=None if confidence is None else confidence.astype(np.float32),
        comments=comments,
        diagonal=diagonal,
        likely_millimetres=diagonal > MILLIMETRE_DIAGONAL,
        too_many_points=len(xyz) > max_points,
        extra={k: np.array(v) for k, v in table.items() if k not in _KNOWN},
    )


def _labels(table: dict[str, NDArray[np.generic]], key: str, name: str) -> NDArray[np.int64] | None:
    """An integer label column (float columns must hold whole numbers)."""
    if key not in table:
        return None
    values = np.asarray(table[key])
    whole = np.isfinite(values).all() and np.all(values == np.round(values))
    if values.dtype.kind == "f" and not whole:
        raise InputError(f"{name}: {key} must hold whole numbers")
    return values.astype(np.int64)
