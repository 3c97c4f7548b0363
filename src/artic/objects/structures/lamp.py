"""Desk lamp: a base plate and a chain of 2-4 revolute links ending in a head (section 4.5).

The tree is a chain whose length and joint axes vary per object: base -> arm_0 -> ...
-> arm_{n-2} -> head. At configuration zero every arm stands vertically on the top of
the previous one and the head's shade points to the front (-x). A joint's axis is
horizontal (+y: q > 0 tilts the link backwards, towards +x) or vertical (+z: the link
swivels about its own length).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from artic.objects.model import ArticulatedObject
from artic.objects.parts import Box
from artic.objects.spec import Range
from artic.objects.structures.assembly import PartNode, assemble_tree
from artic.objects.structures.registry import StructureConfig, StructureSpec, register_structure

AxisName = Literal["horizontal", "vertical"]
_AXES = {"horizontal": np.array([0.0, 1.0, 0.0]), "vertical": np.array([0.0, 0.0, 1.0])}


class LampConfig(StructureConfig):
    """`conf/common/category/lamp.yaml`. Lengths in metres, angles in radians."""

    chain: tuple[int, int] = Field((2, 4), description="[min, max] revolute links incl. the head")
    base_width: Range = Field(description="square base plate side, m")
    base_height: Range = Field(description="base plate thickness, m")
    arm_length: Range = Field(description="length of each arm, m")
    arm_thickness: Range = Field(description="square arm section side, m")
    head_length: Range = Field(description="shade length towards the front, m")
    head_width: Range = Field(description="shade width, m")
    head_height: Range = Field(description="shade height, m")
    first_vertical: float = Field(0.5, ge=0, le=1, description="P(the base joint is vertical)")
    vertical: float = Field(0.2, ge=0, le=1, description="P(a later arm joint is vertical)")
    tilt_range: Range = Field(description="limits of a horizontal arm joint, rad")
    swivel_range: Range = Field(description="limits of a vertical joint, rad")
    head_range: Range = Field(description="limits of the head's (horizontal) joint, rad")

    @model_validator(mode="after")
    def _valid(self) -> LampConfig:
        lo, hi = self.chain
        if not 2 <= lo <= hi:
            raise ValueError(f"chain: expected 2 <= min <= max, got [{lo}, {hi}]")
        if self.head_width[0] <= self.arm_thickness[1]:
            raise ValueError("head_width: the shade must be wider than the thickest arm")
        return self


class LampSpec(StructureSpec):
    """One lamp: the base plate, the arms (base to head) and the head, with their joints."""

    category: Literal["lamp"] = "lamp"
    base_width: float = Field(gt=0, description="base plate side, m")
    base_height: float = Field(gt=0, description="base plate thickness, m")
    thickness: float = Field(gt=0, description="arm section side, m")
    arm_lengths: tuple[float, ...] = Field(min_length=1, description="arm lengths, base first, m")
    head: tuple[float, float, float] = Field(description="shade length, width, height, m")
    axes: tuple[AxisName, ...] = Field(description="joint axis per link (arms, then the head)")
    limits: tuple[Range, ...] = Field(description="joint limits per link, rad")

    @model_validator(mode="after")
    def _one_joint_per_link(self) -> LampSpec:
        n = len(self.arm_lengths) + 1
        if len(self.axes) != n or len(self.limits) != n:
            raise ValueError(f"axes and limits need {n} entries (arms + head)")
        if self.head[1] <= self.thickness:
            raise ValueError("head: the shade must be wider than the arms")
        return self


def _u(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def sample_lamp(cfg: LampConfig, index: int, rng: np.random.Generator) -> LampSpec:
    """Draw one lamp: chain length uniform in `chain`, sizes uniform, each joint's axis
    vertical with probability `first_vertical` (base joint) or `vertical` (other arms);
    the head's joint is horizontal. Only `rng` is used."""
    n = int(rng.integers(cfg.chain[0], cfg.chain[1] + 1))
    base_width, base_height = _u(rng, cfg.base_width), _u(rng, cfg.base_height)
    thickness = _u(rng, cfg.arm_thickness)
    arms = tuple(_u(rng, cfg.arm_length) for _ in range(n - 1))
    head = (_u(rng, cfg.head_length), _u(rng, cfg.head_width), _u(rng, cfg.head_height))
    axes: list[AxisName] = []
    for k in range(n - 1):
        p = cfg.first_vertical if k == 0 else cfg.vertical
        axes.append("vertical" if rng.random() < p else "horizontal")
    axes.append("horizontal")
    limits = [cfg.swivel_range if a == "vertical" else cfg.tilt_range for a in axes[:-1]]
    return LampSpec(
        index=index,
        base_width=base_width,
        base_height=base_height,
        thickness=thickness,
        arm_lengths=arms,
        head=head,
        axes=tuple(axes),
        limits=(*limits, cfg.head_range),
        parts=cfg.parts,
    )


def _square(side: float, z: tuple[float, float]) -> Box:
    return Box((-side / 2, side / 2), (-side / 2, side / 2), z)


@register_structure("lamp", LampConfig, LampSpec, sample_lamp)
def build_lamp(spec: LampSpec) -> ArticulatedObject:
    """Links base, arm_0 .. arm_{n-2}, head; joint k (revolute) between consecutive links.
    Joint origins: the base plate's top centre, then each arm's top centre."""
    p, t = spec.parts, spec.thickness
    nodes = [
        PartNode(
            "base", "base", (_square(spec.base_width, (0.0, spec.base_height)),), p.body_density
        )
    ]
    top = spec.base_height
    for k, length in enumerate(spec.arm_lengths):
        nodes.append(
            PartNode(
                name=f"arm_{k}",
                role="arm",
                boxes=(_square(t, (0.0, length)),),
                density=p.door_density,
                parent=k,
                joint_type="revolute",
                origin=np.array([0.0, 0.0, top]),
                axis=_AXES[spec.axes[k]],
                limits=spec.limits[k],
            )
        )
        top = length
    length, width, height = spec.head
    neck = _square(t, (0.0, t))
    shade = Box((-length, t / 2), (-width / 2, width / 2), (t, t + height))
    nodes.append(
        PartNode(
            name="head",
            role="head",
            boxes=(neck, shade),
            density=p.door_density,
            parent=len(nodes) - 1,
            joint_type="revolute",
            origin=np.array([0.0, 0.0, top]),
            axis=_AXES[spec.axes[-1]],
            limits=spec.limits[-1],
        )
    )
    return assemble_tree(f"lamp_{spec.index}", nodes, p)
