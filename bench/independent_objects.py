"""An independent object generator for Chapter 4 (issue 18, item 5): storage furniture,
lamps and office chairs the segmenter never trained on, written as a `generate-dataset
dataset=hierarchy` folder.

    python bench/independent_objects.py --category storage_furniture --objects 10 --seed 0 \
        --out artifacts/objects/independent_storage_furniture
    python bench/independent_objects.py render-scan \
        dataset=artifacts/objects/independent_storage_furniture \
        render.configurations=2 noise.lateral_sigma_px=1.0 noise.axial_a=0.002 \
        noise.dropout=0.02 noise.edge_dropout=0.7 out=artifacts/scans/independent_storage_furniture
    artic evaluate hierarchy category=storage_furniture \
        scans=artifacts/scans/independent_storage_furniture segmenter=DIR labeller=DIR

The objects are built from artic's object-tree types (`Link`, `Joint`, `ArticulatedObject`;
link index = part id, the body is part 0 and every door or drawer a child of it, knobs
part of their front's link as handles are in the training data), so `tree.json`, the
motion types and the part ids come out as `generate-dataset` writes them. The geometry
and its distributions are this file's own; only the mesh utilities (`union_mesh`,
`mass_properties`), the URDF writer, `object_tree` and the pose protocol of section 4.5
(`sample_configurations`: 18 poses uniform within the joint limits) are artic's.

How it differs from the training generator (`artic.objects.structures.storage_furniture`,
conf/common/category/storage_furniture.yaml):

- proportions. Training: one box, depth 0.35-0.65, width 0.4-1.6, height 0.4-2.0 m,
  uniform. Here: three styles, tall wardrobes (width 0.8-1.5, height 1.7-2.2 m), low
  sideboards (1.2-2.1, 0.55-0.9 m) and wide chests of drawers (0.8-1.7, 0.75-1.3 m).
- support. Training: the body stands on the floor. Here: a plinth (6-12 cm, recessed
  3-5 cm behind the front) or four legs (10-25 cm), part of the body.
- top. Training: a flush top panel. Here: a top slab 20-35 mm thick overhanging 0-30 mm
  at the front and sides.
- grid. Training: rows first (1-4 rows, each split into 1-3 compartments), openings of
  at least 18 cm. Here: columns first (wardrobes 1-3, sideboards 2-4, chests 1-2
  columns, each its own stack, openings down to 10 cm): a full-height door beside a
  stack of drawers, 1-3 drawers under a door, a hat-box door over a tall door, a shallow
  drawer over a door, 3-6 graduated drawers (lower ones taller), open shelves only in
  sideboards. More parts per object than the training generator's: 8.5 against 4.5 on
  average over the first 10 objects of seed 0 and the training data's first 10 withheld.
- fronts. Training: flat 20 mm slabs, overlay doors and inset drawers. Here: flat or
  panelled (a frame of four boxes around an inset panel recessed 5-10 mm, one link),
  17-25 mm thick; per object all inset (flush in their openings, the rails visible) or
  all overlay (over half the rails).
- gaps. Training: 2 mm. Here: 3-6 mm around every front.
- handles. Training: a bar (15 mm square, on two posts). Here: knobs, 16-sided
  cylinders or square boxes of 18-35 mm; one per door on its stile at hand height
  (tall doors) or high up (low doors), one or two per drawer.
- hinges. Training: either side, uniform. Here: outer columns hinge outwards (80 %),
  so neighbouring doors read as a pair.
- joint ranges. Training: doors [0, pi/2], drawers 0.8 x their length (<= 0.5 m). Here:
  doors [0, 1.4-1.95 rad], drawers 0.55-0.9 x their box length.
- walls. Training: 20 mm everywhere. Here: 16-25 mm carcass, 10-15 mm drawer boxes.
- noise. Scored with another sensor noise level: `noise.*` overrides on render-scan.

Lamps (`--category lamp`; training: `artic.objects.structures.lamp`): a round base disc
with a boss (training: a square plate); round tubes with a hinge barrel at each joint,
leaning back and forth at rest like an Anglepoise (training: square arms standing
vertically); a conical shade facing forwards and down (training: a box); 1-4 arms plus
the head (training 1-3); the base joint swivels with probability 0.7 over [-2.5, 2.5]
(training 0.5 over [-pi, pi]), later joints 0.15 (training 0.2); tilt limits asymmetric,
about [-0.3..-0.6, 0.4..0.9] (training +-pi/4). Same tree family: base -> arm_0 -> ... -> head.

Office chairs (`--category office_chair`; training: `artic.objects.structures.office_chair`):
five legs (80 %) or four diagonal ones from a round hub (training: four legs along +-x,
+-y); casters with one or twin round wheels (75 %) or glides, never bare wheels (training
0.5 / 0.3 / 0.2 with plus-shaped box wheels); a round, hollow gas-spring tube and a round
column (85 %); a seat with a front lip, swivelling 85 %; a back of three panels curving
forwards on a spine, with a headrest 30 % of the time, none / fixed / tilting 0.1 / 0.45 /
0.45, tilting to 0.15-0.5 rad (training a flat panel, 0.5 / 0.4 fixed / tilting, 0.2-0.4
rad); L-bracket armrests 60 % (training posts, 50 %). Same tree family: base -> caster_k
-> wheel_k, base -> [column ->] seat -> back, armrests.

Cylinders, cones and rotated boxes are joined into a link's mesh as separate closed
shells (no boolean union), so a few hidden faces (a tube's end inside a hinge barrel)
are sampled by the clean clouds; the fused (noisy) scans see only outer surfaces.

Every object is test split (index.csv `split` = test), so `artic evaluate hierarchy`
scores them all. `spec.json` holds this generator's spec (category
`independent_storage_furniture`, `independent_lamp`, `independent_office_chair`),
`index.csv` and the scans artic's category (`storage_furniture`, ...), so that
category's models evaluate them.

Why `render-scan` runs through this script: `artic render-scan` rebuilds each object from
its `spec.json` through the registry of varying-structure categories
(`artic.render.scan_objects.scan_object` -> `artic.objects.families.build_object`), not from
`object.urdf`; a plain `artic` process does not know this generator's category and stops
with "spec.json: not a valid object spec". `python bench/independent_objects.py render-scan
ARGS` registers the category (at import, so spawned workers have it too) and runs the
unchanged `artic render-scan ARGS` in this process. Deterministic per seed: object i is
drawn from `default_rng([seed, i, STREAM])`, its poses from `[seed, i, STREAM, 1]`.
"""

from __future__ import annotations

from artic.reproducibility import pin_numerics

pin_numerics()  # before NumPy loads, as the `artic` command does

import argparse  # noqa: E402
import math  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, Final, Literal, NamedTuple, NoReturn  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402
from pydantic import BaseModel, ConfigDict, Field, model_validator  # noqa: E402

from artic.errors import InputError  # noqa: E402
from artic.geometry.transforms import make_transform  # noqa: E402
from artic.objects.model import ArticulatedObject, Joint, Link, TriangleMesh  # noqa: E402
from artic.objects.parts import Box, mass_properties, union_mesh  # noqa: E402
from artic.objects.spec import PartsConfig  # noqa: E402
from artic.objects.structures import (  # noqa: E402
    STRUCTURES,
    StructureConfig,
    StructureSpec,
    register_structure,
)

NAME: Final = "independent_storage_furniture"
"""The spec.json category of these objects (registered in artic's structure registry)."""
CATEGORY = "storage_furniture"
"""The category index.csv and the scans carry: the models that score these objects."""
STREAM = 0x1DE  # object i: default_rng([seed, i, STREAM]); its poses: [seed, i, STREAM, 1]
POSES = 18  # articulated poses per object (section 4.5, as generate-dataset writes)
CAMERA = "kinect_v1_128"  # generate-dataset's default camera, recorded in the manifest

Style = Literal["wardrobe", "sideboard", "chest"]
Support = Literal["plinth", "legs"]
Mount = Literal["inset", "overlay"]
KnobShape = Literal["cylinder", "box"]
Content = Literal["door", "drawer", "open"]

_CONTACT = 1e-9  # boxes closer than this touch


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# ---------------------------------------------------------------------------- the spec


class Cell(_Frozen):
    """One opening of a column, listed bottom to top: its height and what fills it."""

    height: float = Field(gt=0, description="opening height along z, m")
    content: Content = Field(description="door (revolute), drawer (prismatic) or open shelf")
    hinge: Literal[-1, 1] = Field(1, description="door: +1 hinge at low y (axis +z), -1 high y")
    panelled: bool = Field(False, description="front is a frame + recessed panel")
    knobs: int = Field(1, ge=0, le=2, description="knobs on the front")


class Column(_Frozen):
    """A column of cells between two dividers (or a divider and a side), -y to +y."""

    width: float = Field(gt=0, description="opening width along y, m")
    cells: tuple[Cell, ...] = Field(min_length=1, description="bottom to top")


class Construction(_Frozen):
    """Per-object construction sizes, metres."""

    wall: float = Field(gt=0, description="carcass panels, dividers and rails")
    front: float = Field(gt=0, description="door and drawer-front thickness")
    mount: Mount = Field(description="inset: fronts flush inside the openings; overlay: over")
    gap: float = Field(gt=0, description="clearance around every front")
    frame: float = Field(gt=0, description="stile and rail width of panelled fronts")
    recess: float = Field(gt=0, description="how far a panel sits behind its frame's face")
    knob: KnobShape = Field(description="knob shape of the whole object")
    knob_size: float = Field(gt=0, description="knob diameter or side")
    knob_length: float = Field(gt=0, description="knob length out of the front")
    drawer_wall: float = Field(gt=0, description="drawer box walls")
    top: float = Field(gt=0, description="top slab thickness")
    overhang: float = Field(ge=0, description="top slab overhang at the front and sides")
    support: Support = Field(description="plinth or four legs")
    support_height: float = Field(gt=0, description="plinth or leg height")
    leg: float = Field(gt=0, description="leg side, or plinth recess behind the front")


class IndependentStorageSpec(StructureSpec):
    """One object: carcass size, construction, columns (-y to +y), joint ranges."""

    category: Literal["independent_storage_furniture"] = "independent_storage_furniture"
    style: Style
    depth: float = Field(gt=0, description="carcass extent along x, m")
    width: float = Field(gt=0, description="carcass extent along y, m")
    carcass_height: float = Field(gt=0, description="carcass extent along z (no support, top)")
    build: Construction
    columns: tuple[Column, ...] = Field(min_length=1)
    door_upper: float = Field(gt=0, description="every door's upper limit, rad")
    drawer_travel: float = Field(gt=0, le=1, description="drawer limit, fraction of its box")

    @model_validator(mode="after")
    def _fits(self) -> IndependentStorageSpec:
        wall = self.build.wall
        widths = sum(c.width for c in self.columns) + wall * (len(self.columns) + 1)
        if not math.isclose(widths, self.width, abs_tol=1e-6):
            raise ValueError(f"columns: widths and dividers add up to {widths}, not {self.width}")
        for j, column in enumerate(self.columns):
            heights = sum(c.height for c in column.cells) + wall * (len(column.cells) + 1)
            if not math.isclose(heights, self.carcass_height, abs_tol=1e-6):
                raise ValueError(f"columns.{j}: heights add up to {heights}")
        if all(c.content == "open" for col in self.columns for c in col.cells):
            raise ValueError("columns: at least one door or drawer")
        return self


class IndependentStorageConfig(StructureConfig):
    """Registered beside the spec (the registry wants one); the distributions are
    this file's constants and functions, not config fields."""

    name: str = NAME


# ---------------------------------------------------------------------------- sampling

_STYLES: dict[Style, dict[str, tuple[float, float]]] = {
    # carcass width, depth, overall height (floor to the top of the slab), metres
    "wardrobe": {"width": (0.8, 1.5), "depth": (0.5, 0.65), "height": (1.7, 2.2)},
    "sideboard": {"width": (1.2, 2.1), "depth": (0.35, 0.5), "height": (0.55, 0.9)},
    "chest": {"width": (0.8, 1.7), "depth": (0.4, 0.55), "height": (0.75, 1.3)},
}
_COLUMNS: dict[Style, tuple[int, int]] = {"wardrobe": (1, 3), "sideboard": (2, 4), "chest": (1, 2)}
_MIN_COLUMN = 0.28  # m, narrowest column opening
_MIN_CELL = 0.1  # m, lowest opening


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def _shares(rng: np.random.Generator, total: float, weights: Sequence[float]) -> list[float]:
    """`total` split in proportion to `weights` (the last takes the rounding)."""
    w = np.asarray(weights, dtype=np.float64)
    parts = [float(total * v / w.sum()) for v in w[:-1]]
    return [*parts, total - sum(parts)]


def _column_plan(
    rng: np.random.Generator, style: Style, inner: float
) -> list[tuple[Content, float]]:
    """(content, relative height) of one column's cells, bottom to top."""
    pick = float(rng.random())

    def drawers(n: int, growth: float) -> list[tuple[Content, float]]:
        return [("drawer", growth ** (-i)) for i in range(n)]  # graduated: largest at the bottom

    if style == "wardrobe":
        if pick < 0.35:
            return [("door", 1.0)]
        if pick < 0.65:  # 1-3 drawers under a door
            n = int(rng.integers(1, 4))
            drawer_h = _uniform(rng, (0.15, 0.25))
            stack: list[tuple[Content, float]] = [("drawer", drawer_h)] * n
            return [*stack, ("door", max(inner - n * drawer_h, 0.3))]
        if pick < 0.85:  # a hat-box door over a tall door
            top = _uniform(rng, (0.3, 0.45))
            return [("door", max(inner - top, 0.3)), ("door", top)]
        return drawers(int(rng.integers(4, 7)), _uniform(rng, (1.0, 1.15)))
    if style == "sideboard":
        if pick < 0.35:
            return [("door", 1.0)]
        if pick < 0.6:  # a shallow drawer over a door
            top = _uniform(rng, (0.1, 0.16))
            return [("door", max(inner - top, 0.15)), ("drawer", top)]
        if pick < 0.9:
            return drawers(int(rng.integers(2, 5)), _uniform(rng, (1.0, 1.2)))
        return [("open", 1.0)]
    if pick < 0.85:  # chest
        return drawers(int(rng.integers(3, 7)), _uniform(rng, (1.0, 1.25)))
    top = _uniform(rng, (0.12, 0.2))
    return [("door", max(inner - 2 * top, 0.2)), ("drawer", top), ("drawer", top)]


def _cells(
    rng: np.random.Generator,
    plan: list[tuple[Content, float]],
    inner: float,
    wall: float,
    panelled: tuple[bool, bool],
    column: int,
    columns: int,
    width: float,
) -> tuple[Cell, ...]:
    """The cells of a column of opening height `inner` from its plan."""
    n = len(plan)
    while n > 1 and (inner - (n - 1) * wall) / n < _MIN_CELL:  # too many: merge from the top
        plan = plan[:-1]
        n -= 1
    heights = _shares(rng, inner - (n - 1) * wall, [h for _, h in plan])
    if min(heights) < _MIN_CELL:  # a plan's fixed heights do not fit: equal cells
        heights = _shares(rng, inner - (n - 1) * wall, [1.0] * n)
    if column == 0 and columns > 1:
        outward = 1 if rng.random() < 0.8 else -1
    elif column == columns - 1 and columns > 1:
        outward = -1 if rng.random() < 0.8 else 1
    else:
        outward = 1 if rng.random() < 0.5 else -1
    cells = []
    for (content, _), height in zip(plan, heights, strict=True):
        door = content == "door"
        knobs = 1 if door or width < 0.5 else 2
        cells.append(
            Cell(
                height=height,
                content=content,
                hinge=outward if door else 1,
                panelled=panelled[0] if door else panelled[1] and height > 0.15,
                knobs=0 if content == "open" else knobs,
            )
        )
    return tuple(cells)


def sample_independent(
    cfg: IndependentStorageConfig, index: int, rng: np.random.Generator
) -> IndependentStorageSpec:
    """Draw one object from `rng` only: style, sizes, construction, columns, cells."""
    style: Style = ("wardrobe", "sideboard", "chest")[int(rng.integers(0, 3))]
    ranges = _STYLES[style]
    width, depth, height = (_uniform(rng, ranges[k]) for k in ("width", "depth", "height"))
    legs = bool(rng.random() < (0.6 if style == "sideboard" else 0.35))
    support: Support = "legs" if legs else "plinth"
    build = Construction(
        wall=_uniform(rng, (0.016, 0.025)),
        front=_uniform(rng, (0.017, 0.025)),
        mount="overlay" if rng.random() < (0.6 if style == "chest" else 0.3) else "inset",
        gap=_uniform(rng, (0.003, 0.006)),
        frame=_uniform(rng, (0.045, 0.075)),
        recess=_uniform(rng, (0.005, 0.01)),
        knob="cylinder" if rng.random() < 0.6 else "box",
        knob_size=_uniform(rng, (0.018, 0.035)),
        knob_length=_uniform(rng, (0.022, 0.035)),
        drawer_wall=_uniform(rng, (0.010, 0.015)),
        top=_uniform(rng, (0.02, 0.035)),
        overhang=_uniform(rng, (0.0, 0.03)),
        support=support,
        support_height=_uniform(rng, (0.1, 0.25) if legs else (0.06, 0.12)),
        leg=_uniform(rng, (0.03, 0.05)),
    )
    carcass = height - build.support_height - build.top
    wall = build.wall
    lo, hi = _COLUMNS[style]
    fit = int((width - wall) // (_MIN_COLUMN + wall))
    n_cols = int(rng.integers(min(lo, fit), min(hi, fit) + 1))
    symmetric = rng.random() < 0.5
    weights = [1.0] * n_cols if symmetric else list(rng.uniform(0.7, 1.3, size=n_cols))
    widths = _shares(rng, width - (n_cols + 1) * wall, weights)
    if min(widths) < _MIN_COLUMN:
        widths = _shares(rng, width - (n_cols + 1) * wall, [1.0] * n_cols)
    panelled = (bool(rng.random() < 0.7), bool(rng.random() < 0.3))
    inner = carcass - 2 * wall
    columns = [
        Column(
            width=w,
            cells=_cells(rng, _column_plan(rng, style, inner), inner, wall, panelled, j, n_cols, w),
        )
        for j, w in enumerate(widths)
    ]
    if all(c.content == "open" for col in columns for c in col.cells):
        first = columns[0]
        door = first.cells[0].model_copy(update={"content": "door", "knobs": 1})
        columns[0] = Column(width=first.width, cells=(door, *first.cells[1:]))
    return IndependentStorageSpec(
        index=index,
        parts=PartsConfig(panel_thickness=wall, door_thickness=build.front, gap=build.gap),
        style=style,
        depth=depth,
        width=width,
        carcass_height=carcass,
        build=build,
        columns=tuple(columns),
        door_upper=_uniform(rng, (1.4, 1.95)),
        drawer_travel=_uniform(rng, (0.55, 0.9)),
    )


# ---------------------------------------------------------------------------- geometry


def _openings(spec: IndependentStorageSpec) -> list[tuple[int, int, Box]]:
    """(column, cell, opening box) in column then bottom-to-top order; x = front plane."""
    wall, z0 = spec.build.wall, spec.build.support_height
    front = -spec.depth / 2
    out = []
    y = -spec.width / 2 + wall
    for j, column in enumerate(spec.columns):
        z = z0 + wall
        for k, cell in enumerate(column.cells):
            out.append((j, k, Box((front, front), (y, y + column.width), (z, z + cell.height))))
            z += cell.height + wall
        y += column.width + wall
    return out


def _body_boxes(spec: IndependentStorageSpec) -> list[Box]:
    """Support, carcass (sides, back, bottom, top panel), top slab, dividers, rails."""
    b = spec.build
    d, w, t = spec.depth, spec.width, b.wall
    z0, z1 = b.support_height, b.support_height + spec.carcass_height
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    boxes = [
        Box((x0, x1), (y0, y0 + t), (z0, z1)),  # side -y
        Box((x0, x1), (y1 - t, y1), (z0, z1)),  # side +y
        Box((x1 - t, x1), (y0 + t, y1 - t), (z0, z1)),  # back
        Box((x0, x1 - t), (y0 + t, y1 - t), (z0, z0 + t)),  # bottom
        Box((x0, x1 - t), (y0 + t, y1 - t), (z1 - t, z1)),  # top panel
        Box((x0 - b.overhang, x1), (y0 - b.overhang, y1 + b.overhang), (z1, z1 + b.top)),
    ]
    if b.support == "plinth":  # recessed behind the front (b.leg) and 10 mm at the sides
        boxes.append(Box((x0 + b.leg, x1 - 0.01), (y0 + 0.01, y1 - 0.01), (0.0, z0)))
    else:
        inset = 0.02
        for lx in (x0 + inset, x1 - inset - b.leg):
            for ly in (y0 + inset, y1 - inset - b.leg):
                boxes.append(Box((lx, lx + b.leg), (ly, ly + b.leg), (0.0, z0)))
    y = y0 + t
    for j, column in enumerate(spec.columns):
        y_hi = y + column.width
        if j < len(spec.columns) - 1:
            boxes.append(Box((x0, x1 - t), (y_hi, y_hi + t), (z0 + t, z1 - t)))  # divider
        z = z0 + t
        for cell in column.cells[:-1]:
            z += cell.height
            boxes.append(Box((x0, x1 - t), (y, y_hi), (z, z + t)))  # rail
            z += t
        y = y_hi + t
    return boxes


def _cover(
    spec: IndependentStorageSpec, opening: Box
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The (y, z) extent of the front closing `opening`: inside it less the gap (inset),
    or over half the neighbouring divider or rail less half the gap, flush with the
    carcass at its sides and bottom, a gap under the top slab (overlay)."""
    b = spec.build
    (y_lo, y_hi), (z_lo, z_hi) = opening.y, opening.z
    if b.mount == "inset":
        return (y_lo + b.gap, y_hi - b.gap), (z_lo + b.gap, z_hi - b.gap)
    t, g = b.wall, b.gap
    side_lo, side_hi = -spec.width / 2, spec.width / 2
    z0 = b.support_height
    z1 = z0 + spec.carcass_height
    ya = side_lo if math.isclose(y_lo - t, side_lo, abs_tol=1e-9) else y_lo - t / 2 + g / 2
    yb = side_hi if math.isclose(y_hi + t, side_hi, abs_tol=1e-9) else y_hi + t / 2 - g / 2
    za = z0 if math.isclose(z_lo - t, z0, abs_tol=1e-9) else z_lo - t / 2 + g / 2
    zb = z1 - g if math.isclose(z_hi + t, z1, abs_tol=1e-9) else z_hi + t / 2 - g / 2
    return (ya, yb), (za, zb)


def _front_boxes(
    y: tuple[float, float], z: tuple[float, float], thick: float, cell: Cell, b: Construction
) -> tuple[list[Box], Box | None]:
    """A front over `y` x `z`, x from 0 (its face) to `thick` (link frame). Panelled: two
    stiles and two rails of width b.frame (at most a quarter of the front) around a panel
    recessed by b.recess. Returns the boxes and the panel (None when flat)."""
    if not cell.panelled:
        return [Box((0.0, thick), y, z)], None
    f = min(b.frame, (y[1] - y[0]) / 4, (z[1] - z[0]) / 4)
    panel = Box((b.recess, thick), (y[0] + f, y[1] - f), (z[0] + f, z[1] - f))
    return [
        Box((0.0, thick), (y[0], y[0] + f), z),  # stile
        Box((0.0, thick), (y[1] - f, y[1]), z),  # stile
        Box((0.0, thick), (y[0] + f, y[1] - f), (z[0], z[0] + f)),  # bottom rail
        Box((0.0, thick), (y[0] + f, y[1] - f), (z[1] - f, z[1])),  # top rail
        panel,
    ], panel


def _knob(
    b: Construction, y: float, z: float, panel: Box | None
) -> tuple[Box | None, TriangleMesh | None]:
    """A knob at (y, z) on a front's face (x = 0, or the panel's face when it sits on
    the panel), sticking out towards -x: a box, or a 16-sided cylinder mesh."""
    on_panel = panel is not None and panel.y[0] < y < panel.y[1] and panel.z[0] < z < panel.z[1]
    base = panel.x[0] if on_panel and panel is not None else 0.0
    half = b.knob_size / 2
    if b.knob == "box":
        return Box((base - b.knob_length, base), (y - half, y + half), (z - half, z + half)), None
    import trimesh

    along_x = make_transform(
        rotation=np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
        translation=np.array([base - b.knob_length / 2, y, z]),
    )
    shape = trimesh.creation.cylinder(
        radius=half, height=b.knob_length, sections=16, transform=along_x
    )
    vertices = np.asarray(shape.vertices, dtype=np.float64)
    return None, TriangleMesh(vertices, np.asarray(shape.faces, dtype=np.int32))


def _join(meshes: Sequence[TriangleMesh]) -> TriangleMesh:
    """One link mesh of closed meshes (vertices stacked, triangles renumbered)."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return TriangleMesh(
        np.concatenate([m.vertices for m in meshes]).astype(np.float64),
        np.concatenate([m.triangles + o for m, o in zip(meshes, offsets, strict=True)]).astype(
            np.int32
        ),
    )


def _mesh(boxes: Sequence[Box], extra: Sequence[TriangleMesh]) -> TriangleMesh:
    """The union of `boxes` (one watertight solid) plus closed meshes touching it."""
    return _join([union_mesh(boxes), *extra])


class _Moving(NamedTuple):
    """A door or drawer: name, role, joint (origin in the body frame) and its mesh in
    its link frame."""

    name: str
    role: Literal["door", "drawer"]
    joint_type: Literal["revolute", "prismatic"]
    origin: tuple[float, float, float]
    axis: tuple[float, float, float]
    limits: tuple[float, float]
    mesh: TriangleMesh


def _door(spec: IndependentStorageSpec, name: str, cell: Cell, opening: Box) -> _Moving:
    """A door hinged on its `cell.hinge` edge at the front face; q > 0 opens it towards
    -x. Link frame: the hinge edge's bottom, the front's face at x = 0."""
    b = spec.build
    (ya, yb), (za, zb) = _cover(spec, opening)
    face = -spec.depth / 2 - (b.front if b.mount == "overlay" else 0.0)
    width, height = yb - ya, zb - za
    span = (0.0, width) if cell.hinge == 1 else (-width, 0.0)
    boxes, panel = _front_boxes(span, (0.0, height), b.front, cell, b)
    stile = min(b.frame, width / 4) if cell.panelled else 2 * b.knob_size
    knob_y = cell.hinge * (width - max(stile / 2, b.knob_size))
    world_z = 1.05 if height > 1.2 else za + 0.8 * height  # tall doors: knob at hand height
    knob_z = float(np.clip(world_z - za, 0.15 * height, 0.85 * height))
    box, cylinder = _knob(b, knob_y, knob_z, panel)
    return _Moving(
        name=name,
        role="door",
        joint_type="revolute",
        origin=(face, ya if cell.hinge == 1 else yb, za),
        axis=(0.0, 0.0, float(cell.hinge)),
        limits=(0.0, spec.door_upper),
        mesh=_mesh([*boxes, *([box] if box else [])], [cylinder] if cylinder else []),
    )


def _drawer(spec: IndependentStorageSpec, name: str, cell: Cell, opening: Box) -> _Moving:
    """A drawer: its front (flat or panelled) and an open-top box behind it, lower than
    the front and narrower than the opening; axis -x. Link frame: the front face's
    centre."""
    b = spec.build
    (ya, yb), (za, zb) = _cover(spec, opening)
    face = -spec.depth / 2 - (b.front if b.mount == "overlay" else 0.0)
    hw, hh = (yb - ya) / 2, (zb - za) / 2
    boxes, panel = _front_boxes((-hw, hw), (-hh, hh), b.front, cell, b)
    # the box fits the opening with 8 mm at each side, sits 4 mm above its floor
    ow = (opening.y[1] - opening.y[0]) / 2 - 0.008
    oz = max(opening.z[0] + 0.004 - (za + hh), -hh)  # opening floor in the link frame
    top = oz + max(0.6 * (opening.z[1] - opening.z[0]), 0.05)
    x_in = b.front  # the box starts behind the front, reaches 15 mm short of the back
    room = spec.depth - b.wall - 0.015 - (b.front if b.mount == "inset" else 0.0)
    x_end = x_in + 0.92 * room
    t = b.drawer_wall
    boxes += [
        Box((x_in, x_end), (-ow, -ow + t), (oz, top)),  # side
        Box((x_in, x_end), (ow - t, ow), (oz, top)),  # side
        Box((x_end - t, x_end), (-ow + t, ow - t), (oz, top)),  # back
        Box((x_in, x_end - t), (-ow + t, ow - t), (oz, oz + t)),  # bottom
    ]
    knob_ys = [0.0] if cell.knobs == 1 else [-hw / 2, hw / 2]
    extra_boxes: list[Box] = []
    cylinders: list[TriangleMesh] = []
    for ky in knob_ys:
        box, cylinder = _knob(b, ky, 0.0, panel)
        extra_boxes += [box] if box else []
        cylinders += [cylinder] if cylinder else []
    travel = spec.drawer_travel * (x_end - x_in)
    return _Moving(
        name=name,
        role="drawer",
        joint_type="prismatic",
        origin=(face, (ya + yb) / 2, (za + zb) / 2),
        axis=(-1.0, 0.0, 0.0),
        limits=(0.0, travel),
        mesh=_mesh([*boxes, *extra_boxes], cylinders),
    )


def _link(name: str, role: str, mesh: TriangleMesh, density: float) -> Link:
    return Link(name=name, role=role, mesh=mesh, inertial=mass_properties(mesh, density))


@register_structure(NAME, IndependentStorageConfig, IndependentStorageSpec, sample_independent)
def build_independent(spec: IndependentStorageSpec) -> ArticulatedObject:
    """Body (part 0), then per column (-y to +y) and cell (bottom to top) its door or
    drawer, each a child of the body: `door_<n>` / `drawer_<n>` on `joint_<n>`."""
    p = spec.parts
    links = [_link("body", "body", union_mesh(_body_boxes(spec)), 600.0)]
    joints: list[Joint] = []
    n = 0
    for j, k, opening in _openings(spec):
        cell = spec.columns[j].cells[k]
        if cell.content == "open":
            continue
        make = _door if cell.content == "door" else _drawer
        part = make(spec, f"{cell.content}_{n}", cell, opening)
        density = 650.0 if part.role == "drawer" else 550.0
        links.append(_link(part.name, part.role, part.mesh, density))
        joints.append(
            Joint(
                name=f"joint_{n}",
                type=part.joint_type,
                parent="body",
                child=part.name,
                origin=make_transform(translation=np.array(part.origin)),
                axis=np.array(part.axis),
                limits=part.limits,
                damping=p.joint_damping,
                friction=p.joint_friction,
                effort=p.joint_effort,
                velocity=p.joint_velocity,
            )
        )
        n += 1
    return ArticulatedObject(
        name=f"{NAME}_{spec.index}", links=tuple(links), joints=tuple(joints), base_pose=np.eye(4)
    )


# ---------------------------------------------------------------------------- lamps

LAMP: Final = "independent_lamp"
"""The spec.json category of the independent lamps."""


class Arm(_Frozen):
    """One arm: a round tube from its joint, leaning by `lean` about +y at rest (> 0:
    towards the back, +x), with a hinge barrel across its joint."""

    length: float = Field(gt=0, description="tube length, m")
    lean: float = Field(description="rest inclination from vertical, rad (> 0: backwards)")
    axis: Literal["horizontal", "vertical"] = Field(description="joint axis: +y or +z")
    limits: tuple[float, float] = Field(description="joint limits, rad")


class IndependentLampSpec(StructureSpec):
    """A lamp: a round base with a boss, a chain of tubes, a conical shade."""

    category: Literal["independent_lamp"] = "independent_lamp"
    base_radius: float = Field(gt=0, description="base disc radius, m")
    base_height: float = Field(gt=0, description="base disc thickness, m")
    boss: float = Field(gt=0, description="height of the boss on the disc, m")
    tube: float = Field(gt=0, description="tube radius, m")
    arms: tuple[Arm, ...] = Field(min_length=1, description="base first")
    shade_radius: float = Field(gt=0, description="shade mouth radius, m")
    shade_length: float = Field(gt=0, description="shade length, m")
    shade_tilt: float = Field(description="shade axis below horizontal at rest, rad")
    head_limits: tuple[float, float] = Field(description="head joint limits (+y), rad")


class IndependentLampConfig(StructureConfig):
    """Registered beside the spec; the distributions are this file's."""

    name: str = LAMP


def sample_independent_lamp(
    cfg: IndependentLampConfig, index: int, rng: np.random.Generator
) -> IndependentLampSpec:
    """1-4 arms: the first leans back or stands, later ones alternate forwards and back;
    the base joint swivels with probability 0.7, later joints with 0.15."""
    arms = []
    for k in range(int(rng.integers(1, 5))):
        vertical = rng.random() < (0.7 if k == 0 else 0.15)
        lean = _uniform(rng, (-0.1, 0.35)) if k % 2 == 0 else _uniform(rng, (-1.0, -0.3))
        limits = (
            (-2.5, 2.5) if vertical else (-_uniform(rng, (0.3, 0.6)), _uniform(rng, (0.4, 0.9)))
        )
        arms.append(
            Arm(
                length=_uniform(rng, (0.12, 0.42)),
                lean=lean,
                axis="vertical" if vertical else "horizontal",
                limits=limits,
            )
        )
    return IndependentLampSpec(
        index=index,
        parts=PartsConfig(body_density=2500.0, door_density=900.0, joint_effort=5.0),
        base_radius=_uniform(rng, (0.06, 0.11)),
        base_height=_uniform(rng, (0.012, 0.03)),
        boss=_uniform(rng, (0.015, 0.04)),
        tube=_uniform(rng, (0.006, 0.013)),
        arms=tuple(arms),
        shade_radius=_uniform(rng, (0.045, 0.09)),
        shade_length=_uniform(rng, (0.08, 0.16)),
        shade_tilt=_uniform(rng, (0.2, 1.1)),
        head_limits=(-_uniform(rng, (0.5, 0.9)), _uniform(rng, (0.4, 0.8))),
    )


def _solid(shape: object) -> TriangleMesh:
    """A trimesh solid as a TriangleMesh."""
    return TriangleMesh(
        np.asarray(shape.vertices, dtype=np.float64),  # type: ignore[attr-defined]
        np.asarray(shape.faces, dtype=np.int32),  # type: ignore[attr-defined]
    )


def _tube(start: NDArray[np.float64], end: NDArray[np.float64], radius: float) -> TriangleMesh:
    import trimesh

    return _solid(trimesh.creation.cylinder(radius=radius, segment=[start, end], sections=16))


def _barrel(radius: float) -> TriangleMesh:
    """A hinge barrel across +y at the link origin."""
    a, b = np.array([0.0, -2 * radius, 0.0]), np.array([0.0, 2 * radius, 0.0])
    return _tube(a, b, 1.6 * radius)


@register_structure(LAMP, IndependentLampConfig, IndependentLampSpec, sample_independent_lamp)
def build_independent_lamp(spec: IndependentLampSpec) -> ArticulatedObject:
    """base -> arm_0 -> ... -> head, every joint revolute, each at the previous tube's end
    (the first on the boss). The shade is a cone whose mouth faces forwards and down."""
    import trimesh

    p, r = spec.parts, spec.tube
    base_top = spec.base_height + spec.boss
    disc = _tube(np.zeros(3), np.array([0.0, 0.0, spec.base_height]), spec.base_radius)
    boss = _tube(np.array([0.0, 0.0, spec.base_height]), np.array([0.0, 0.0, base_top]), 2 * r)
    links = [_link("base", "base", _join([disc, boss]), p.body_density)]
    joints: list[Joint] = []
    origin, parent = np.array([0.0, 0.0, base_top]), "base"
    chain = [(f"arm_{k}", "arm", arm) for k, arm in enumerate(spec.arms)]
    for k, (name, role, arm) in enumerate(chain):
        end = arm.length * np.array([np.sin(arm.lean), 0.0, np.cos(arm.lean)])
        mesh = _join([_barrel(r), _tube(np.zeros(3), end, r)])
        links.append(_link(name, role, mesh, p.door_density))
        axis = np.array([0.0, 1.0, 0.0] if arm.axis == "horizontal" else [0.0, 0.0, 1.0])
        joints.append(_revolute(k, parent, name, origin, axis, arm.limits, p))
        origin, parent = end, name
    # the head: a neck tube, then a cone whose axis points forwards and down by shade_tilt
    direction = np.array([-np.cos(spec.shade_tilt), 0.0, -np.sin(spec.shade_tilt)])
    neck_end = 2.5 * r * direction
    mouth = neck_end + spec.shade_length * direction
    cone = trimesh.creation.cone(radius=spec.shade_radius, height=spec.shade_length, sections=24)
    cone.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, -1.0], direction))
    cone.apply_translation(mouth)  # the cone's base (its mouth) at `mouth`, apex towards the neck
    head = _join([_barrel(r), _tube(np.zeros(3), neck_end, r), _solid(cone)])
    links.append(_link("head", "head", head, p.door_density))
    joints.append(
        _revolute(
            len(chain), parent, "head", origin, np.array([0.0, 1.0, 0.0]), spec.head_limits, p
        )
    )
    return ArticulatedObject(
        name=f"{LAMP}_{spec.index}", links=tuple(links), joints=tuple(joints), base_pose=np.eye(4)
    )


def _revolute(
    k: int,
    parent: str,
    child: str,
    origin: NDArray[np.float64],
    axis: NDArray[np.float64],
    limits: tuple[float, float],
    p: PartsConfig,
) -> Joint:
    return Joint(
        name=f"joint_{k}",
        type="revolute",
        parent=parent,
        child=child,
        origin=make_transform(translation=np.asarray(origin, dtype=np.float64)),
        axis=axis,
        limits=limits,
        damping=p.joint_damping,
        friction=p.joint_friction,
        effort=p.joint_effort,
        velocity=p.joint_velocity,
    )


# ---------------------------------------------------------------------------- office chairs

CHAIR: Final = "independent_office_chair"
"""The spec.json category of the independent office chairs."""


class IndependentChairSpec(StructureSpec):
    """An office chair: a round-hub star base (4 diagonal or 5 legs) on casters or
    glides, a round gas-lift column, a seat with a front lip, a curved back on a spine,
    L-bracket armrests. Metres and radians."""

    category: Literal["independent_office_chair"] = "independent_office_chair"
    legs: int = Field(ge=4, le=5, description="4 (diagonal) or 5 legs")
    leg_reach: float = Field(gt=0, description="centre to leg tip")
    leg_width: float = Field(gt=0, description="leg width (and height x 0.7)")
    feet: Literal["casters", "glides"] = Field(description="what the legs stand on")
    twin: bool = Field(description="casters carry twin wheels")
    wheel_radius: float = Field(gt=0, description="wheel radius")
    tube_radius: float = Field(gt=0, description="gas-spring tube radius")
    tube_height: float = Field(gt=0, description="tube above the hub")
    gas_lift: bool = Field(description="a prismatic column (else the seat sits on the tube)")
    lift_travel: float = Field(gt=0, description="column stroke")
    seat_depth: float = Field(gt=0, description="seat extent along x")
    seat_width: float = Field(gt=0, description="seat extent along y")
    seat_thickness: float = Field(gt=0, description="cushion thickness")
    swivel: bool = Field(description="the seat turns about +z (continuous)")
    back: Literal["none", "fixed", "tilting"] = Field(description="back kind")
    back_height: float = Field(gt=0, description="back panel height")
    back_curve: float = Field(ge=0, description="wing angle of the back's side panels")
    headrest: bool = Field(description="a headrest on the back (same part)")
    back_tilt: float = Field(gt=0, description="upper limit of a tilting back")
    armrests: bool = Field(description="two L-bracket armrests (fixed)")
    armrest_height: float = Field(gt=0, description="pad above the seat")


class IndependentChairConfig(StructureConfig):
    """Registered beside the spec; the distributions are this file's."""

    name: str = CHAIR


def sample_independent_chair(
    cfg: IndependentChairConfig, index: int, rng: np.random.Generator
) -> IndependentChairSpec:
    """Sizes uniform in this file's ranges, then the options; a chair that would not
    move gets a swivelling seat."""
    feet: Literal["casters", "glides"] = "casters" if rng.random() < 0.75 else "glides"
    gas_lift, swivel = bool(rng.random() < 0.85), bool(rng.random() < 0.85)
    back = ("none", "fixed", "tilting")[int(rng.choice(3, p=[0.1, 0.45, 0.45]))]
    if feet == "glides" and not gas_lift and back != "tilting":
        swivel = True
    return IndependentChairSpec(
        index=index,
        parts=PartsConfig(body_density=1100.0, door_density=250.0, joint_effort=20.0),
        legs=5 if rng.random() < 0.8 else 4,
        leg_reach=_uniform(rng, (0.27, 0.36)),
        leg_width=_uniform(rng, (0.035, 0.055)),
        feet=feet,
        twin=bool(rng.random() < 0.5),
        wheel_radius=_uniform(rng, (0.022, 0.032)),
        tube_radius=_uniform(rng, (0.022, 0.032)),
        tube_height=_uniform(rng, (0.1, 0.18)),
        gas_lift=gas_lift,
        lift_travel=_uniform(rng, (0.06, 0.12)),
        seat_depth=_uniform(rng, (0.42, 0.52)),
        seat_width=_uniform(rng, (0.45, 0.56)),
        seat_thickness=_uniform(rng, (0.06, 0.1)),
        swivel=swivel,
        back=back,
        back_height=_uniform(rng, (0.42, 0.7)),
        back_curve=_uniform(rng, (0.0, 0.45)),
        headrest=bool(rng.random() < 0.3),
        back_tilt=_uniform(rng, (0.15, 0.5)),
        armrests=bool(rng.random() < 0.6),
        armrest_height=_uniform(rng, (0.17, 0.26)),
    )


def _block(extents: Sequence[float], centre: Sequence[float], yaw: float = 0.0) -> TriangleMesh:
    """A box of `extents` centred at `centre`, turned by `yaw` about +z."""
    import trimesh

    c, s = np.cos(yaw), np.sin(yaw)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pose = make_transform(rotation=rotation, translation=np.asarray(centre, dtype=np.float64))
    return _solid(trimesh.creation.box(extents=list(extents), transform=pose))


def _span(ends: tuple[float, float]) -> tuple[float, float]:
    """An interval from two ends in either order."""
    return (min(ends), max(ends))


def _wheels(spec: IndependentChairSpec) -> TriangleMesh:
    """One wheel (or a twin pair) rolling about +y, centred at the origin."""
    r, w = spec.wheel_radius, 0.35 * spec.wheel_radius
    if not spec.twin:
        return _tube(np.array([0.0, -w, 0.0]), np.array([0.0, w, 0.0]), r)
    discs = [(-2.2 * w, -0.2 * w), (0.2 * w, 2.2 * w)]
    return _join([_tube(np.array([0.0, a, 0.0]), np.array([0.0, b, 0.0]), r) for a, b in discs])


@register_structure(CHAIR, IndependentChairConfig, IndependentChairSpec, sample_independent_chair)
def build_independent_chair(spec: IndependentChairSpec) -> ArticulatedObject:
    """base -> caster_k -> wheel_k (continuous, per leg), base -> [column ->] seat
    (continuous or fixed) -> back (revolute +y or fixed), armrest_0 (-y), armrest_1."""
    import trimesh

    p, gap, r = spec.parts, 0.003, spec.wheel_radius
    spin = (-math.pi, math.pi)
    leg_h = 0.7 * spec.leg_width
    caster_h = 0.025
    z_leg = 2 * r + 1.4 * caster_h + 2 * gap if spec.feet == "casters" else 0.02  # leg bottom
    hub_top = z_leg + leg_h + 0.02
    tube_top = hub_top + spec.tube_height
    base = [
        _tube(np.array([0.0, 0.0, z_leg]), np.array([0.0, 0.0, hub_top]), 1.8 * spec.tube_radius),
        _solid(
            trimesh.creation.annulus(
                r_min=spec.tube_radius - 0.005,
                r_max=spec.tube_radius,
                height=spec.tube_height,
                sections=24,
                transform=make_transform(
                    translation=np.array([0.0, 0.0, hub_top + spec.tube_height / 2])
                ),
            )
        ),
    ]
    offset = math.pi / 4 if spec.legs == 4 else math.pi / 2  # no leg straight to the front
    angles = [offset + 2 * math.pi * k / spec.legs for k in range(spec.legs)]
    tips = [spec.leg_reach * np.array([math.cos(a), math.sin(a)]) for a in angles]
    for a in angles:
        centre = (0.5 * spec.leg_reach * math.cos(a), 0.5 * spec.leg_reach * math.sin(a))
        extents = (spec.leg_reach + spec.leg_width / 2, spec.leg_width, leg_h)
        base.append(_block(extents, (*centre, z_leg + leg_h / 2), a))
    if spec.feet == "glides":
        for tip in tips:
            base.append(_tube(np.array([*tip, 0.0]), np.array([*tip, z_leg]), 0.6 * spec.leg_width))
    links = [_link("base", "base", _join(base), p.body_density)]
    joints: list[Joint] = []
    z_axis, y_axis = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])

    def attach(name: str, role: str, mesh: TriangleMesh, parent: str, kind: str,
               origin: NDArray[np.float64], axis: NDArray[np.float64],
               limits: tuple[float, float], density: float) -> None:  # fmt: skip
        movable = [j for j in joints if j.type != "fixed"]
        joint_name = f"{name}_fixed" if kind == "fixed" else f"joint_{len(movable)}"
        links.append(_link(name, role, mesh, density))
        joints.append(
            Joint(
                name=joint_name,
                type=kind,  # type: ignore[arg-type]
                parent=parent,
                child=name,
                origin=make_transform(translation=origin),
                axis=axis,
                limits=limits if kind != "fixed" else (0.0, 0.0),
                damping=p.joint_damping,
                friction=p.joint_friction,
                effort=p.joint_effort,
                velocity=p.joint_velocity,
            )
        )

    if spec.feet == "casters":
        trail = 0.6 * r
        for k, tip in enumerate(tips):
            fork = _join(
                [
                    _tube(np.array([0.0, 0.0, -caster_h]), np.zeros(3), 0.4 * spec.leg_width),
                    _block((trail + r, 2.8 * 0.35 * r + 0.01, 0.4 * caster_h),
                           (-trail / 2, 0.0, -caster_h - 0.2 * caster_h)),
                ]
            )  # fmt: skip
            origin = np.array([*tip, z_leg - gap])
            attach(f"caster_{k}", "caster", fork, "base", "continuous", origin, z_axis, spin, 900.0)
            wheel_origin = np.array([-trail, 0.0, -caster_h - 0.4 * caster_h - gap - r])
            attach(f"wheel_{k}", "wheel", _wheels(spec), f"caster_{k}", "continuous",
                   wheel_origin, y_axis, spin, 1000.0)  # fmt: skip
    seat_parent, seat_origin = "base", np.array([0.0, 0.0, tube_top])
    if spec.gas_lift:
        insert, above = spec.tube_height - 0.01, 0.05
        column = _tube(np.array([0.0, 0.0, -insert]), np.array([0.0, 0.0, above]),
                       spec.tube_radius - 0.008)  # fmt: skip
        attach("column", "column", column, "base", "prismatic", seat_origin, z_axis,
               (0.0, min(spec.lift_travel, insert - 0.02)), p.body_density)  # fmt: skip
        seat_parent, seat_origin = "column", np.array([0.0, 0.0, above])
    sd, sw, st = spec.seat_depth, spec.seat_width, spec.seat_thickness
    plate = 0.035
    seat = _join(
        [
            _block((0.16, 0.16, plate), (0.0, 0.0, plate / 2)),  # mechanism
            _block((sd, sw, st), (0.0, 0.0, plate + st / 2)),  # cushion
            _block((0.05, 0.9 * sw, 0.6 * st), (-sd / 2 - 0.025, 0.0, plate + 0.3 * st)),  # lip
        ]
    )
    swivel = "continuous" if spec.swivel else "fixed"
    attach("seat", "seat", seat, seat_parent, swivel, seat_origin, z_axis, spin, p.door_density)
    top = plate + st
    if spec.back != "none":
        h, panel = spec.back_height, 0.035
        wing = 0.3 * sw
        pieces = [
            _block((0.03, 0.05, top + 0.1), (0.0, 0.0, (top + 0.1) / 2 - top)),  # spine
            _block((panel, 0.4 * sw, h), (0.03, 0.0, 0.1 + h / 2)),  # middle
        ]
        for side in (-1.0, 1.0):  # side panels, turned forwards by back_curve
            yaw = side * spec.back_curve
            wing_centre = (
                0.03 - 0.5 * wing * math.sin(spec.back_curve),
                side * (0.2 * sw + 0.5 * wing * math.cos(spec.back_curve)),
                0.1 + h / 2,
            )
            pieces.append(_block((panel, wing, h), wing_centre, yaw))
        if spec.headrest:
            pieces.append(_block((0.05, 0.3 * sw, 0.12), (0.03, 0.0, 0.1 + h + 0.1)))
        kind = "revolute" if spec.back == "tilting" else "fixed"
        origin = np.array([sd / 2 + 0.03, 0.0, top])
        attach("back", "back", _join(pieces), "seat", kind, origin, y_axis,
               (0.0, spec.back_tilt), p.door_density)  # fmt: skip
    if spec.armrests:
        hgt, reach = spec.armrest_height, 0.06
        for k, side in enumerate((-1.0, 1.0)):
            boxes = [
                Box((-0.03, 0.03), _span((-side * 0.1, side * reach)), (-0.02, 0.0)),  # bracket
                Box((-0.02, 0.02), _span((side * reach, side * (reach + 0.025))),
                    (-0.02, hgt)),  # post
                Box((-0.13, 0.11), _span((side * (reach - 0.015), side * (reach + 0.055))),
                    (hgt, hgt + 0.025)),  # pad
            ]  # fmt: skip
            origin = np.array([0.05, side * (sw / 2), plate])
            attach(f"armrest_{k}", "armrest", union_mesh(boxes), "seat", "fixed", origin,
                   z_axis, (0.0, 0.0), p.door_density)  # fmt: skip
    return ArticulatedObject(
        name=f"{CHAIR}_{spec.index}", links=tuple(links), joints=tuple(joints), base_pose=np.eye(4)
    )


# ---------------------------------------------------------------------------- the dataset


class Generator(NamedTuple):
    """One category of this file: the spec category it writes, its config and sampler."""

    spec_category: str
    config: Callable[[], StructureConfig]
    sample: Callable[[Any, int, np.random.Generator], StructureSpec]


GENERATORS: dict[str, Generator] = {
    "storage_furniture": Generator(NAME, IndependentStorageConfig, sample_independent),
    "lamp": Generator(LAMP, IndependentLampConfig, sample_independent_lamp),
    "office_chair": Generator(CHAIR, IndependentChairConfig, sample_independent_chair),
}
"""artic's category (index.csv, the scans, the models) -> this file's generator."""


def object_files(
    seed: int, object_id: int, category: str = CATEGORY, poses: int = POSES
) -> dict[str, str]:
    """The files of object `object_id` as generate-dataset dataset=hierarchy names them:
    spec.json, object.urdf, meshes/*.obj, tree.json, poses.json (relative path -> text)."""
    from artic.objects.families import build_object
    from artic.objects.tree import object_tree, sample_configurations
    from artic.objects.urdf import write_urdf

    generator = GENERATORS[category]
    rng = np.random.default_rng([seed, object_id, STREAM])
    spec = generator.sample(generator.config(), object_id, rng)
    obj = build_object(spec)  # through the registry, as render-scan rebuilds it
    urdf = write_urdf(obj)
    rng = np.random.default_rng([seed, object_id, STREAM, 1])
    files = {"spec.json": spec.model_dump_json(indent=2) + "\n", "object.urdf": urdf.urdf}
    files.update(urdf.meshes)
    files["tree.json"] = object_tree(obj).model_dump_json(indent=2) + "\n"
    files["poses.json"] = sample_configurations(obj, poses, rng).model_dump_json(indent=2) + "\n"
    return files


def dataset_config(category: str, objects: int, seed: int, out: Path) -> dict[str, object]:
    """The manifest's config: generate-dataset's keys, this generator named in it."""
    from omegaconf import OmegaConf

    from artic.config.compose import conf_dir

    camera = OmegaConf.to_container(OmegaConf.load(conf_dir() / "common/camera" / f"{CAMERA}.yaml"))
    return {
        "artifacts_root": "artifacts",
        "camera": camera,
        "category": {
            "name": category,
            "generator": "bench/independent_objects.py",
            "spec": GENERATORS[category].spec_category,
        },
        "dataset": {
            "chunk_size": objects,
            "kind": "hierarchy",
            "objects": objects,
            "poses": POSES,
            "split": "test",
            "train_per_test": 0,
        },
        "out": str(out),
        "runtime": {"workers": 0},
        "seed": seed,
        "shard": {"count": 1, "index": 0},
    }


def write_dataset(category: str, objects: int, seed: int, out: Path) -> Path:
    """Write the dataset folder `out` (atomically: built in a sibling temporary folder,
    renamed into place); every object in the test split. Returns `out`."""
    from artic.artifacts.formats import write_csv, write_json
    from artic.artifacts.manifest import (
        MANIFEST,
        Manifest,
        list_outputs,
        now_iso,
        outputs_hash,
        package_versions,
    )
    from artic.artifacts.object_dataset import INDEX, INDEX_COLUMNS, object_dir, write_object
    from artic.artifacts.output import check_out, config_hash_of
    from artic.objects.tree import ObjectTree

    if category not in GENERATORS:
        known = ", ".join(GENERATORS)
        raise InputError(f"--category: {category!r} is not built; expected one of {known}")
    if objects < 1:
        raise InputError(f"--objects: expected >= 1, got {objects}")
    if seed < 0:
        raise InputError(f"--seed: expected >= 0, got {seed}")
    check_out(out)
    if out.exists() and any(out.iterdir()):
        raise InputError(f"--out: {out} exists and is not empty; remove it or pick another")
    out.parent.mkdir(parents=True, exist_ok=True)
    started, t0 = now_iso(), time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        rows = []
        shapes = set()
        for object_id in range(objects):
            folder = tmp / object_dir(object_id)
            write_object(folder, object_files(seed, object_id, category))
            tree = ObjectTree.model_validate_json((folder / "tree.json").read_text())
            shapes.add((tree.edges, tree.joint_types))
            rows.append((object_id, "test", category, tree.dof, 0))
        write_csv(tmp / INDEX, INDEX_COLUMNS, rows)
        config = dataset_config(category, objects, seed, out)
        write_json(tmp / "category.json", config["category"])
        outputs = list_outputs(tmp)
        manifest = Manifest(
            stage="generate-dataset",
            config=config,
            config_hash=config_hash_of("generate-dataset", config, ()),
            seed=seed,
            inputs={},
            choices={"camera": CAMERA, "category": category, "dataset": "hierarchy"},
            outputs=outputs,
            content_hash=outputs_hash(outputs),
            versions=package_versions(),
            started_at=started,
            finished_at=now_iso(),
            wall_time_s=round(time.perf_counter() - t0, 3),
            stats={
                "category": category,
                "generator": GENERATORS[category].spec_category,
                "objects": objects,
                "train objects": 0,
                "test objects": objects,
                "distinct trees": len(shapes),
                "dof min": min(r[3] for r in rows),
                "dof max": max(r[3] for r in rows),
                "poses per object": POSES,
            },
        )
        write_json(tmp / MANIFEST, manifest.model_dump(mode="json"))
        if out.exists():
            out.rmdir()  # empty (checked above)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


# ---------------------------------------------------------------------------- command line


def _one_line_error(message: str) -> NoReturn:
    """argparse's error without the usage lines: one line, exit 2."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def _generate(argv: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog="independent_objects.py",
        description="Storage furniture from an independent generator, written as a "
        "generate-dataset dataset=hierarchy folder (all objects test split). "
        "`independent_objects.py render-scan ARGS` runs artic render-scan on it.",
    )
    parser.add_argument("--category", default=CATEGORY, help=", ".join(GENERATORS))
    parser.add_argument("--objects", type=int, required=True, help="number of objects")
    parser.add_argument("--seed", type=int, default=0, help="object i from (seed, i)")
    parser.add_argument("--out", type=Path, required=True, help="output folder (new)")
    parser.error = _one_line_error  # type: ignore[method-assign]
    args = parser.parse_args(argv)
    try:
        out = write_dataset(args.category, args.objects, args.seed, args.out)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    name = GENERATORS[args.category].spec_category
    print(f"wrote {args.objects} {args.category} objects ({name}) to {out}")
    return 0


def _render_scan(argv: Sequence[str]) -> int:
    """`artic render-scan ARGV` in this process, where this generator's category is
    registered (the runner's exit code)."""
    from artic.cli.main import main

    sys.argv = ["artic", "render-scan", *argv]
    try:
        main()
    except SystemExit as done:
        return int(done.code or 0) if not isinstance(done.code, str) else 1
    return 0


if __name__ == "__main__":
    assert all(g.spec_category in STRUCTURES for g in GENERATORS.values())
    if sys.argv[1:2] == ["render-scan"]:
        sys.exit(_render_scan(sys.argv[2:]))
    sys.exit(_generate(sys.argv[1:]))
