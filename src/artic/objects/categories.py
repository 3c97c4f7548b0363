"""The six object categories of the thesis' synthetic dataset (section 3.2.3, Appendix A),
the two mechanisms of Chapter 7's tasks (section 7.4: slide, lever), and the registry
that maps a category name to its builder.

`build(spec)` is pure: the spec fully determines the object. Builders share the part
constructors of `artic.objects.parts`; conventions (frames, hinge sides, joint order)
are written down in `docs/objects.md`.
"""

from __future__ import annotations

from collections.abc import Callable

from artic.named import Registry
from artic.objects.model import ArticulatedObject
from artic.objects.parts import (
    Box,
    Interval,
    assemble,
    drawer,
    flap_door,
    lever_arm,
    overlay_front,
    shell_boxes,
    slide_carriage,
    vertical_door,
)
from artic.objects.spec import ObjectSpec

Builder = Callable[[ObjectSpec], ArticulatedObject]

CATEGORIES: Registry[Builder] = Registry("category", "category", "categories")
"""Registered builders by category name; fill it with `@register_category`."""
#: decorator: register `builder(spec) -> ArticulatedObject` under a name
register_category = CATEGORIES.register


def get_builder(name: str) -> Builder:
    """The builder registered as `name`; InputError naming the known categories otherwise."""
    return CATEGORIES.lookup(name)


def build(spec: ObjectSpec) -> ArticulatedObject:
    """Meshes, links and joints of the object `spec` describes (pure, deterministic)."""
    obj = get_builder(spec.category)(spec)
    if obj.dof != spec.dof:
        raise ValueError(f"{spec.category}: builder made {obj.dof} DoF, spec says {spec.dof}")
    kinds = {joint.type for joint in obj.movable_joints}
    if kinds != {spec.joint_type}:
        raise ValueError(f"joint_type: {spec.category} builds {kinds}, spec says {spec.joint_type}")
    return obj


def _front_x(spec: ObjectSpec) -> float:
    return -spec.depth / 2


def _shell(spec: ObjectSpec) -> list[Box]:
    return shell_boxes(spec.depth, spec.width, spec.height, spec.parts.panel_thickness)


def _panel_split(spec: ObjectSpec, panel_side: int) -> tuple[Interval, Interval]:
    """Split the front width into (door span, control-panel span) along y; the panel strip
    (`control_panel_fraction` of the width) is on the +y side if panel_side > 0."""
    half, gap = spec.width / 2, spec.parts.gap
    panel = spec.parts.control_panel_fraction * spec.width
    if panel_side > 0:
        return (-half, half - panel - gap), (half - panel, half)
    return (-half + panel + gap, half), (-half, -half + panel)


def _control_panel(spec: ObjectSpec, span_y: Interval) -> Box:
    """A control-panel plate on the body front, flush with the closed door's face."""
    front = _front_x(spec)
    return Box((front - spec.parts.door_thickness, front), span_y, (0.0, spec.height))


@register_category("cabinet")
def build_cabinet(spec: ObjectSpec) -> ArticulatedObject:
    """One full-front door, hinge side from `spec.chirality`."""
    half = spec.width / 2
    door = vertical_door(
        "door_0", spec.parts, _front_x(spec), (-half, half), (0.0, spec.height), spec.chirality
    )
    return assemble(spec, _shell(spec), [door])


@register_category("cabinet2")
def build_cabinet2(spec: ObjectSpec) -> ArticulatedObject:
    """Two half-width doors hinged at the outer edges: joint 0 the -y door (axis +z),
    joint 1 the +y door (axis -z). Chirality has no meaning here."""
    half, gap = spec.width / 2, spec.parts.gap / 2
    heights = (0.0, spec.height)
    doors = [
        vertical_door("door_0", spec.parts, _front_x(spec), (-half, -gap), heights, 1),
        vertical_door("door_1", spec.parts, _front_x(spec), (gap, half), heights, -1),
    ]
    return assemble(spec, _shell(spec), doors)


@register_category("microwave")
def build_microwave(spec: ObjectSpec) -> ArticulatedObject:
    """A door beside a control-panel strip on its free-edge side; hinge from chirality
    (+1: hinge at -y, panel at +y)."""
    door_y, panel_y = _panel_split(spec, panel_side=spec.chirality)
    door = vertical_door(
        "door_0", spec.parts, _front_x(spec), door_y, (0.0, spec.height), spec.chirality
    )
    return assemble(spec, [*_shell(spec), _control_panel(spec, panel_y)], [door])


@register_category("toaster")
def build_toaster(spec: ObjectSpec) -> ArticulatedObject:
    """A bottom-hinged door (axis (0, -1, 0)) beside a control-panel strip on the -y
    (camera-right) side. Chirality has no meaning here."""
    door_y, panel_y = _panel_split(spec, panel_side=-1)
    door = flap_door("door_0", spec.parts, _front_x(spec), door_y, (0.0, spec.height))
    return assemble(spec, [*_shell(spec), _control_panel(spec, panel_y)], [door])


@register_category("drawer")
def build_drawer(spec: ObjectSpec) -> ArticulatedObject:
    """A drawer inside the shell opening, front flush with the body front, `gap`
    clearance to the walls; prismatic along (-1, 0, 0). With `parts.drawer_front`
    "overlay", a plate `door_thickness` thick in front of it covers the body's front but
    `gap` round its edge, its back face on the body's front when shut (the joint origin,
    as the inset front's front face), the handle on the plate."""
    p = spec.parts
    clear = p.panel_thickness + p.gap
    half = spec.width / 2
    part = drawer(
        "drawer_0",
        p,
        (_front_x(spec), spec.depth / 2 - clear),
        (-half + clear, half - clear),
        (clear, spec.height - clear),
    )
    if p.drawer_front == "overlay":
        part = overlay_front(part, p, (half - p.gap, spec.height / 2 - p.gap))
    return assemble(spec, _shell(spec), [part])


@register_category("refrigerator")
def build_refrigerator(spec: ObjectSpec) -> ArticulatedObject:
    """Fridge door below (joint 0), freezer door above (joint 1, `freezer_fraction` of
    the height), both hinged on the chirality side; a shelf divides the compartments."""
    p = spec.parts
    split = spec.height * (1.0 - p.freezer_fraction)
    half, front = spec.width / 2, _front_x(spec)
    doors = [
        vertical_door("door_0", p, front, (-half, half), (0.0, split - p.gap / 2), spec.chirality),
        vertical_door(
            "door_1", p, front, (-half, half), (split + p.gap / 2, spec.height), spec.chirality
        ),
    ]
    wall = p.panel_thickness
    divider = Box(
        (front, spec.depth / 2 - wall),
        (-half + wall, half - wall),
        (split - wall / 2, split + wall / 2),
    )
    return assemble(spec, [*_shell(spec), divider], doors)


def _block(spec: ObjectSpec) -> Box:
    """The solid body of the Chapter 7 mechanisms: the whole depth x width x height box."""
    half_d, half_w = spec.depth / 2, spec.width / 2
    return Box((-half_d, half_d), (-half_w, half_w), (0.0, spec.height))


@register_category("slide")
def build_slide(spec: ObjectSpec) -> ArticulatedObject:
    """A knob on a carriage sliding along a rail on the front of a solid block (section
    7.4's slide): prismatic along (0, chirality, 0), the travel (the joint limits)
    centred on the front at mid-height. The rail is a bar of `panel_thickness` square
    section spanning the carriage's sweep."""
    p = spec.parts
    travel = spec.joint_limits[0]
    reach = 0.5 * (travel[1] - travel[0]) + p.handle_inset  # sweep of the carriage's edges
    if reach > spec.width / 2 or p.handle_inset > spec.height / 2:
        raise ValueError(
            f"width: a {spec.width} x {spec.height} m slide front has no room for "
            f"{travel[1] - travel[0]} m of travel of a {2 * p.handle_inset} m carriage"
        )
    front, side, centre_z = _front_x(spec), p.panel_thickness, spec.height / 2
    rail = Box((front - side, front), (-reach, reach), (centre_z - side / 2, centre_z + side / 2))
    part = slide_carriage("slider_0", p, front - side, centre_z, travel, spec.chirality)
    return assemble(spec, [_block(spec), rail], [part])


@register_category("lever")
def build_lever(spec: ObjectSpec) -> ArticulatedObject:
    """An arm hinged at the centre of a solid block's front (section 7.4's lever), a knob
    at its free end: axis (-chirality, 0, 0), up at q = 0, the knob turning towards
    chirality * y. Knob radius min(width, height) / 2 - 2 `handle_inset`, so the arm
    stays in front of the block's front face at every angle."""
    p = spec.parts
    length = min(spec.width, spec.height) / 2 - 2.0 * p.handle_inset
    if length <= 0:
        raise ValueError(
            f"width: a {spec.width} x {spec.height} m lever front leaves no arm beside "
            f"handle_inset {p.handle_inset} m (knob radius min(width, height) / 2 - 2 inset)"
        )
    arm = lever_arm("lever_0", p, _front_x(spec), spec.height / 2, length, spec.chirality)
    return assemble(spec, [_block(spec)], [arm])
