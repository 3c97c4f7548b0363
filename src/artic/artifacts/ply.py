"""PLY point clouds: the labelled scans `render-depth render=scan` writes, and the scans
users bring to `artic infer-hierarchy` (docs/formats.md, "Scans (Chapter 4)").

Parsing and writing are `plyfile`'s; this module is artic's layer over it: the vertex
properties artic knows, units and NaN checks, and one-line `InputError`s naming the file.

Written: binary little-endian, one `vertex` element with properties x, y, z (float32,
metres), then optionally part_id (int32), motion_type (uint8: 0 static, 1 rotating,
2 translating, 3 both) and confidence (float32), in that order; header comments are
ASCII (`ascii_comment`) without trailing blanks. The bytes depend only on the arrays and
comments, so the same cloud gives the same file (the same bytes artic wrote before it
used plyfile).

Read: ascii, binary_little_endian or binary_big_endian, any vertex properties (x, y, z
required; part_id, motion_type and confidence picked up when present, the rest kept in
`extra`), other elements (faces, ...) parsed by plyfile and ignored. Bad files raise
one-line `InputError`s; suspicious ones (millimetre units, very large clouds) are
reported as flags.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from plyfile import PlyData, PlyElementParseError, PlyHeaderParseError
from plyfile import PlyElement as _PlyfileElement

from artic.errors import InputError

#: bounding-box diagonal (in the file's units) above which a cloud is likely millimetres
MILLIMETRE_DIAGONAL = 20.0
#: artic's vertex properties and the numpy types it writes them with
_WRITTEN = {"part_id": "<i4", "motion_type": "u1", "confidence": "<f4"}
_KNOWN = ("x", "y", "z", "part_id", "motion_type", "confidence")
_BYTE_ORDERS = {"<": "binary_little_endian", ">": "binary_big_endian"}


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
    """A PLY file's header: its format ("ascii", "binary_little_endian",
    "binary_big_endian"), elements and comments."""

    format: str
    elements: tuple[PlyElement, ...]
    comments: tuple[str, ...]

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
    """The bytes of a binary little-endian PLY (written by plyfile) of (N, 3) `points`
    (metres) with the optional per-point (N,) properties; `comments` are single-line
    header comments (non-ASCII characters escaped, `ascii_comment`; trailing blanks
    dropped)."""
    p = np.asarray(points)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {p.shape}")
    n = len(p)
    given = {"part_id": part_id, "motion_type": motion_type, "confidence": confidence}
    columns = {name: np.asarray(v) for name, v in given.items() if v is not None}
    dtype = np.dtype([(a, "<f4") for a in "xyz"] + [(c, _WRITTEN[c]) for c in columns])
    data = np.empty(n, dtype=dtype)
    for i, axis in enumerate("xyz"):
        data[axis] = p[:, i]
    for name, values in columns.items():
        if values.shape != (n,):
            raise ValueError(f"{name} must be ({n},), got {values.shape}")
        if name == "motion_type" and n and (values.min() < 0 or values.max() > 255):
            raise ValueError("motion_type must fit in uint8")
        data[name] = values
    if any("\n" in c or "\r" in c for c in comments):
        raise ValueError("PLY comments must be single lines")
    ply = PlyData(
        [_PlyfileElement.describe(data, "vertex")],
        text=False,
        byte_order="<",
        comments=[ascii_comment(c).rstrip() for c in comments],
    )
    buffer = io.BytesIO()
    ply.write(buffer)
    return buffer.getvalue()


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


def _parse(path: Path) -> PlyData:
    """plyfile's parse of `path`, its errors as one-line InputErrors naming the file.
    Binary elements without lists are memory-mapped (copy-on-write): plyfile reads other
    binary elements row by row in Python, 30-50 times slower (5 million points: 96-110 s
    against 2-3 s); callers copy what they keep."""
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    try:
        return PlyData.read(str(path), mmap="c")
    except PlyHeaderParseError as err:
        if err.line == 1:
            raise InputError(f"{path}: not a PLY file (it does not start with 'ply')") from None
        if "early end-of-file" in err.message:
            raise InputError(f"{path}: PLY header has no end_header line") from None
        raise InputError(
            f"{path}: PLY header line {err.line} not understood ({err.message})"
        ) from None
    except PlyElementParseError as err:
        name = err.element.name if err.element is not None else "?"
        if "early end-of-file" in err.message and err.element is not None:
            count = err.element.count
            rows = "row" if count == 1 else "rows"
            raise InputError(
                f"{path}: PLY body is truncated (its header declares {count} {rows} of element "
                f"'{name}')"
            ) from None
        where = f"element '{name}'"
        where += f", row {err.row + 1}" if err.row is not None else ""
        where += f", property '{err.prop.name}'" if err.prop is not None else ""
        raise InputError(f"{path}: PLY {where}: {err.message}") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: PLY header or text body is not ASCII") from None
    except OSError as err:
        raise InputError(f"{path}: cannot read ({err.strerror})") from None
    except (ValueError, TypeError) as err:  # plyfile's other complaints, e.g. bad types
        raise InputError(f"{path}: not a readable PLY file ({err})") from None


def _header(ply: PlyData) -> PlyHeader:
    elements = []
    for element in ply.elements:
        # str(property) is its header line: "property <type...> <name>"
        properties = tuple(
            (prop.name, " ".join(str(prop).split()[1:-1])) for prop in element.properties
        )
        elements.append(PlyElement(element.name, element.count, properties))
    fmt = "ascii" if ply.text else _BYTE_ORDERS.get(ply.byte_order, "binary_little_endian")
    comments = tuple(c.strip() for c in ply.comments)
    return PlyHeader(format=fmt, elements=tuple(elements), comments=comments)


def read_ply_header(path: Path) -> PlyHeader:
    """The header of the PLY file at `path` (binary bodies are memory-mapped, not read)."""
    return _header(_parse(path))


def read_ply(path: Path, min_points: int = 1, max_points: int = 1_000_000) -> PlyCloud:
    """Read and check the vertices of a PLY point cloud (see the module docstring).

    InputError (one line naming the file) for: a missing or unreadable file, not a PLY,
    no vertex element or no vertices, missing x/y/z, a truncated or malformed body,
    NaN/inf coordinates, motion_type outside 0..3, fewer than `min_points` points.
    Flags (not errors): likely millimetres, more than `max_points` points.
    """
    ply = _parse(path)
    header = _header(ply)
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
    data = ply["vertex"].data
    table = {n: np.array(data[n]) for n in names}  # copies: the file is memory-mapped
    return _cloud(table, header.comments, str(path), min_points, max_points)


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
