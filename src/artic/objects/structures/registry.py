"""Registry of the Chapter 4 categories: objects whose kinematic tree varies per instance.

The six Appendix A categories (`artic.objects.categories`) have one template tree each;
the categories here (storage furniture, lamp, office chair; thesis section 4.5) sample
the tree itself: how many parts, which joints, how deep. Each registers a config model
(`conf/common/category/<name>.yaml`), a spec model (pure data, JSON round trip), a
sampler `sample(cfg, index, rng) -> spec` and a pure builder `build(spec)`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from artic.objects.model import ArticulatedObject
from artic.objects.spec import PartsConfig


class StructureConfig(BaseModel):
    """Base of a Chapter 4 category config: its name and the part constants."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(description="category name, a key of STRUCTURES")
    parts: PartsConfig = Field(default=PartsConfig(), description="part constants")


class StructureSpec(BaseModel):
    """Base of a Chapter 4 object spec: category, sample index and part constants.

    There is no base pose: the object frame is the world frame (z up, front towards -x).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    category: str = Field(description="category name (registry key)")
    index: int = Field(ge=0, description="sample index within its dataset")
    parts: PartsConfig = Field(description="part constants used to build it")


Sampler = Callable[[Any, int, np.random.Generator], StructureSpec]
StructureBuilder = Callable[[Any], ArticulatedObject]


@dataclass(frozen=True)
class StructureCategory:
    """One registered Chapter 4 category."""

    name: str
    config: type[StructureConfig]
    spec: type[StructureSpec]
    sample: Sampler
    build: StructureBuilder


STRUCTURES: dict[str, StructureCategory] = {}
"""Registered Chapter 4 categories by name; fill it with `@register_structure`."""


def register_structure(
    name: str, config: type[StructureConfig], spec: type[StructureSpec], sample: Sampler
) -> Callable[[StructureBuilder], StructureBuilder]:
    """Decorator on a builder: register category `name` with its models and sampler."""

    def decorate(builder: StructureBuilder) -> StructureBuilder:
        if name in STRUCTURES:
            raise ValueError(f"category {name!r} is already registered")
        STRUCTURES[name] = StructureCategory(name, config, spec, sample, builder)
        return builder

    return decorate


def get_structure(name: str) -> StructureCategory:
    """The category registered as `name`; KeyError naming the known ones otherwise."""
    try:
        return STRUCTURES[name]
    except KeyError:
        known = ", ".join(sorted(STRUCTURES))
        raise KeyError(
            f"unknown category {name!r}; known varying-structure categories: {known}"
        ) from None
