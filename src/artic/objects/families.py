"""The two families of procedural objects, behind one entry point.

- Appendix A templates (`ObjectSpec`, `objects.categories`): fixed kinematic structure
  per category (Chapter 3).
- Varying-structure categories (`StructureSpec`, `objects.structures`:
  storage_furniture, lamp, office_chair): the kinematic tree varies per object
  (Chapter 4).

A spec.json names its category; `parse_spec` reads it into the right spec type and
`build_object` builds either. Pure: no file access.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

from artic.objects.spec import ObjectSpec

if TYPE_CHECKING:
    from artic.objects.model import ArticulatedObject
    from artic.objects.structures import StructureSpec


def spec_category(text: str) -> str:
    """The `category` field of a spec's JSON text; ValueError when there is none."""
    data = json.loads(text)
    if not isinstance(data, dict) or not isinstance(data.get("category"), str):
        raise ValueError("expected a JSON object with a string field 'category'")
    return str(data["category"])


def parse_spec(text: str) -> ObjectSpec | StructureSpec:
    """A spec.json of either family, chosen by its `category` field.

    Raises ValueError (json.JSONDecodeError, pydantic.ValidationError) when malformed.
    """
    from artic.objects.structures import STRUCTURES, parse_structure_spec

    if spec_category(text) in STRUCTURES:
        return parse_structure_spec(text)
    return ObjectSpec.model_validate_json(text)


def build_object(spec: ObjectSpec | StructureSpec) -> ArticulatedObject:
    """The object a spec of either family describes (links in URDF order, 0 = root)."""
    if isinstance(spec, ObjectSpec):
        from artic.objects.categories import build

        return build(spec)
    from artic.objects.structures import build_structure

    return build_structure(spec)
