"""objects.families: one entry point for specs of both object families."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from artic.objects.families import build_object, parse_spec, spec_category
from artic.objects.spec import ObjectSpec
from artic.objects.structures import STRUCTURES, StructureSpec, sample_structure

CATEGORY_DIR = Path(__file__).resolve().parents[2] / "conf" / "common" / "category"


def test_parse_spec_round_trips_both_families(make_spec: Callable[[str, int], ObjectSpec]) -> None:
    template = make_spec("microwave", 0)
    parsed = parse_spec(template.model_dump_json())
    assert isinstance(parsed, ObjectSpec) and parsed == template
    assert build_object(parsed).dof == template.dof
    raw = yaml.safe_load((CATEGORY_DIR / "lamp.yaml").read_text())
    cfg = STRUCTURES["lamp"].config.model_validate(raw)
    spec = sample_structure(cfg, 3, np.random.default_rng(3))
    again = parse_spec(spec.model_dump_json())
    assert isinstance(again, StructureSpec) and again == spec
    assert len(build_object(again).links) >= 3
    assert spec_category(spec.model_dump_json()) == "lamp"


def test_malformed_specs_raise_value_errors() -> None:
    with pytest.raises(ValueError, match="category"):
        parse_spec(json.dumps({"name": "x"}))
    with pytest.raises(ValueError):
        parse_spec("not json")
    with pytest.raises(ValueError):
        parse_spec(json.dumps({"category": "microwave"}))
