"""Chapter 4 categories with varying kinematic trees: storage furniture, lamp, office chair.

Importing this package registers them in `STRUCTURES`. `sample_structure(cfg, index,
rng)` draws a spec, `build_structure(spec)` builds it (pure), `parse_structure_spec`
reads a spec back from its JSON text. Conventions: docs/objects.md, "Objects with
varying structure (Chapter 4)".
"""

from __future__ import annotations

import numpy as np

from artic.objects.model import ArticulatedObject
from artic.objects.structures import lamp, office_chair, storage_furniture
from artic.objects.structures.registry import (
    STRUCTURES,
    StructureConfig,
    StructureSpec,
    get_structure,
    register_structure,
)

__all__ = [
    "STRUCTURES",
    "StructureConfig",
    "StructureSpec",
    "build_structure",
    "get_structure",
    "lamp",
    "office_chair",
    "parse_structure_spec",
    "register_structure",
    "sample_structure",
    "storage_furniture",
]


def sample_structure(cfg: StructureConfig, index: int, rng: np.random.Generator) -> StructureSpec:
    """Draw object `index` of the category `cfg.name` from `rng` (and nothing else)."""
    category = get_structure(cfg.name)
    if not isinstance(cfg, category.config):
        raise TypeError(f"{cfg.name}: expected a {category.config.__name__}")
    return category.sample(cfg, index, rng)


def build_structure(spec: StructureSpec) -> ArticulatedObject:
    """The object `spec` describes: links in depth-first order, link index = part id."""
    obj = get_structure(spec.category).build(spec)
    obj.parent_indices()  # raises unless a valid tree
    return obj


def parse_structure_spec(text: str) -> StructureSpec:
    """A spec from its JSON text (`spec.model_dump_json()`), by its `category` field."""
    import json

    category = json.loads(text).get("category")
    return get_structure(str(category)).spec.model_validate_json(text)
