"""Storage furniture: a cabinet body with a sampled grid of compartments (section 4.5).

The body is a shell open at the front (as `parts.shell_boxes`), split into rows (bottom
to top) by horizontal shelves and each row into compartments by vertical dividers, all
`panel_thickness` thick. Each compartment holds a drawer (prismatic), a door (revolute,
hinge on either side), a double door (two doors hinged at the outer edges) or nothing
(an open shelf). Every door and drawer carries a handle, part of its link (as in
PartNet-Mobility, whose links are the rigid moving parts). The number of rows,
compartments and their contents vary per object, so the kinematic tree does too: body ->
door/drawer, 1 to rows x columns x 2 movable parts.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.objects.model import ArticulatedObject
from artic.objects.parts import Box, drawer, shell_boxes, vertical_door
from artic.objects.spec import Chirality, GeometryRanges, Range
from artic.objects.structures.assembly import PartNode, assemble_tree, moving_part_node
from artic.objects.structures.registry import StructureConfig, StructureSpec, register_structure

Content = Literal["drawer", "door", "double_door", "empty"]
CONTENTS: tuple[Content, ...] = ("drawer", "door", "double_door", "empty")
MAX_CONTENT_TRIES = 20


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class ContentWeights(_Frozen):
    """Relative probabilities of a compartment's content (normalised when sampling)."""

    drawer: float = Field(1.0, ge=0, description="a drawer")
    door: float = Field(1.0, ge=0, description="a single door, hinge side uniform")
    double_door: float = Field(0.5, ge=0, description="two doors (wide compartments only)")
    empty: float = Field(0.5, ge=0, description="an open shelf")

    @model_validator(mode="after")
    def _some_moving(self) -> ContentWeights:
        if self.drawer + self.door + self.double_door <= 0:
            raise ValueError("contents: drawer, door and double_door weights are all 0")
        return self


class LayoutConfig(_Frozen):
    """How compartments are arranged."""

    rows: tuple[int, int] = Field((1, 4), description="[min, max] rows, bottom to top")
    columns: tuple[int, int] = Field((1, 3), description="[min, max] compartments per row")
    min_compartment: float = Field(
        0.18, gt=0, description="smallest compartment opening (width and height), m"
    )
    uniform_row: float = Field(
        0.5, ge=0, le=1, description="probability that all compartments of a row hold the same"
    )
    aligned: float = Field(
        0.0,
        ge=0,
        le=1,
        description="probability that every row shares the bottom row's column split, so "
        "compartments stack in columns (a chest of drawers, a hat-box door over a tall one); "
        "contents are then drawn per column and `uniform_row` makes a column uniform",
    )
    double_door_min_width: float = Field(
        0.4, gt=0, description="narrower compartments get a single door instead, m"
    )
    contents: ContentWeights = Field(default=ContentWeights(), description="content weights")

    @model_validator(mode="after")
    def _ordered(self) -> LayoutConfig:
        for field in ("rows", "columns"):
            lo, hi = getattr(self, field)
            if not 1 <= lo <= hi:
                raise ValueError(f"layout.{field}: expected 1 <= min <= max, got [{lo}, {hi}]")
        return self


class StorageFurnitureConfig(StructureConfig):
    """`conf/common/category/storage_furniture.yaml`."""

    geometry: GeometryRanges = Field(description="outer body dimension ranges, m")
    layout: LayoutConfig = Field(default=LayoutConfig(), description="compartment grid")
    door_range: Range = Field(description="door joint limits, rad (0 = closed)")
    drawer_travel: float = Field(
        0.8, gt=0, le=1, description="drawer opening limit, fraction of the drawer's length"
    )
    drawer_max: float = Field(0.5, gt=0, description="drawer opening limit cap, m")

    @model_validator(mode="after")
    def _compartment_fits(self) -> StorageFurnitureConfig:
        inner = min(self.geometry.width[0], self.geometry.height[0])
        inner -= 2 * self.parts.panel_thickness
        if self.layout.min_compartment > inner:
            raise ValueError(
                f"layout.min_compartment: {self.layout.min_compartment} m does not fit in the "
                f"smallest body's {inner} m opening"
            )
        return self


class Compartment(_Frozen):
    """One compartment: its opening width (m, between dividers), content, hinge side."""

    width: float = Field(gt=0, description="opening width along y, m")
    content: Content = Field(description="what the compartment holds")
    hinge: Chirality = Field(1, description="single door: +1 hinge at low y, -1 at high y")


class Row(_Frozen):
    """A row of compartments, listed from -y to +y."""

    height: float = Field(gt=0, description="opening height along z, m")
    compartments: tuple[Compartment, ...] = Field(min_length=1)


class StorageFurnitureSpec(StructureSpec):
    """One storage-furniture object: body size, rows (bottom to top), joint limits."""

    category: Literal["storage_furniture"] = "storage_furniture"
    depth: float = Field(gt=0, description="body extent along x, m")
    width: float = Field(gt=0, description="body extent along y, m")
    height: float = Field(gt=0, description="body extent along z, m")
    rows: tuple[Row, ...] = Field(min_length=1, description="rows, bottom to top")
    door_limits: Range = Field(description="every door joint's (lower, upper), rad")
    drawer_limits: Range = Field(description="every drawer joint's (lower, upper), m")

    @model_validator(mode="after")
    def _fits(self) -> StorageFurnitureSpec:
        wall = self.parts.panel_thickness
        heights = sum(r.height for r in self.rows) + wall * (len(self.rows) + 1)
        if not math.isclose(heights, self.height, abs_tol=1e-6):
            raise ValueError(f"rows: heights and shelves add up to {heights} m, not {self.height}")
        for r, row in enumerate(self.rows):
            widths = sum(c.width for c in row.compartments) + wall * (len(row.compartments) + 1)
            if not math.isclose(widths, self.width, abs_tol=1e-6):
                raise ValueError(
                    f"rows.{r}: widths and dividers add up to {widths} m, not {self.width}"
                )
        if not any(c.content != "empty" for row in self.rows for c in row.compartments):
            raise ValueError("rows: at least one compartment must hold a door or drawer")
        return self


def _split(rng: np.random.Generator, total: float, count: int, smallest: float) -> list[float]:
    """`count` extents >= `smallest` adding up to `total` (uniform on the simplex)."""
    extra = total - count * smallest
    return [smallest + extra * float(w) for w in rng.dirichlet(np.ones(count))]


def _count(
    rng: np.random.Generator, bounds: tuple[int, int], inner: float, cfg: StorageFurnitureConfig
) -> int:
    """Uniform count in `bounds`, capped so each opening is >= min_compartment."""
    wall, smallest = cfg.parts.panel_thickness, cfg.layout.min_compartment
    fit = math.floor((inner + wall) / (smallest + wall))
    if fit < 1:
        raise ValueError(f"layout.min_compartment: {smallest} m does not fit in {inner} m")
    hi = max(1, min(bounds[1], fit))
    return int(rng.integers(min(bounds[0], hi), hi + 1))


def _contents(
    rng: np.random.Generator, widths: list[float], cfg: StorageFurnitureConfig
) -> list[Compartment]:
    weights = cfg.layout.contents
    p = np.array([weights.drawer, weights.door, weights.double_door, weights.empty])
    p = p / p.sum()
    same = bool(rng.random() < cfg.layout.uniform_row)
    picks = (
        [int(rng.choice(len(CONTENTS), p=p))] * len(widths)
        if same
        else [int(rng.choice(len(CONTENTS), p=p)) for _ in widths]
    )
    hinges = rng.choice([-1, 1], size=len(widths))
    cells = []
    for width, pick, hinge in zip(widths, picks, hinges, strict=True):
        content = CONTENTS[pick]
        if content == "double_door" and width < cfg.layout.double_door_min_width:
            content = "door"
        cells.append(Compartment(width=width, content=content, hinge=1 if hinge > 0 else -1))
    return cells


def sample_storage_furniture(
    cfg: StorageFurnitureConfig, index: int, rng: np.random.Generator
) -> StorageFurnitureSpec:
    """Draw one object: dimensions (uniform), row count and heights, per row the
    compartment count and widths (with probability `layout.aligned` the bottom row's for
    every row: columns of stacked compartments, whose contents are then drawn per column
    rather than per row, `uniform_row` making a column uniform), and contents. Contents
    are redrawn (at most `MAX_CONTENT_TRIES` times) until some compartment moves; then the
    first becomes a drawer. Only `rng` is used."""
    depth, width, height = (
        float(rng.uniform(*r))
        for r in (cfg.geometry.depth, cfg.geometry.width, cfg.geometry.height)
    )
    wall, smallest = cfg.parts.panel_thickness, cfg.layout.min_compartment
    inner_h, inner_w = height - 2 * wall, width - 2 * wall
    n_rows = _count(rng, cfg.layout.rows, inner_h, cfg)
    heights = _split(rng, inner_h - (n_rows - 1) * wall, n_rows, smallest)
    aligned = cfg.layout.aligned > 0 and bool(rng.random() < cfg.layout.aligned)
    layout: list[tuple[float, list[float]]] = []
    for row_height in heights:
        if aligned and layout:
            layout.append((row_height, layout[0][1]))
            continue
        n_cols = _count(rng, cfg.layout.columns, inner_w, cfg)
        layout.append((row_height, _split(rng, inner_w - (n_cols - 1) * wall, n_cols, smallest)))
    for _ in range(MAX_CONTENT_TRIES):
        if aligned:  # contents drawn per column, so a column can be uniform (a stack)
            columns = [_contents(rng, [w] * len(layout), cfg) for w in layout[0][1]]
            cells = [tuple(column[r] for column in columns) for r in range(len(layout))]
        else:
            cells = [tuple(_contents(rng, w, cfg)) for _, w in layout]
        rows = [Row(height=h, compartments=c) for (h, _), c in zip(layout, cells, strict=True)]
        if any(c.content != "empty" for row in rows for c in row.compartments):
            break
    else:
        first = rows[0].compartments[0].model_copy(update={"content": "drawer"})
        rows[0] = Row(height=rows[0].height, compartments=(first, *rows[0].compartments[1:]))
    length = depth - wall - cfg.parts.gap  # the drawer, front face to back
    return StorageFurnitureSpec(
        index=index,
        depth=depth,
        width=width,
        height=height,
        rows=tuple(rows),
        door_limits=cfg.door_range,
        drawer_limits=(0.0, min(cfg.drawer_max, cfg.drawer_travel * length)),
        parts=cfg.parts,
    )


def _grid(spec: StorageFurnitureSpec) -> list[tuple[float, float, list[tuple[float, float]]]]:
    """Per row (z_lo, z_hi, [(y_lo, y_hi) per compartment]): opening bounds, body frame."""
    wall = spec.parts.panel_thickness
    rows, z = [], wall
    for row in spec.rows:
        spans, y = [], -spec.width / 2 + wall
        for cell in row.compartments:
            spans.append((y, y + cell.width))
            y += cell.width + wall
        rows.append((z, z + row.height, spans))
        z += row.height + wall
    return rows


def _cover(
    lo: float, hi: float, outer: tuple[float, float], wall: float, gap: float
) -> tuple[float, float]:
    """The front area a door covers: to the middle of inner dividers (minus half the
    gap), to the outer edge at the body's sides."""
    a = outer[0] if math.isclose(lo - wall, outer[0], abs_tol=1e-9) else lo - wall / 2 + gap / 2
    b = outer[1] if math.isclose(hi + wall, outer[1], abs_tol=1e-9) else hi + wall / 2 - gap / 2
    return a, b


def _body_boxes(spec: StorageFurnitureSpec) -> list[Box]:
    wall = spec.parts.panel_thickness
    front, back = -spec.depth / 2, spec.depth / 2 - wall
    inner_y = (-spec.width / 2 + wall, spec.width / 2 - wall)
    boxes = shell_boxes(spec.depth, spec.width, spec.height, wall)
    grid = _grid(spec)
    for z_lo, z_hi, spans in grid:
        if z_hi + wall < spec.height - 1e-9:
            boxes.append(Box((front, back), inner_y, (z_hi, z_hi + wall)))  # shelf above
        for _, y_hi in spans[:-1]:
            boxes.append(Box((front, back), (y_hi, y_hi + wall), (z_lo, z_hi)))  # divider
    return boxes


@register_structure(
    "storage_furniture", StorageFurnitureConfig, StorageFurnitureSpec, sample_storage_furniture
)
def build_storage_furniture(spec: StorageFurnitureSpec) -> ArticulatedObject:
    """Body, then per compartment (rows bottom to top, -y to +y) its door(s) or drawer
    (each with its handle). Names: `door_<n>` / `drawer_<n>`, numbered in that order."""
    p = spec.parts
    wall, gap, front = p.panel_thickness, p.gap, -spec.depth / 2
    nodes = [PartNode("body", "body", tuple(_body_boxes(spec)), p.body_density)]
    n = 0
    for row, (z_lo, z_hi, spans) in zip(spec.rows, _grid(spec), strict=True):
        z_cover = _cover(z_lo, z_hi, (0.0, spec.height), wall, gap)
        for cell, (y_lo, y_hi) in zip(row.compartments, spans, strict=True):
            y_cover = _cover(y_lo, y_hi, (-spec.width / 2, spec.width / 2), wall, gap)
            if cell.content == "drawer":
                moving = [
                    drawer(
                        f"drawer_{n}",
                        p,
                        (front, spec.depth / 2 - wall - gap),
                        (y_lo + gap, y_hi - gap),
                        (z_lo + gap, z_hi - gap),
                    )
                ]
            elif cell.content == "door":
                moving = [vertical_door(f"door_{n}", p, front, y_cover, z_cover, cell.hinge)]
            elif cell.content == "double_door":
                mid = 0.5 * (y_cover[0] + y_cover[1])
                moving = [
                    vertical_door(f"door_{n}", p, front, (y_cover[0], mid - gap / 2), z_cover, 1),
                    vertical_door(
                        f"door_{n + 1}", p, front, (mid + gap / 2, y_cover[1]), z_cover, -1
                    ),
                ]
            else:
                continue
            for part in moving:
                limits = spec.drawer_limits if part.role == "drawer" else spec.door_limits
                nodes.append(moving_part_node(part, 0, p, limits))
                n += 1
    return assemble_tree(f"storage_furniture_{spec.index}", nodes, p)
