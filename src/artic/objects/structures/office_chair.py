"""Office chair: a four-legged base on glides, wheels or swivelling casters, a gas-lift
column, a swivelling seat, and optionally a back (fixed or tilting) and armrests.

Trees vary per object (section 4.5): base -> [caster_k ->] wheel_k (continuous), base ->
[column (prismatic, +z) ->] seat (continuous swivel about +z, or fixed) -> back (fixed
or revolute about +y: q > 0 reclines) and armrests (fixed). Legs run along +x, +y, -x,
-y from the centre; the seat's front faces -x. Lengths in metres, angles in radians.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from artic.objects.model import ArticulatedObject, UrdfJointType
from artic.objects.parts import Box
from artic.objects.spec import Range
from artic.objects.structures.assembly import PartNode, assemble_tree
from artic.objects.structures.registry import StructureConfig, StructureSpec, register_structure

Feet = Literal["glides", "wheels", "casters"]
Back = Literal["none", "fixed", "tilting"]
FEET: tuple[Feet, ...] = ("glides", "wheels", "casters")
BACKS: tuple[Back, ...] = ("none", "fixed", "tilting")
_LEGS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))
_TUBE_WALL = 0.006  # m, wall of the base's gas-spring tube
_GLIDE = 0.02  # m, glide height
_CASTER = 0.02  # m, caster block height
_MECHANISM = 0.04  # m, height of the block under the seat


class _Weights(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class FeetWeights(_Weights):
    glides: float = Field(0.2, ge=0, description="static feet (no wheel parts)")
    wheels: float = Field(0.3, ge=0, description="wheels on the legs (continuous joints)")
    casters: float = Field(0.5, ge=0, description="swivelling casters carrying wheels")


class BackWeights(_Weights):
    none: float = Field(0.1, ge=0, description="no back (a stool)")
    fixed: float = Field(0.5, ge=0, description="a back on a fixed joint")
    tilting: float = Field(0.4, ge=0, description="a reclining back (revolute)")


class OfficeChairConfig(StructureConfig):
    """`conf/common/category/office_chair.yaml`."""

    leg_reach: Range = Field(description="centre to leg end, m")
    leg_thickness: Range = Field(description="square leg section side, m")
    wheel_radius: Range = Field(description="wheel radius, m")
    wheel_width: Range = Field(description="wheel width, m")
    tube_height: Range = Field(description="gas-spring tube above the legs, m")
    tube_side: Range = Field(description="square tube side, m")
    lift_travel: Range = Field(description="gas-lift stroke, m")
    column_length: Range = Field(description="column above the tube when down, m")
    seat_depth: Range = Field(description="seat extent along x, m")
    seat_width: Range = Field(description="seat extent along y, m")
    seat_thickness: Range = Field(description="seat cushion thickness, m")
    back_height: Range = Field(description="back panel height, m")
    back_tilt: Range = Field(description="upper limit of a tilting back, rad")
    armrest_height: Range = Field(description="armrest pad above the seat, m")
    feet: FeetWeights = Field(default=FeetWeights(), description="what the legs stand on")
    back: BackWeights = Field(default=BackWeights(), description="back kinds")
    gas_lift: float = Field(0.8, ge=0, le=1, description="P(a height-adjustable column)")
    swivel: float = Field(0.9, ge=0, le=1, description="P(the seat swivels)")
    armrests: float = Field(0.5, ge=0, le=1, description="P(two armrests)")
    spin_range: Range = Field(description="range continuous joints' poses are drawn from, rad")

    @model_validator(mode="after")
    def _column_fits(self) -> OfficeChairConfig:
        if self.tube_side[0] <= 2 * (_TUBE_WALL + self.parts.gap) + 0.01:
            raise ValueError("tube_side: leaves no room for the gas-lift column inside the tube")
        return self


class OfficeChairSpec(StructureSpec):
    """One office chair."""

    category: Literal["office_chair"] = "office_chair"
    leg_reach: float = Field(gt=0)
    leg_thickness: float = Field(gt=0)
    feet: Feet
    wheel_radius: float = Field(gt=0)
    wheel_width: float = Field(gt=0)
    tube_height: float = Field(gt=0)
    tube_side: float = Field(gt=0)
    gas_lift: bool
    lift_travel: float = Field(gt=0)
    column_length: float = Field(gt=0)
    seat_depth: float = Field(gt=0)
    seat_width: float = Field(gt=0)
    seat_thickness: float = Field(gt=0)
    swivel: bool
    back: Back
    back_height: float = Field(gt=0)
    back_tilt: float = Field(gt=0)
    armrests: bool
    armrest_height: float = Field(gt=0)
    spin_range: Range


def _pick(rng: np.random.Generator, names: tuple[str, ...], weights: _Weights) -> str:
    p = np.array([getattr(weights, n) for n in names], dtype=np.float64)
    if p.sum() <= 0:
        raise ValueError(f"weights of {', '.join(names)} are all 0")
    return names[int(rng.choice(len(names), p=p / p.sum()))]


def sample_office_chair(
    cfg: OfficeChairConfig, index: int, rng: np.random.Generator
) -> OfficeChairSpec:
    """Draw one chair: sizes uniform, then feet, gas lift, swivel, back and armrests. A
    chair that would not move at all gets a swivelling seat. Only `rng` is used."""
    sizes = {
        name: float(rng.uniform(*getattr(cfg, name)))
        for name in (
            "leg_reach", "leg_thickness", "wheel_radius", "wheel_width", "tube_height",
            "tube_side", "lift_travel", "column_length", "seat_depth", "seat_width",
            "seat_thickness", "back_height", "back_tilt", "armrest_height",
        )
    }  # fmt: skip
    feet = _pick(rng, FEET, cfg.feet)
    gas_lift = bool(rng.random() < cfg.gas_lift)
    swivel = bool(rng.random() < cfg.swivel)
    back = _pick(rng, BACKS, cfg.back)
    armrests = bool(rng.random() < cfg.armrests)
    if feet == "glides" and not gas_lift and back != "tilting":
        swivel = True
    return OfficeChairSpec.model_validate(
        {
            **sizes,
            "index": index,
            "feet": feet,
            "gas_lift": gas_lift,
            "swivel": swivel,
            "back": back,
            "armrests": armrests,
            "spin_range": cfg.spin_range,
            "parts": cfg.parts,
        }
    )


def _square(side: float, z: tuple[float, float]) -> Box:
    return Box((-side / 2, side / 2), (-side / 2, side / 2), z)


def _wheel(radius: float, width: float, axis_y: bool) -> tuple[Box, ...]:
    """A plus-shaped wheel centred at the origin, rolling about y (axis_y) or x."""
    r, s, w = radius, 0.6 * radius, width / 2
    if axis_y:
        return (Box((-r, r), (-w, w), (-s, s)), Box((-s, s), (-w, w), (-r, r)))
    return (Box((-w, w), (-r, r), (-s, s)), Box((-w, w), (-s, s), (-r, r)))


def _base_boxes(spec: OfficeChairSpec, z0: float) -> list[Box]:
    reach, lt, half = spec.leg_reach, spec.leg_thickness, spec.tube_side / 2
    legs = (z0, z0 + lt)
    hub = half + 0.01
    boxes = [
        Box((-reach - lt / 2, reach + lt / 2), (-lt / 2, lt / 2), legs),
        Box((-lt / 2, lt / 2), (-reach - lt / 2, reach + lt / 2), legs),
        Box((-hub, hub), (-hub, hub), legs),
    ]
    tube = (z0 + lt, z0 + lt + spec.tube_height)
    w = _TUBE_WALL
    boxes += [
        Box((-half, -half + w), (-half, half), tube),
        Box((half - w, half), (-half, half), tube),
        Box((-half + w, half - w), (-half, -half + w), tube),
        Box((-half + w, half - w), (half - w, half), tube),
    ]
    if spec.feet == "glides":
        boxes += [
            Box(
                (x * reach - lt / 2, x * reach + lt / 2),
                (y * reach - lt / 2, y * reach + lt / 2),
                (0.0, _GLIDE),
            )
            for x, y in _LEGS
        ]
    return boxes


def _feet_nodes(spec: OfficeChairSpec, z0: float) -> list[PartNode]:
    p, r, gap = spec.parts, spec.wheel_radius, spec.parts.gap
    spin: tuple[float, float] = spec.spin_range
    nodes: list[PartNode] = []
    y_axis, x_axis = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])
    for k, (x, y) in enumerate(_LEGS):
        end = np.array([x * spec.leg_reach, y * spec.leg_reach, 0.0])
        if spec.feet == "wheels":
            along_x = x != 0.0
            nodes.append(
                PartNode(
                    f"wheel_{k}", "wheel", _wheel(r, spec.wheel_width, along_x), p.handle_density,
                    parent=0, joint_type="continuous", origin=end + np.array([0.0, 0.0, r]),
                    axis=y_axis if along_x else x_axis, limits=spin,
                )
            )  # fmt: skip
        elif spec.feet == "casters":
            trail, side = 0.5 * r, spec.wheel_width / 2 + 0.005
            block = Box((-trail - 0.4 * r, 0.4 * r), (-side, side), (-_CASTER, 0.0))
            caster = len(nodes) + 1
            nodes.append(
                PartNode(
                    f"caster_{k}", "caster", (block,), p.handle_density, parent=0,
                    joint_type="continuous", origin=end + np.array([0.0, 0.0, z0 - gap]),
                    axis=np.array([0.0, 0.0, 1.0]), limits=spin,
                )
            )  # fmt: skip
            nodes.append(
                PartNode(
                    f"wheel_{k}", "wheel", _wheel(r, spec.wheel_width, True), p.handle_density,
                    parent=caster, joint_type="continuous",
                    origin=np.array([-trail, 0.0, -_CASTER - gap - r]), axis=y_axis, limits=spin,
                )
            )  # fmt: skip
    return nodes


def _joint(movable: bool, kind: UrdfJointType) -> UrdfJointType:
    return kind if movable else "fixed"


@register_structure("office_chair", OfficeChairConfig, OfficeChairSpec, sample_office_chair)
def build_office_chair(spec: OfficeChairSpec) -> ArticulatedObject:
    """Links in depth-first order: base, the feet (caster_k, wheel_k or wheel_k per leg
    +x, +y, -x, -y), column (if gas lift), seat, back (unless none), armrest_0 (-y),
    armrest_1 (+y)."""
    p, gap, r = spec.parts, spec.parts.gap, spec.wheel_radius
    z0 = {"glides": _GLIDE, "wheels": 2 * r + gap, "casters": 2 * r + 2 * gap + _CASTER}[spec.feet]
    tube_top = z0 + spec.leg_thickness + spec.tube_height
    nodes = [PartNode("base", "base", tuple(_base_boxes(spec, z0)), p.body_density)]
    nodes += _feet_nodes(spec, z0)
    seat_parent, seat_origin = 0, np.array([0.0, 0.0, tube_top])
    if spec.gas_lift:
        side = spec.tube_side - 2 * _TUBE_WALL - 2 * gap
        insert = min(spec.lift_travel + 0.02, spec.tube_height)
        nodes.append(
            PartNode(
                "column", "column", (_square(side, (-insert, spec.column_length)),), p.body_density,
                parent=0, joint_type="prismatic", origin=seat_origin,
                axis=np.array([0.0, 0.0, 1.0]), limits=(0.0, min(spec.lift_travel, insert)),
            )
        )  # fmt: skip
        seat_parent, seat_origin = len(nodes) - 1, np.array([0.0, 0.0, spec.column_length])
    sd, sw, top = spec.seat_depth, spec.seat_width, _MECHANISM + spec.seat_thickness
    seat_boxes = (
        _square(min(0.12, 0.5 * sd), (0.0, _MECHANISM)),
        Box((-sd / 2, sd / 2), (-sw / 2, sw / 2), (_MECHANISM, top)),
    )
    seat = len(nodes)
    nodes.append(
        PartNode(
            "seat", "seat", seat_boxes, p.door_density, parent=seat_parent,
            joint_type=_joint(spec.swivel, "continuous"), origin=seat_origin,
            axis=np.array([0.0, 0.0, 1.0]), limits=spec.spin_range if spec.swivel else (0.0, 0.0),
        )
    )  # fmt: skip
    if spec.back != "none":
        tilting = spec.back == "tilting"
        tilt = (0.0, spec.back_tilt) if tilting else (0.0, 0.0)
        back = Box((-0.03, 0.0), (-0.45 * sw, 0.45 * sw), (gap, gap + spec.back_height))
        nodes.append(
            PartNode(
                "back", "back", (back,), p.door_density, parent=seat,
                joint_type=_joint(tilting, "revolute"), origin=np.array([sd / 2, 0.0, top]),
                axis=np.array([0.0, 1.0, 0.0]), limits=tilt,
            )
        )  # fmt: skip
    if spec.armrests:
        post, pad_w, pad_l, h = 0.025, 0.06, 0.6 * sd, spec.armrest_height
        boxes = (
            _square(post, (gap, h)),
            Box((-pad_l / 2, pad_l / 2), (-pad_w / 2, pad_w / 2), (h, h + post)),
        )
        for k, side in enumerate((-1.0, 1.0)):
            nodes.append(
                PartNode(
                    f"armrest_{k}", "armrest", boxes, p.door_density, parent=seat,
                    origin=np.array([0.0, side * (sw / 2 - pad_w / 2), top]),
                )
            )  # fmt: skip
    return assemble_tree(f"office_chair_{spec.index}", nodes, p)
