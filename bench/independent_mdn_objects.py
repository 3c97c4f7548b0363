"""A second generator of the six categories for Chapter 3 (issue 24, "Done when"):
objects the MDN never trained on, rendered by a camera of another tool, predicted through
`artic predict`'s code path and scored against their true labels.

    .venv/bin/python bench/independent_mdn_objects.py \
        --category microwave|cabinet|cabinet2|toaster|drawer|refrigerator \
        --objects 60 --seed 0 --model DIR [--report DIR] --out DIR \
        [--sides both|left|right] [--sizes table_a1|generator] [--builder bench|artic]
        [--placement frame|table_a2] [--no-refine]

`--model`: a `train-mdn` output folder (its `model.pt`) or a model file, of `--category`.
`--report`: an `artic evaluate mdn` output folder of that model: the median axis-position
error of the estimate scored ("Ours" rows of its errors.csv, or "Ours + refinement" when
refining) on withheld training-generator objects, the denominator of `ratio`.
`--sides` (the categories with a hinge side to draw, `SIDED`: microwave, cabinet,
refrigerator): both = object i hinged on the camera's right (chirality +1) for even i,
left (-1) for odd i, so exactly half each. The others (cabinet2, toaster, drawer: training
chirality [1], no hinge side) take only "both"; their images have side "none" and one
summary row, "both". `--no-refine`: the network's estimate (`artic predict --no-refine`),
scored against the report's "Ours" rows.
`--sizes`: cabinets and two-door cabinets of Table A.1 (56-64 x 60-140 x 60-140 cm) or
of the thesis' generator (half of them: 28-32 x 30-70 x 30-70 cm); the other categories
have one range, Table A.1's (`SIZES`), so the option only names the row for them.
For the drawer (prismatic) the "configuration" columns are centimetres, not degrees (as
`kinematic_errors` gives them); the two-door categories' errors are the means over their
two joints (as `evaluate mdn`'s).
`--builder artic`: the control. The same numbers (sizes, hinge side, pose, q), camera,
placement and noise, but the object built by artic's own builder (`label_spec` through
`artic.objects.categories.build`): what is left of the error is the camera, the placement
and the noise; the difference to the default is this generator's objects.
`--placement`: `frame` (the default) places the object anywhere it fits the image (below);
`table_a2` keeps its base's height (camera z) inside Table A.2's range for the category
(conf/common/category/<category>.yaml `pose.z`: the training views' heights, the camera
above a drawer's base, 0.7-1.5 m above a refrigerator's) where the image allows it: z
uniform over that range's overlap with the positions that keep the object inside the
image, or the position nearest the range when they do not overlap. The distance, y, the
objects, the camera and the noise are `frame`'s; the draws are the same numbers, so
object i differs between the two in its height only.

Writes into `--out` (a new or empty folder; built in a temporary sibling, renamed in
place): `images/NNNNNN.png` (depth, 16-bit millimetres), `camera.json` (the six
intrinsics and a `frame_id`, as ROS tools add), `labels.csv` (per image: object, side and
artic's label vector), `objects.jsonl` (each object's spec), `errors.csv` (per image:
axis-position error cm as `artic.evaluation.kinematics.kinematic_errors` defines it,
yaw error deg, configuration error deg, the rotation error in the thesis' metric deg,
hinge side right, whether predict warned and its warnings) and `summary.csv`
(`SUMMARY_COLUMNS`: one row per side present, and "both" when both are or the category
has no hinge side); prints the summary. Same seed, same bytes
(images, labels, objects): object i is drawn from `default_rng([seed, i, STREAM])`, its
sensor noise from `[seed, i, STREAM, 1]`.

**Labels: artic's convention exactly** (src/artic/objects/labels.py, docs/objects.md):
the label vector is `artic.objects.labels.image_labels(spec.label_spec(), obj, spec.q())`,
with an artic `ObjectSpec` holding these numbers:
- pose x, y, z: the centre of the bottom of the object (what it stands on: feet, legs
  or plinth included) in the camera frame; yaw about +z, 0 = front facing the camera;
- depth: the body's (carcass's) extent along its x, the door in front of it not counted;
  width: the body's extent along y (a cabinet's top-slab overhang not counted); height:
  the whole object's, floor to top (feet, plinth or legs and top slab included);
- chirality +1: hinge on the object's -y edge (the camera's right at yaw 0), axis +z;
  -1: hinge on +y, axis -z; q >= 0 swings the free edge towards the camera;
- the joint origin: the hinge edge's bottom point on the body's front plane (the door's
  back face), as artic's `vertical_door`; the part origin: the centre of the door link's
  bounding box in the joint frame (handles are their own link, as artic's are).
- the other categories, as artic's builders (docs/objects.md, "Structure"): the
  two-door cabinet's joint 0 is the -y door hinged at its -y edge (axis +z), joint 1 the
  +y door hinged at its +y edge (axis -z); the refrigerator's joint 0 the lower (fridge)
  door, joint 1 the upper (freezer) door, both hinged on the chirality side, origins at
  each door's hinge-edge bottom point; the toaster's door is hinged at its bottom edge,
  axis (0, -1, 0), the origin the centre of that edge on the body's front plane, the
  control panel on the -y side; the drawer's joint is prismatic along (-1, 0, 0), q in
  metres, the origin the centre of the drawer front on the body's front plane (for an
  overlay front, which stands in front of the carcass, its back face: the front plane, as
  for doors, the front not counted in the depth).
`from_artic_spec` builds this file's object from an artic spec of any of the six
categories with no extra details; the tests check that its labels equal those of artic's
builder to 1e-6.

How the objects differ from the training generator (`artic.objects.categories`,
conf/common/category/<category>.yaml):

- microwave sizes. Training: independent uniforms over Table A.1 (depth 0.25-0.56,
  width 0.40-0.76, height 0.22-0.45 m). Here: width 0.40 + 0.36 Beta(2, 3) (most near
  0.5 m, as sold), height = width x U(0.52, 0.66), depth = width x U(0.70, 0.90), each
  clipped to Table A.1's range.
- microwave body. Training: a 2 cm shell open across the front, a flat control-panel plate
  (1/4 of the width). Here: 6-12 mm sheet walls round a cavity behind the door only; a
  solid electronics block behind the control panel (20-30 % of the width); four feet
  8-20 mm tall; the panel carries a display bump (90 %) and a keypad of 3-5 rows of 3
  buttons (85 %), each standing 2-4 mm proud.
- microwave door. Training: a flat 2 cm slab with a bar handle on posts. Here: 3-4.5 cm
  thick, 0-6 mm short of the body's top and bottom, a window panel recessed 6-15 mm in a
  frame (85 %), a grip recess in the free-edge stile (80 %; otherwise a push-button door,
  no grip at all), never a bar handle.
- cabinet sizes. Training: Table A.1 halved. Here: Table A.1 (`--sizes table_a1`) or
  its half (`generator`), uniform; the height is the overall height.
- cabinet construction. Training: a 2 cm shell on the floor, the door the whole front.
  Here: 16-20 mm carcass with 0-2 shelves; a plinth recessed 3-6 cm (45 %), four legs
  (35 %) or neither (wall-hung, 20 %), 6-15 cm tall (half for generator sizes); a top
  slab 18-30 mm thick overhanging 0-30 mm; an overlay door 16-22 mm thick with 3-6 mm
  gaps all round, flat or panelled (a frame round a panel recessed 5-10 mm, 50 %); a knob
  (box or 16-sided cylinder, 50 %) or a bar on two posts, 4-6 cm from the free edge.
- two-door cabinet (cabinet2). Training: a 2 cm shell, two flat doors 2 mm apart
  covering the whole front, sizes uniform from the generator's smallest to Table A.1's
  largest (28-64 x 30-140 x 30-140 cm). Here: sizes and construction as the cabinet's
  above (`--sizes`; carcass, shelves, plinth, legs or neither, top slab), two overlay
  doors with 3-6 mm gaps round them and 3-8 mm between them, flat or panelled, each with
  the same knob or bar 4-6 cm from its free (middle) edge; each door's q drawn on its own.
- toaster (oven). Training: a 2 cm shell, a flat control-panel plate (1/4 of the width)
  on the -y side, a flat 2 cm door with a bar handle near its top, on the floor. Here:
  width 0.40 + 0.20 Beta(2, 2), height = width x U(0.5, 0.8), depth = width x
  U(0.6, 0.85), clipped to Table A.1 (20-50 x 40-60 x 20-50 cm); 6-12 mm sheet walls
  round the cavity, a solid electronics block behind a control panel of 18-32 % of the
  width carrying 1-3 round knobs standing 1.5-2.5 cm proud; 0-6 vent slots through the
  roof; four feet 10-25 mm tall; the door 2-3.5 cm thick, 0-8 mm short of the body's top
  and bottom, a window recessed 4-10 mm in a frame (80 %), and a horizontal bar on posts
  of 50-85 % of the door's width (70 %) or a lip along its top edge.
- drawer. Training: a 2 cm shell, the drawer's 2 cm front flush inside the opening with
  2 mm clearance, a bar handle centred, on the floor. Here: width 0.30 + 0.46 Beta(2,
  2.5), height (overall) = width x U(0.35, 0.6) clipped to 14-30 cm, depth 0.45 + 0.15
  Beta(2.5, 1.5) (Table A.1: 45-60 x 30-76 x 10-30 cm); 16-20 mm carcass; a top slab
  16-30 mm overhanging 0-20 mm (60 %); a plinth or four feet 2-6 cm (60 %, when the
  height leaves a 10 cm carcass); an overlay front 16-22 mm thick covering the carcass
  but a 1-4 mm reveal (75 %) or a front inside the opening; a drawer box of 12-16 mm
  walls 3-8 mm clear of the carcass, its sides 1-3 cm lower than the front, 0-3 cm short
  of the back; a knob (box or round), a bar of 10-30 cm, or (overlay fronts) a finger
  grip recessed along the front's top edge.
- refrigerator. Training: a 2 cm shell, two flat 2 cm doors (the freezer 1/3 of the
  height) with bar handles at mid-height, on the floor. Here: width 0.6 + 0.3 Beta(2, 2),
  depth = width x U(0.95, 1.15) clipped to 60-80 cm, height 0.82 + 0.06 Beta(2, 2)
  (Table A.1); 3-5 cm walls; a kick plate 4-8 cm tall recessed 4-8 cm (50 %), four feet
  1-3 cm (40 %) or neither; a hinge cover 1.5-3 cm tall on the top's front hinge corner
  (60 %; the height counts it); doors 5-7 cm thick with a gasket band behind them, 2-5 mm
  gaps round and 4-10 mm between them, the freezer 25-40 % of the carcass height;
  vertical bars 25-70 % of each door's height near the fridge door's top and the freezer
  door's bottom (75 %) or a grip recessed in each door's free edge. Each door's q on its
  own.
- hinge side. Training: the microwave's, the cabinet's and the refrigerator's [-1, 1]
  drawn; the others [1]. Here: `--sides` (microwave, cabinet, refrigerator), else 1.
- camera and placement. Training: `thesis_sim` (192x108, f = 105.4 px) or
  `kinect_v1_128`, positions uniform over Table A.2. Here: 640x480, fx = fy = 525,
  cx = 319.5, cy = 239.5 (the issue's camera, artic's camera convention), so `predict`
  reprojects every image into the model's camera; the object at a distance from the
  nearest at which the bounding box of the whole object at its configuration (open door
  included) projects inside the image with `MARGIN_PX` to spare, to `DISTANCE_SPAN`
  beyond it, then y and z uniform over the positions that keep it inside. No support
  plane (as in training). One image per object.
- configuration U(0, pi/2) (Table A.2; the drawer's U(0, 0.4) m; each door of the
  two-door categories its own) and yaw U(-pi/4, pi/4), as in training.
- sensor noise. Training: conf/common/noise/kinect.yaml (lateral 0.5 px, axial
  sigma 1.2 mm + 1.9 mm/m^2 (z - 0.4)^2, edge dropout 0.5, dropout 0.005). Here:
  `NOISE`: lateral 0.8 px, axial 2 mm + 2.5 mm/m^2 (z - 0.4)^2, edge dropout 0.7,
  dropout 0.01 (a noisier sensor), at the 640x480 image's focal length.

Prediction is `artic.kinematics.predict.predict_image` (what `artic predict` runs: the
camera file read with its extra field, the reprojection, the domain warnings) with the
CLI's default estimator (most-likely). `warned` in errors.csv is 1 when predict warned
about the estimate (`ESTIMATE_WARNINGS`: outside the training ranges, or the mixture
split between hinge sides); the notes every image of this bench gets (the camera file's
ignored `frame_id`, the reprojection into the training camera, a smoke model) are in
`warnings` but not counted.
"""

from __future__ import annotations

from artic.reproducibility import pin_numerics

pin_numerics()  # before NumPy loads, as the `artic` command does

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import logging  # noqa: E402
import math  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, Final, Literal, NamedTuple, NoReturn  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402
from pydantic import BaseModel, ConfigDict, Field, model_validator  # noqa: E402

from artic.errors import InputError  # noqa: E402
from artic.geometry.camera import CameraIntrinsics  # noqa: E402
from artic.geometry.transforms import make_transform, transform_points  # noqa: E402
from artic.objects.model import ArticulatedObject, Joint, Link, TriangleMesh  # noqa: E402
from artic.objects.parts import Box, Interval, mass_properties, union_mesh  # noqa: E402
from artic.objects.spec import ObjectSpec, PartsConfig, Pose  # noqa: E402
from artic.render.noise import SensorNoiseConfig  # noqa: E402

Category = Literal["microwave", "cabinet", "cabinet2", "toaster", "drawer", "refrigerator"]
Sides = Literal["both", "left", "right"]
Sizes = Literal["table_a1", "generator"]
Builder = Literal["bench", "artic"]
Placement = Literal["frame", "table_a2"]
PLACEMENTS: Final = ("frame", "table_a2")
Support = Literal["none", "plinth", "legs"]
Knob = Literal["knob_box", "knob_round"]

CATEGORIES: Final = ("microwave", "cabinet", "cabinet2", "toaster", "drawer", "refrigerator")
SIDED: Final = ("microwave", "cabinet", "refrigerator")
"""The categories with a hinge side to draw (training chirality [-1, 1]): `--sides`."""
TWO_DOORS: Final = ("cabinet2", "refrigerator")  # dof 2: a q per door
STREAM: Final = 0x24D  # object i: default_rng([seed, i, STREAM]); its noise: [..., 1]
CAMERA: Final = CameraIntrinsics(fx=525.0, fy=525.0, cx=319.5, cy=239.5, width=640, height=480)
FRAME_ID: Final = "bench_depth_camera"
"""The extra field of camera.json (camera files of other tools carry a frame name)."""
NOISE: Final = SensorNoiseConfig(
    lateral_sigma_px=0.8, axial_a=0.002, axial_b=0.0025, edge_dropout=0.7, dropout=0.01
)
"""This bench's sensor noise; the training data's is conf/common/noise/kinect.yaml."""
MARGIN_PX: Final = 8.0  # the object's bounding box stays this far inside the image
DISTANCE_SPAN: Final = 0.8  # m: x from the nearest distance that fits to this beyond it
MIN_DEPTH: Final = 0.5  # m: nearest point of the object (the sensor sees from 0.4 m)
CONFIGURATION: Final = (0.0, math.pi / 2)  # Table A.2
TRAVEL: Final = (0.0, 0.4)  # m, the drawer's configuration, Table A.2
YAW: Final = (-math.pi / 4, math.pi / 4)  # Table A.2
ESTIMATOR: Final = "most-likely"  # `artic predict`'s default
ESTIMATE_WARNINGS: Final = ("the estimate lies outside", "the mixture is split")
"""Prefixes of predict's warnings about the estimate (kinematics/predict.py)."""
CABINET_SIZES: Final[dict[str, dict[str, tuple[float, float]]]] = {
    "table_a1": {"depth": (0.56, 0.64), "width": (0.6, 1.4), "height": (0.6, 1.4)},
    "generator": {"depth": (0.28, 0.32), "width": (0.3, 0.7), "height": (0.3, 0.7)},
}
MICROWAVE_SIZES: Final = {"depth": (0.25, 0.56), "width": (0.40, 0.76), "height": (0.22, 0.45)}
SIZES: Final[dict[str, dict[str, tuple[float, float]]]] = {
    "microwave": MICROWAVE_SIZES,
    "toaster": {"depth": (0.2, 0.5), "width": (0.4, 0.6), "height": (0.2, 0.5)},
    "drawer": {"depth": (0.45, 0.6), "width": (0.3, 0.76), "height": (0.1, 0.3)},
    "refrigerator": {"depth": (0.6, 0.8), "width": (0.6, 0.9), "height": (0.82, 0.88)},
}
"""Table A.1's sizes (conf/common/category/<category>.yaml) of the categories with one
range; the cabinets' are `CABINET_SIZES`."""
SUMMARY_COLUMNS: Final = (
    "category",
    "sides",
    "sizes",
    "placement",
    "estimator",
    "images",
    "axis_position_cm_median",
    "yaw_deg_median",
    "configuration_deg_median",
    "hinge_side_right_pct",
    "warned_pct",
    "withheld_axis_position_cm_median",
    "ratio",
)
ERROR_COLUMNS: Final = (
    "image",
    "object_id",
    "side",
    "chirality",
    "chirality_estimate",
    "axis_position_cm",
    "yaw_deg",
    "configuration_deg",
    "rotation_thesis_deg",
    "hinge_side_right",
    "warned",
    "warnings",
)


class _Frozen(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


# ---------------------------------------------------------------------------- the spec


class MicrowaveBuild(_Frozen):
    """How one microwave is made, metres (0 or False: the detail is absent)."""

    kind: Literal["microwave"] = "microwave"
    wall: float = Field(gt=0, description="sheet walls round the cavity")
    door_thickness: float = Field(gt=0, description="door slab")
    gap: float = Field(ge=0, description="between the door's free edge and the panel")
    door_margin: float = Field(ge=0, description="door short of the body's bottom and top")
    panel_fraction: float = Field(gt=0, lt=1, description="control panel share of the width")
    foot_height: float = Field(ge=0, description="feet under the body; 0: none")
    foot_side: float = Field(gt=0, description="square feet's side")
    window: bool = Field(description="a window panel recessed in a frame")
    hinge_stile: float = Field(ge=0, description="window frame at the hinge edge")
    free_stile: float = Field(ge=0, description="window frame at the free edge")
    rail: float = Field(ge=0, description="window frame at top and bottom")
    window_recess: float = Field(ge=0, description="window panel behind the door's face")
    grip: bool = Field(description="a grip recess in the free-edge stile")
    grip_width: float = Field(ge=0, description="grip recess along the door's width")
    grip_height: float = Field(ge=0, le=1, description="grip recess, share of door height")
    grip_depth: float = Field(ge=0, description="grip recess behind the door's face")
    display: bool = Field(description="a display bump on the control panel")
    button_rows: int = Field(ge=0, le=6, description="keypad rows of 3 buttons; 0: none")
    relief: float = Field(ge=0, description="how far display and buttons stand proud")


class CabinetBuild(_Frozen):
    """How one cabinet is made, metres (0: the detail is absent)."""

    kind: Literal["cabinet"] = "cabinet"
    wall: float = Field(gt=0, description="carcass panels")
    door_thickness: float = Field(gt=0, description="overlay door")
    gap: float = Field(ge=0, description="round the door")
    support: Literal["none", "plinth", "legs"]
    support_height: float = Field(ge=0, description="plinth or legs; 0 with none")
    support_inset: float = Field(ge=0, description="plinth recess behind the front, or leg side")
    top: float = Field(ge=0, description="top slab thickness; 0: none")
    overhang: float = Field(ge=0, description="top slab overhang, front and sides")
    shelves: int = Field(ge=0, le=4)
    panelled: bool = Field(description="door: a frame round a recessed panel")
    frame: float = Field(ge=0, description="panelled door's frame width")
    recess: float = Field(ge=0, description="panelled door's panel behind the face")
    handle: Literal["none", "knob_box", "knob_round", "bar"]
    handle_size: float = Field(gt=0, description="knob side or diameter; bar length")
    handle_inset: float = Field(gt=0, description="handle centre to the free edge")
    centre_gap: float | None = Field(
        default=None, ge=0, description="two-door cabinet: between its doors; None: one door"
    )


class ToasterBuild(_Frozen):
    """How one toaster oven is made, metres (0 or False: the detail is absent)."""

    kind: Literal["toaster"] = "toaster"
    wall: float = Field(gt=0, description="sheet walls round the cavity")
    door_thickness: float = Field(gt=0, description="door slab")
    gap: float = Field(ge=0, description="between the door's side and the control panel")
    door_margin: float = Field(ge=0, description="door short of the body's bottom and top")
    panel_fraction: float = Field(gt=0, lt=1, description="control panel share of the width")
    foot_height: float = Field(ge=0, description="feet under the body; 0: none")
    foot_side: float = Field(gt=0, description="square feet's side")
    window: bool = Field(description="a window panel recessed in a frame")
    stile: float = Field(ge=0, description="window frame at the door's sides")
    rail: float = Field(ge=0, description="window frame at top and bottom")
    window_recess: float = Field(ge=0, description="window panel behind the door's face")
    handle: Literal["bar", "lip"] = Field(description="bar on posts, or a lip along the top")
    handle_length: float = Field(gt=0, description="bar or lip along the door's width")
    handle_inset: float = Field(ge=0, description="bar centre below the door's top edge")
    knobs: int = Field(ge=0, le=3, description="round knobs on the control panel")
    knob_size: float = Field(gt=0, description="knob diameter (capped to fit the panel)")
    knob_depth: float = Field(gt=0, description="how far the knobs stand proud")
    vents: int = Field(ge=0, le=8, description="slots through the roof; 0: none")
    vent_width: float = Field(gt=0, description="slot width along x")


class DrawerBuild(_Frozen):
    """How one drawer unit is made, metres (0 or False: the detail is absent)."""

    kind: Literal["drawer"] = "drawer"
    wall: float = Field(gt=0, description="carcass panels")
    front_thickness: float = Field(gt=0, description="drawer front")
    overlay: bool = Field(description="front in front of the carcass, else inside the opening")
    reveal: float = Field(ge=0, description="overlay: carcass edge left showing round it")
    clearance: float = Field(ge=0, description="drawer box to the carcass walls")
    box_wall: float = Field(gt=0, description="drawer box sides, back and bottom")
    box_short: float = Field(ge=0, description="box back short of the carcass back")
    side_drop: float = Field(ge=0, description="box sides and back lower than the front")
    support: Support
    support_height: float = Field(ge=0, description="plinth or feet; 0 with none")
    support_inset: float = Field(ge=0, description="plinth recess behind the front, or foot side")
    top: float = Field(ge=0, description="top slab thickness; 0: none")
    overhang: float = Field(ge=0, description="top slab overhang, front and sides")
    handle: Literal["none", "knob_box", "knob_round", "bar", "grip"]
    handle_size: float = Field(gt=0, description="knob side or diameter; bar length")
    grip_height: float = Field(ge=0, description="grip: recess down from the front's top")
    grip_depth: float = Field(ge=0, description="grip: recess behind the front's face")


class RefrigeratorBuild(_Frozen):
    """How one refrigerator is made, metres (0: the detail is absent)."""

    kind: Literal["refrigerator"] = "refrigerator"
    wall: float = Field(gt=0, description="carcass panels")
    door_thickness: float = Field(gt=0, description="doors, gasket band included")
    gap: float = Field(ge=0, description="round the doors")
    centre_gap: float = Field(ge=0, description="between the fridge and freezer doors")
    freezer_fraction: float = Field(gt=0, lt=1, description="upper door's share of the carcass")
    support: Support = Field(description="plinth: a kick plate; legs: four feet")
    support_height: float = Field(ge=0, description="kick plate or feet; 0 with none")
    support_inset: float = Field(ge=0, description="kick plate recess, or foot side")
    hinge_cover: float = Field(ge=0, description="cover on the top's hinge corner; 0: none")
    hinge_cover_width: float = Field(gt=0, description="the cover along y")
    gasket: float = Field(ge=0, description="gasket band inset from the door's edges; 0: none")
    gasket_depth: float = Field(ge=0, description="gasket band's share of the thickness")
    handle: Literal["bar", "recess"] = Field(description="bars on posts, or grips recessed")
    handle_fraction: tuple[float, float] = Field(description="bar or grip, share of door height")
    handle_inset: float = Field(gt=0, description="bar centre to the free edge")
    recess_width: float = Field(gt=0, description="grip recess along the door's width")
    recess_depth: float = Field(gt=0, description="grip recess behind the door's face")


AnyBuild = MicrowaveBuild | CabinetBuild | ToasterBuild | DrawerBuild | RefrigeratorBuild


class BenchSpec(_Frozen):
    """One object and its image: the numbers the labels are made of (module docstring,
    "Labels"), the configuration q it is rendered at and how it is built."""

    category: Category
    index: int = Field(ge=0)
    depth: float = Field(gt=0, description="body extent along x, m")
    width: float = Field(gt=0, description="body extent along y, m")
    height: float = Field(gt=0, description="whole object along z, m")
    chirality: Literal[-1, 1]
    pose: Pose
    configuration: float = Field(description="joint 0's q in the image: rad, or m (drawer)")
    configuration_1: float | None = Field(
        default=None, description="joint 1's q, rad: the two-door categories only"
    )
    upper: float = Field(gt=0, description="the joints' upper limit, rad or m")
    build: AnyBuild = Field(discriminator="kind")

    @model_validator(mode="after")
    def _one_q_per_joint(self) -> BenchSpec:
        if (self.configuration_1 is not None) != (self.category in TWO_DOORS):
            raise ValueError(f"configuration_1: given iff the category has two doors ({self})")
        return self

    @property
    def dof(self) -> int:
        """Movable joints: 2 for the two-door categories, else 1."""
        return 2 if self.category in TWO_DOORS else 1

    def q(self) -> NDArray[np.float64]:
        """(dof,) the configuration the image shows, joint order."""
        extra = [] if self.configuration_1 is None else [self.configuration_1]
        return np.array([self.configuration, *extra], dtype=np.float64)

    def label_spec(self) -> ObjectSpec:
        """artic's `ObjectSpec` of these numbers, for `image_labels`."""
        return ObjectSpec(
            category=self.category,
            index=self.index,
            dof=self.dof,
            joint_type="prismatic" if self.category == "drawer" else "revolute",
            depth=self.depth,
            width=self.width,
            height=self.height,
            chirality=self.chirality,
            pose=self.pose,
            joint_limits=((0.0, self.upper),) * self.dof,
            parts=PartsConfig(),
        )


def _detail_free(spec: ObjectSpec) -> AnyBuild:
    """This file's construction of artic's `spec` with no extra details (`from_artic_spec`)."""
    p = spec.parts
    if spec.category == "microwave":
        return MicrowaveBuild(
            wall=p.panel_thickness, door_thickness=p.door_thickness, gap=p.gap,
            door_margin=0.0, panel_fraction=p.control_panel_fraction, foot_height=0.0,
            foot_side=0.03, window=False, hinge_stile=0.0, free_stile=0.0, rail=0.0,
            window_recess=0.0, grip=False, grip_width=0.0, grip_height=0.0, grip_depth=0.0,
            display=False, button_rows=0, relief=0.0,
        )  # fmt: skip
    if spec.category in ("cabinet", "cabinet2"):
        return CabinetBuild(
            wall=p.panel_thickness, door_thickness=p.door_thickness, gap=0.0, support="none",
            support_height=0.0, support_inset=0.0, top=0.0, overhang=0.0, shelves=0,
            panelled=False, frame=0.0, recess=0.0, handle="bar", handle_size=0.2,
            handle_inset=p.handle_inset,
            centre_gap=p.gap if spec.category == "cabinet2" else None,
        )  # fmt: skip
    if spec.category == "toaster":
        return ToasterBuild(
            wall=p.panel_thickness, door_thickness=p.door_thickness, gap=p.gap,
            door_margin=0.0, panel_fraction=p.control_panel_fraction, foot_height=0.0,
            foot_side=0.03, window=False, stile=0.0, rail=0.0, window_recess=0.0,
            handle="bar", handle_length=p.handle_length, handle_inset=p.handle_inset,
            knobs=0, knob_size=0.03, knob_depth=0.02, vents=0, vent_width=0.01,
        )  # fmt: skip
    if spec.category == "drawer":
        return DrawerBuild(
            wall=p.panel_thickness, front_thickness=p.door_thickness, overlay=False,
            reveal=0.0, clearance=p.gap, box_wall=p.panel_thickness, box_short=0.0,
            side_drop=0.0, support="none", support_height=0.0, support_inset=0.0, top=0.0,
            overhang=0.0, handle="bar", handle_size=p.handle_length, grip_height=0.0,
            grip_depth=0.0,
        )  # fmt: skip
    if spec.category == "refrigerator":
        return RefrigeratorBuild(
            wall=p.panel_thickness, door_thickness=p.door_thickness, gap=0.0,
            centre_gap=p.gap, freezer_fraction=p.freezer_fraction, support="none",
            support_height=0.0, support_inset=0.0, hinge_cover=0.0, hinge_cover_width=0.08,
            gasket=0.0, gasket_depth=0.0, handle="bar", handle_fraction=(0.5, 0.5),
            handle_inset=p.handle_inset, recess_width=0.03, recess_depth=0.01,
        )  # fmt: skip
    raise InputError(f"category: {spec.category!r}; expected one of {', '.join(CATEGORIES)}")


def from_artic_spec(spec: ObjectSpec, configuration: float | Sequence[float]) -> BenchSpec:
    """This file's object with the numbers of artic's `spec` (any of the six categories)
    and no extra details: its moving parts where artic's builder puts them (for the
    convention test). `configuration`: q, or one per joint."""
    q = [float(configuration)] if isinstance(configuration, int | float) else list(configuration)
    if len(q) != spec.dof:
        raise ValueError(f"configuration: {spec.dof} values expected, got {q}")
    build = _detail_free(spec)
    return BenchSpec(
        category=spec.category,  # a name of CATEGORIES: checked by _detail_free
        index=spec.index,
        depth=spec.depth,
        width=spec.width,
        height=spec.height,
        chirality=spec.chirality,
        pose=spec.pose,
        configuration=q[0],
        configuration_1=q[1] if len(q) > 1 else None,
        upper=spec.joint_limits[0][1],
        build=build,
    )


# ---------------------------------------------------------------------------- sampling


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _clip(value: float, bounds: tuple[float, float]) -> float:
    return float(min(max(value, bounds[0]), bounds[1]))


def sample_microwave(rng: np.random.Generator, index: int, chirality: Literal[-1, 1]) -> BenchSpec:
    """A microwave's sizes and construction (pose: yaw only; `place` sets x, y, z)."""
    width = 0.40 + 0.36 * float(rng.beta(2.0, 3.0))
    height = _clip(width * _u(rng, 0.52, 0.66), MICROWAVE_SIZES["height"])
    depth = _clip(width * _u(rng, 0.70, 0.90), MICROWAVE_SIZES["depth"])
    feet = _u(rng, 0.008, 0.02)
    panel = _u(rng, 0.20, 0.30)
    door_w = width * (1 - panel)
    door_h = height - feet
    window = bool(rng.random() < 0.85)
    grip = bool(rng.random() < 0.8)
    build = MicrowaveBuild(
        wall=_u(rng, 0.006, 0.012),
        door_thickness=_u(rng, 0.03, 0.045),
        gap=_u(rng, 0.002, 0.004),
        door_margin=_u(rng, 0.0, 0.006),
        panel_fraction=panel,
        foot_height=feet,
        foot_side=_u(rng, 0.02, 0.04),
        window=window,
        hinge_stile=door_w * _u(rng, 0.08, 0.14),
        free_stile=door_w * _u(rng, 0.14, 0.22),
        rail=door_h * _u(rng, 0.12, 0.2),
        window_recess=_u(rng, 0.006, 0.015),
        grip=grip,
        grip_width=door_w * _u(rng, 0.05, 0.08),
        grip_height=_u(rng, 0.3, 0.6),
        grip_depth=_u(rng, 0.01, 0.02),
        display=bool(rng.random() < 0.9),
        button_rows=int(rng.integers(3, 6)) if rng.random() < 0.85 else 0,
        relief=_u(rng, 0.002, 0.004),
    )
    return BenchSpec(
        category="microwave",
        index=index,
        depth=depth,
        width=width,
        height=height,
        chirality=chirality,
        pose=Pose(x=0.0, y=0.0, z=0.0, yaw=_u(rng, *YAW)),
        configuration=_u(rng, *CONFIGURATION),
        upper=CONFIGURATION[1],
        build=build,
    )


def sample_cabinet(
    rng: np.random.Generator, index: int, chirality: Literal[-1, 1], sizes: Sizes
) -> BenchSpec:
    """A cabinet's sizes (`CABINET_SIZES[sizes]`) and construction (pose: yaw only)."""
    ranges = CABINET_SIZES[sizes]
    depth, width, height = (_u(rng, *ranges[k]) for k in ("depth", "width", "height"))
    scale = 1.0 if sizes == "table_a1" else 0.5
    pick = float(rng.random())
    support: Literal["none", "plinth", "legs"] = (
        "plinth" if pick < 0.45 else "legs" if pick < 0.8 else "none"
    )
    support_height = 0.0 if support == "none" else scale * _u(rng, 0.06, 0.15)
    inset = _u(rng, 0.03, 0.06) if support == "plinth" else _u(rng, 0.03, 0.05)
    handle = ("knob_box", "knob_round", "bar", "bar")[int(rng.integers(0, 4))]
    build = CabinetBuild(
        wall=_u(rng, 0.016, 0.02),
        door_thickness=_u(rng, 0.016, 0.022),
        gap=_u(rng, 0.003, 0.006),
        support=support,
        support_height=support_height,
        support_inset=inset,
        top=_u(rng, 0.018, 0.03),
        overhang=_u(rng, 0.0, 0.03),
        shelves=int(rng.integers(0, 3)),
        panelled=bool(rng.random() < 0.5),
        frame=_u(rng, 0.05, 0.08) * scale,
        recess=_u(rng, 0.005, 0.01),
        handle=handle,
        handle_size=_u(rng, 0.1, 0.3) * scale if handle == "bar" else _u(rng, 0.02, 0.035),
        handle_inset=_u(rng, 0.04, 0.06),
    )
    return BenchSpec(
        category="cabinet",
        index=index,
        depth=depth,
        width=width,
        height=height,
        chirality=chirality,
        pose=Pose(x=0.0, y=0.0, z=0.0, yaw=_u(rng, *YAW)),
        configuration=_u(rng, *CONFIGURATION),
        upper=CONFIGURATION[1],
        build=build,
    )


def sample_cabinet2(rng: np.random.Generator, index: int, sizes: Sizes) -> BenchSpec:
    """A two-door cabinet: a cabinet's sizes and construction (`sample_cabinet`, its
    numbers first so they follow the same draws), then the gap between the doors and the
    second door's q."""
    one = sample_cabinet(rng, index, 1, sizes)
    assert isinstance(one.build, CabinetBuild)
    build = one.build.model_copy(update={"centre_gap": _u(rng, 0.003, 0.008)})
    return BenchSpec(
        **{**one.model_dump(exclude={"build", "configuration_1"}), "category": "cabinet2"},
        configuration_1=_u(rng, *CONFIGURATION),
        build=build,
    )


def _yaw_pose(rng: np.random.Generator) -> Pose:
    return Pose(x=0.0, y=0.0, z=0.0, yaw=_u(rng, *YAW))


def sample_toaster(rng: np.random.Generator, index: int) -> BenchSpec:
    """A toaster oven's sizes and construction (pose: yaw only; `place` sets x, y, z)."""
    ranges = SIZES["toaster"]
    width = 0.40 + 0.20 * float(rng.beta(2.0, 2.0))
    height = _clip(width * _u(rng, 0.5, 0.8), ranges["height"])
    depth = _clip(width * _u(rng, 0.6, 0.85), ranges["depth"])
    feet = _u(rng, 0.01, 0.025)
    panel = _u(rng, 0.18, 0.32)
    gap = _u(rng, 0.002, 0.005)
    door_w, door_h = width * (1 - panel) - gap, height - feet
    build = ToasterBuild(
        wall=_u(rng, 0.006, 0.012),
        door_thickness=_u(rng, 0.02, 0.035),
        gap=gap,
        door_margin=_u(rng, 0.0, 0.008),
        panel_fraction=panel,
        foot_height=feet,
        foot_side=_u(rng, 0.02, 0.035),
        window=bool(rng.random() < 0.8),
        stile=door_w * _u(rng, 0.08, 0.14),
        rail=door_h * _u(rng, 0.15, 0.25),
        window_recess=_u(rng, 0.004, 0.01),
        handle="bar" if rng.random() < 0.7 else "lip",
        handle_length=door_w * _u(rng, 0.5, 0.85),
        handle_inset=door_h * _u(rng, 0.06, 0.1),
        knobs=int(rng.integers(1, 4)),
        knob_size=_u(rng, 0.025, 0.04),
        knob_depth=_u(rng, 0.015, 0.025),
        vents=int(rng.integers(0, 7)),
        vent_width=_u(rng, 0.006, 0.012),
    )
    return BenchSpec(
        category="toaster",
        index=index,
        depth=depth,
        width=width,
        height=height,
        chirality=1,
        pose=_yaw_pose(rng),
        configuration=_u(rng, *CONFIGURATION),
        upper=CONFIGURATION[1],
        build=build,
    )


def sample_drawer(rng: np.random.Generator, index: int) -> BenchSpec:
    """A drawer unit's sizes and construction (pose: yaw only). The support is dropped
    when the height leaves less than a 10 cm carcass under the top slab."""
    width = 0.30 + 0.46 * float(rng.beta(2.0, 2.5))
    height = _clip(width * _u(rng, 0.35, 0.6), (0.14, SIZES["drawer"]["height"][1]))
    depth = 0.45 + 0.15 * float(rng.beta(2.5, 1.5))
    overlay = bool(rng.random() < 0.75)
    top = _u(rng, 0.016, 0.03) if rng.random() < 0.6 else 0.0
    pick = float(rng.random())
    support: Support = "plinth" if pick < 0.35 else "legs" if pick < 0.6 else "none"
    support_height = min(_u(rng, 0.02, 0.06), max(0.0, height - top - 0.1))
    if support == "none" or support_height < 0.01:
        support, support_height = "none", 0.0
    handles = ("knob_box", "knob_round", "bar", "bar", "grip") if overlay else (
        "knob_box", "knob_round", "bar")  # fmt: skip
    handle = handles[int(rng.integers(0, len(handles)))]
    front = _u(rng, 0.016, 0.022)
    build = DrawerBuild(
        wall=_u(rng, 0.016, 0.02),
        front_thickness=front,
        overlay=overlay,
        reveal=_u(rng, 0.001, 0.004) if overlay else 0.0,
        clearance=_u(rng, 0.003, 0.008),
        box_wall=_u(rng, 0.012, 0.016),
        box_short=_u(rng, 0.0, 0.03),
        side_drop=_u(rng, 0.01, 0.03),
        support=support,
        support_height=support_height,
        support_inset=_u(rng, 0.02, 0.05) if support == "plinth" else _u(rng, 0.025, 0.04),
        top=top,
        overhang=_u(rng, 0.0, 0.02) if top > 0 else 0.0,
        handle=handle,
        handle_size=_u(rng, 0.1, 0.3) if handle == "bar" else _u(rng, 0.02, 0.035),
        grip_height=_u(rng, 0.02, 0.035) if handle == "grip" else 0.0,
        grip_depth=front * _u(rng, 0.5, 0.75) if handle == "grip" else 0.0,
    )
    return BenchSpec(
        category="drawer",
        index=index,
        depth=depth,
        width=width,
        height=height,
        chirality=1,
        pose=_yaw_pose(rng),
        configuration=_u(rng, *TRAVEL),
        upper=TRAVEL[1],
        build=build,
    )


def sample_refrigerator(
    rng: np.random.Generator, index: int, chirality: Literal[-1, 1]
) -> BenchSpec:
    """A refrigerator's sizes and construction (pose: yaw only), a q per door."""
    ranges = SIZES["refrigerator"]
    width = 0.6 + 0.3 * float(rng.beta(2.0, 2.0))
    depth = _clip(width * _u(rng, 0.95, 1.15), ranges["depth"])
    height = 0.82 + 0.06 * float(rng.beta(2.0, 2.0))
    pick = float(rng.random())
    support: Support = "plinth" if pick < 0.5 else "legs" if pick < 0.9 else "none"
    heights = {"plinth": (0.04, 0.08), "legs": (0.01, 0.03), "none": (0.0, 0.0)}[support]
    build = RefrigeratorBuild(
        wall=_u(rng, 0.03, 0.05),
        door_thickness=_u(rng, 0.05, 0.07),
        gap=_u(rng, 0.002, 0.005),
        centre_gap=_u(rng, 0.004, 0.01),
        freezer_fraction=_u(rng, 0.25, 0.4),
        support=support,
        support_height=_u(rng, *heights),
        support_inset=_u(rng, 0.04, 0.08) if support == "plinth" else _u(rng, 0.03, 0.05),
        hinge_cover=_u(rng, 0.015, 0.03) if rng.random() < 0.6 else 0.0,
        hinge_cover_width=_u(rng, 0.06, 0.12),
        gasket=_u(rng, 0.01, 0.02),
        gasket_depth=_u(rng, 0.008, 0.015),
        handle="bar" if rng.random() < 0.75 else "recess",
        handle_fraction=(_u(rng, 0.25, 0.7), _u(rng, 0.25, 0.7)),
        handle_inset=_u(rng, 0.04, 0.07),
        recess_width=_u(rng, 0.025, 0.04),
        recess_depth=_u(rng, 0.015, 0.03),
    )
    return BenchSpec(
        category="refrigerator",
        index=index,
        depth=depth,
        width=width,
        height=height,
        chirality=chirality,
        pose=_yaw_pose(rng),
        configuration=_u(rng, *CONFIGURATION),
        configuration_1=_u(rng, *CONFIGURATION),
        upper=CONFIGURATION[1],
        build=build,
    )


# ---------------------------------------------------------------------------- geometry
# Boxes are written for chirality +1 (hinge on -y) and mirrored in y for -1.


def _mirror(box: Box, chirality: int) -> Box:
    if chirality == 1:
        return box
    return Box(box.x, (-box.y[1], -box.y[0]), box.z)


def _link(name: str, role: str, mesh: TriangleMesh, density: float) -> Link:
    return Link(name=name, role=role, mesh=mesh, inertial=mass_properties(mesh, density))


def _join(meshes: Sequence[TriangleMesh]) -> TriangleMesh:
    """One link mesh of closed meshes (vertices stacked, triangles renumbered)."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return TriangleMesh(
        np.concatenate([m.vertices for m in meshes]).astype(np.float64),
        np.concatenate([m.triangles + o for m, o in zip(meshes, offsets, strict=True)]).astype(
            np.int32
        ),
    )


Handle = tuple[TriangleMesh, tuple[float, float, float]]
"""A handle link: its mesh in its own frame and its mount point in the part's frame."""


class _Part(NamedTuple):
    """A moving part: its joint (origin in the body frame, a point on the axis; the axis),
    its boxes in the joint frame and its handle link, if any, in chirality +1 coordinates
    (a vertical door's y from 0 at the hinge to its width). `mirror` -1: reflected in y
    (a door hinged on +y), on top of the object's chirality."""

    role: Literal["door", "drawer"]
    joint_type: Literal["revolute", "prismatic"]
    origin: tuple[float, float, float]
    axis: tuple[float, float, float]
    boxes: list[Box]
    handle: Handle | None
    mirror: int = 1


def _door(origin: tuple[float, float, float], boxes: list[Box], handle: Handle | None) -> _Part:
    """A door on a vertical hinge at `origin` (q > 0 opens its free edge to the camera)."""
    return _Part("door", "revolute", origin, (0.0, 0.0, 1.0), boxes, handle)


def _mirror_mesh(mesh: TriangleMesh, m: int) -> TriangleMesh:
    """`mesh` reflected in y when m = -1, triangles reversed to keep them outward."""
    if m == 1:
        return mesh
    return TriangleMesh(mesh.vertices * np.array([1.0, -1.0, 1.0]), mesh.triangles[:, ::-1])


def _mirror_axis(axis: tuple[float, float, float], joint_type: str, m: int) -> NDArray[np.float64]:
    """The joint axis reflected in y when m = -1: a translation's direction as a vector,
    a rotation's as a pseudovector (its sense flips), so q keeps its opening sense."""
    a = np.array(axis, dtype=np.float64)
    if m == 1:
        return a
    return a * np.array([1.0, -1.0, 1.0]) if joint_type == "prismatic" else a * np.array(
        [-1.0, 1.0, -1.0])  # fmt: skip


def _assemble(
    spec: BenchSpec,
    body: list[Box],
    parts: Sequence[_Part],
    extras: Sequence[TriangleMesh] = (),
) -> ArticulatedObject:
    """body -> <role>_k (joint_k) [-> handle_k (handle_k_fixed)] for each part k, as
    artic's `assemble` orders them; everything mirrored by the chirality. `extras`:
    closed meshes joined to the body's (round knobs)."""
    c = spec.chirality
    body_mesh = union_mesh([_mirror(b, c) for b in body])
    if extras:
        body_mesh = _join([body_mesh, *(_mirror_mesh(e, c) for e in extras)])
    links = [_link("body", "body", body_mesh, 600.0)]
    joints = []
    for k, part in enumerate(parts):
        m = c * part.mirror
        name = f"{part.role}_{k}"
        mesh = union_mesh([_mirror(b, m) for b in part.boxes])
        links.append(_link(name, part.role, mesh, 700.0 if part.role == "drawer" else 500.0))
        joints.append(
            Joint(
                name=f"joint_{k}",
                type=part.joint_type,
                parent="body",
                child=name,
                origin=make_transform(translation=np.array(part.origin) * np.array([1.0, m, 1.0])),
                axis=_mirror_axis(part.axis, part.joint_type, m),
                limits=(0.0, spec.upper),
                effort=50.0,
                velocity=2.0,
                damping=0.1,
                friction=0.05,
            )
        )
        if part.handle is not None:
            handle, (hx, hy, hz) = part.handle
            links.append(_link(f"handle_{k}", "handle", _mirror_mesh(handle, m), 1000.0))
            joints.append(
                Joint(
                    name=f"handle_{k}_fixed",
                    type="fixed",
                    parent=name,
                    child=f"handle_{k}",
                    origin=make_transform(translation=np.array([hx, m * hy, hz])),
                )
            )
    return ArticulatedObject(
        name=f"bench_{spec.category}_{spec.index}",
        links=tuple(links),
        joints=tuple(joints),
        base_pose=spec.pose.matrix(),
    )


def _microwave_door(spec: BenchSpec, b: MicrowaveBuild) -> tuple[float, list[Box]]:
    """The door's y extent from the hinge and its boxes (joint frame, chirality +1)."""
    width = spec.width * (1 - b.panel_fraction) - b.gap
    height = spec.height - b.foot_height - 2 * b.door_margin
    t = b.door_thickness
    face, full = (-t, 0.0), (0.0, height)
    if not b.window and not b.grip:
        return width, [Box(face, (0.0, width), full)]
    hs, fs = (b.hinge_stile, b.free_stile) if b.window else (0.0, max(b.grip_width, 0.02))
    boxes = []
    if hs > 0:
        boxes.append(Box(face, (0.0, hs), full))  # hinge stile
    if b.window:
        middle = (hs, width - fs)
        boxes += [
            Box(face, middle, (0.0, b.rail)),
            Box(face, middle, (height - b.rail, height)),
            Box((-t + b.window_recess, 0.0), middle, (b.rail, height - b.rail)),  # window
        ]
    else:
        boxes.append(Box(face, (0.0, width - fs), full))
    free = (width - fs, width)
    if b.grip:  # a recess open to the free edge, centred on the door's height
        lo = 0.5 * height * (1 - b.grip_height)
        hi = height - lo
        grip_y = (width - b.grip_width, width)
        boxes += [
            Box(face, free, (0.0, lo)),
            Box(face, free, (hi, height)),
            Box((-t + b.grip_depth, 0.0), grip_y, (lo, hi)),
        ]
        if b.grip_width < fs:
            boxes.append(Box(face, (width - fs, width - b.grip_width), (lo, hi)))
    else:
        boxes.append(Box(face, free, full))
    return width, boxes


def build_microwave(spec: BenchSpec) -> ArticulatedObject:
    """A microwave: feet, a sheet-metal cavity behind the door, an electronics block
    behind the control panel (display, keypad) on the free-edge side; the door hinged
    on the chirality side (module docstring)."""
    b = spec.build
    assert isinstance(b, MicrowaveBuild)
    d, w, t = spec.depth, spec.width, b.wall
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    z0, z1 = b.foot_height, spec.height
    panel = b.panel_fraction * w
    y_block = y1 - panel - b.gap  # the electronics block's side facing the cavity
    body = [
        Box((x1 - t, x1), (y0, y1), (z0, z1)),  # back
        Box((x0, x1 - t), (y0, y0 + t), (z0, z1)),  # hinge-side wall
        Box((x0, x1 - t), (y0 + t, y_block), (z0, z0 + t)),  # floor
        Box((x0, x1 - t), (y0 + t, y_block), (z1 - t, z1)),  # roof
        Box((x0, x1 - t), (y_block, y1), (z0, z1)),  # electronics block
        Box((x0 - b.door_thickness, x0), (y1 - panel, y1), (z0, z1)),  # control panel
    ]
    if b.foot_height > 0:
        s, inset = b.foot_side, 0.03
        for fx in ((x0 + inset, x0 + inset + s), (x1 - inset - s, x1 - inset)):
            for fy in ((y0 + inset, y0 + inset + s), (y1 - inset - s, y1 - inset)):
                body.append(Box(fx, fy, (0.0, z0)))
    face = x0 - b.door_thickness
    proud = (face - b.relief, face)
    centre, hb = y1 - panel / 2, z1 - z0
    if b.display:
        body.append(
            Box(
                proud,
                (centre - 0.35 * panel, centre + 0.35 * panel),
                (z1 - 0.2 * hb, z1 - 0.08 * hb),
            )
        )
    if b.button_rows:
        side = min(0.16 * panel, 0.5 * (0.45 * hb) / b.button_rows)
        pitch_y, pitch_z = 0.27 * panel, 0.45 * hb / b.button_rows
        top = z1 - 0.28 * hb
        for r in range(b.button_rows):
            zc = top - (r + 0.5) * pitch_z
            for k in (-1, 0, 1):
                yc = centre + k * pitch_y
                body.append(
                    Box(proud, (yc - side / 2, yc + side / 2), (zc - side / 2, zc + side / 2))
                )
        start = (centre - 0.35 * panel, centre + 0.35 * panel)
        body.append(Box(proud, start, (z0 + 0.06 * hb, z0 + 0.14 * hb)))  # door-open button
    _, boxes = _microwave_door(spec, b)
    return _assemble(spec, body, [_door((x0, y0, z0 + b.door_margin), boxes, None)])


def _round_knob(diameter: float, length: float) -> TriangleMesh:
    """A 16-sided cylinder along x from 0 to -`length` (standing out of a face at x = 0)."""
    import trimesh

    along_x = make_transform(
        rotation=np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
        translation=np.array([-length / 2, 0.0, 0.0]),
    )
    shape = trimesh.creation.cylinder(
        radius=diameter / 2, height=length, sections=16, transform=along_x
    )
    return TriangleMesh(
        np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces, dtype=np.int32)
    )


def _bar(length: float, along: Literal["y", "z"]) -> TriangleMesh:
    """A 12 mm bar 30 mm in front of a face at x = 0 on two end posts, centred, running
    along y or z (the cabinet's handle)."""
    bar, standoff = 0.012, 0.03
    ends = (-length / 2, length / 2)
    across = (-bar / 2, bar / 2)
    pieces = [
        ((-standoff - bar, -standoff), ends),
        ((-standoff, 0.0), (ends[0], ends[0] + bar)),
        ((-standoff, 0.0), (ends[1] - bar, ends[1])),
    ]
    if along == "z":
        return union_mesh([Box(x, across, span) for x, span in pieces])
    return union_mesh([Box(x, span, across) for x, span in pieces])


def _handle_mesh(kind: str, size: float, along: Literal["y", "z"]) -> TriangleMesh:
    """A knob (box or round, `size` its side or diameter) or a bar (`size` long) in its
    own frame, on a face at x = 0, sticking out towards -x."""
    if kind == "knob_round":
        return _round_knob(size, 0.025)
    if kind == "knob_box":
        half = size / 2
        return union_mesh([Box((-0.025, 0.0), (-half, half), (-half, half))])
    return _bar(size, along)


def _cabinet_handle(b: CabinetBuild, width: float, height: float) -> TriangleMesh:
    """The handle in its own frame (on the door's face, sticking out towards -x)."""
    size = b.handle_size if b.handle != "bar" else min(b.handle_size, 0.6 * height)
    return _handle_mesh(b.handle, size, "z")


def _stand(support: Support, inset: float, x: Interval, y: Interval, z0: float) -> list[Box]:
    """What a carcass spanning `x` x `y` from z0 up stands on: a plinth `inset` behind
    its front (1 cm in from the back and sides), four legs of side `inset` 2 cm in from
    the corners, or nothing."""
    (x0, x1), (y0, y1) = x, y
    if support == "plinth" and z0 > 0:
        return [Box((x0 + inset, x1 - 0.01), (y0 + 0.01, y1 - 0.01), (0.0, z0))]
    if support == "legs" and z0 > 0:
        s, gap = inset, 0.02
        return [
            Box(lx, ly, (0.0, z0))
            for lx in ((x0 + gap, x0 + gap + s), (x1 - gap - s, x1 - gap))
            for ly in ((y0 + gap, y0 + gap + s), (y1 - gap - s, y1 - gap))
        ]
    return []


def _carcass(x: Interval, y: Interval, z: Interval, t: float) -> list[Box]:
    """A box open at the front (x[0]): back, two sides, bottom and top panels `t` thick."""
    (x0, x1), (y0, y1), (z0, z1) = x, y, z
    inner_x, inner_y = (x0, x1 - t), (y0 + t, y1 - t)
    return [
        Box((x1 - t, x1), (y0, y1), (z0, z1)),
        Box(inner_x, (y0, y0 + t), (z0, z1)),
        Box(inner_x, (y1 - t, y1), (z0, z1)),
        Box(inner_x, inner_y, (z0, z0 + t)),
        Box(inner_x, inner_y, (z1 - t, z1)),
    ]


def _cabinet_body(spec: BenchSpec, b: CabinetBuild) -> tuple[list[Box], Interval]:
    """A cabinet's carcass with shelves, top slab with overhang and plinth or legs; and
    the carcass's z span (the doors' opening)."""
    d, w, t = spec.depth, spec.width, b.wall
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    z0, z1 = b.support_height, spec.height - b.top  # carcass
    body = _carcass((x0, x1), (y0, y1), (z0, z1), t)
    for k in range(b.shelves):
        z = z0 + t + (k + 1) * (z1 - z0 - 2 * t) / (b.shelves + 1)
        body.append(Box((x0 + 0.02, x1 - t), (y0 + t, y1 - t), (z - t / 2, z + t / 2)))
    if b.top > 0:
        body.append(
            Box((x0 - b.overhang, x1), (y0 - b.overhang, y1 + b.overhang), (z1, spec.height))
        )
    body += _stand(b.support, b.support_inset, (x0, x1), (y0, y1), z0)
    return body, (z0, z1)


def _cabinet_door(b: CabinetBuild, width: float, height: float) -> tuple[list[Box], Handle | None]:
    """An overlay door `width` x `height` (joint frame, hinge at y = 0), flat or
    panelled, and its handle near the free edge."""
    th = b.door_thickness
    face, full = (-th, 0.0), (0.0, height)
    if b.panelled:
        f = min(b.frame, width / 4, height / 4)
        mid = (f, width - f)
        boxes = [
            Box(face, (0.0, f), full),
            Box(face, (width - f, width), full),
            Box(face, mid, (0.0, f)),
            Box(face, mid, (height - f, height)),
            Box((-th + b.recess, 0.0), mid, (f, height - f)),
        ]
    else:
        boxes = [Box(face, (0.0, width), full)]
    if b.handle == "none":
        return boxes, None
    hz = 0.5 * height if height > 1.0 else 0.8 * height
    mount = (-th, width - min(b.handle_inset, width / 4), hz)
    return boxes, (_cabinet_handle(b, width, height), mount)


def build_cabinet(spec: BenchSpec) -> ArticulatedObject:
    """A cabinet: plinth, legs or neither, a carcass with shelves, a top slab with
    overhang, an overlay door with gaps, a knob or bar handle at the free edge."""
    b = spec.build
    assert isinstance(b, CabinetBuild)
    body, (z0, z1) = _cabinet_body(spec, b)
    g = b.gap
    width, height = spec.width - 2 * g, (z1 - z0) - 2 * g
    boxes, handle = _cabinet_door(b, width, height)
    return _assemble(
        spec, body, [_door((-spec.depth / 2, -spec.width / 2 + g, z0 + g), boxes, handle)]
    )


def build_cabinet2(spec: BenchSpec) -> ArticulatedObject:
    """A two-door cabinet: the cabinet's body; two overlay doors `gap` in from the outer
    edges and `centre_gap` apart, door_0 hinged on -y, door_1 its mirror image on +y."""
    b = spec.build
    assert isinstance(b, CabinetBuild) and b.centre_gap is not None
    body, (z0, z1) = _cabinet_body(spec, b)
    g = b.gap
    width, height = (spec.width - 2 * g - b.centre_gap) / 2, (z1 - z0) - 2 * g
    boxes, handle = _cabinet_door(b, width, height)
    door = _door((-spec.depth / 2, -spec.width / 2 + g, z0 + g), boxes, handle)
    return _assemble(spec, body, [door, door._replace(mirror=-1)])


def _toaster_door(b: ToasterBuild, width: float, height: float) -> tuple[list[Box], Handle]:
    """The flap door, joint frame (origin the bottom edge's centre, y across), and its
    handle: a bar `handle_inset` below the top edge or a lip along the top edge."""
    t, half = b.door_thickness, width / 2
    face, across, full = (-t, 0.0), (-half, half), (0.0, height)
    if b.window:
        s, r = min(b.stile, width / 4), min(b.rail, height / 4)
        mid = (-half + s, half - s)
        boxes = [
            Box(face, (-half, -half + s), full),
            Box(face, (half - s, half), full),
            Box(face, mid, (0.0, r)),
            Box(face, mid, (height - r, height)),
            Box((-t + b.window_recess, 0.0), mid, (r, height - r)),
        ]
    else:
        boxes = [Box(face, across, full)]
    length = min(b.handle_length, 0.9 * width)
    if b.handle == "bar":
        inset = min(b.handle_inset, height / 4)
        return boxes, (_bar(length, "y"), (-t, 0.0, height - inset))
    lip = union_mesh([Box((-0.02, 0.0), (-length / 2, length / 2), (-0.012, 0.0))])
    return boxes, (lip, (-t, 0.0, height))


def build_toaster(spec: BenchSpec) -> ArticulatedObject:
    """A toaster oven: feet, a sheet-metal cavity behind the door with vent slots in its
    roof, an electronics block behind the control panel (knobs) on the -y side; the door
    hinged at its bottom edge (module docstring)."""
    b = spec.build
    assert isinstance(b, ToasterBuild)
    d, w, t = spec.depth, spec.width, b.wall
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    z0, z1 = b.foot_height, spec.height
    panel = b.panel_fraction * w
    y_block = y0 + panel + b.gap  # the electronics block's side facing the cavity
    cavity = (y_block, y1 - t)
    body = [
        Box((x1 - t, x1), (y0, y1), (z0, z1)),  # back
        Box((x0, x1 - t), (y1 - t, y1), (z0, z1)),  # free-side wall
        Box((x0, x1 - t), cavity, (z0, z0 + t)),  # floor
        Box((x0, x1 - t), (y0, y_block), (z0, z1)),  # electronics block
        Box((x0 - b.door_thickness, x0), (y0, y0 + panel), (z0, z1)),  # control panel
        *_roof(b, (x0, x1 - t), cavity, (z1 - t, z1)),
    ]
    if b.foot_height > 0:
        s, inset = b.foot_side, 0.02
        for fx in ((x0 + inset, x0 + inset + s), (x1 - inset - s, x1 - inset)):
            for fy in ((y0 + inset, y0 + inset + s), (y1 - inset - s, y1 - inset)):
                body.append(Box(fx, fy, (0.0, z0)))
    knobs = []
    if b.knobs:
        pitch = (z1 - z0) / (b.knobs + 1)
        size = min(b.knob_size, 0.8 * pitch, 0.6 * panel)
        for k in range(b.knobs):
            knob = _round_knob(size, b.knob_depth)
            offset = np.array([x0 - b.door_thickness, y0 + panel / 2, z1 - (k + 1) * pitch])
            knobs.append(TriangleMesh(knob.vertices + offset, knob.triangles))
    width = w - panel - b.gap
    height = z1 - z0 - 2 * b.door_margin
    boxes, handle = _toaster_door(b, width, height)
    origin = (x0, y_block + width / 2, z0 + b.door_margin)
    door = _Part("door", "revolute", origin, (0.0, -1.0, 0.0), boxes, handle)
    return _assemble(spec, body, [door], knobs)


def _roof(b: ToasterBuild, x: Interval, y: Interval, z: Interval) -> list[Box]:
    """The cavity's roof over `x` x `y`, with `vents` slots (along y, the middle 60 %)
    spread over the middle of its depth."""
    if not b.vents:
        return [Box(x, y, z)]
    slot_y = (y[0] + 0.2 * (y[1] - y[0]), y[1] - 0.2 * (y[1] - y[0]))
    pitch = 0.6 * (x[1] - x[0]) / b.vents
    width = min(b.vent_width, 0.5 * pitch)
    start = x[0] + 0.2 * (x[1] - x[0])
    cuts = [(start + (k + 0.5) * pitch - width / 2, start + (k + 0.5) * pitch + width / 2)
            for k in range(b.vents)]  # fmt: skip
    edges = [x[0], *(e for cut in cuts for e in cut), x[1]]
    solid = [(edges[i], edges[i + 1]) for i in range(0, len(edges), 2)]
    return [
        Box(x, (y[0], slot_y[0]), z),
        Box(x, (slot_y[1], y[1]), z),
        *(Box(span, slot_y, z) for span in solid),
    ]


def _overlay_span(
    b: DrawerBuild, opening_y: Interval, opening_z: Interval
) -> tuple[Interval, Interval]:
    """An overlay front's y and z spans: the opening widened by the carcass's wall on
    every side, less the `reveal` (the carcass's edge left showing)."""
    grow = b.wall - b.reveal
    return (opening_y[0] - grow, opening_y[1] + grow), (opening_z[0] - grow, opening_z[1] + grow)


def _drawer_part(
    b: DrawerBuild, front_x: float, opening_y: Interval, opening_z: Interval, back_x: float
) -> _Part:
    """The drawer: a box `clearance` inside the opening (`opening_y` x `opening_z`) from
    the body's front plane `front_x` to `back_x`, with its front inside the opening or in
    front of the carcass (`overlay`: `_overlay_span`), and its handle. Joint origin: the
    front's centre on the front plane (module docstring, "Labels")."""
    cl, bw, tf = b.clearance, b.box_wall, b.front_thickness
    yb = (opening_y[0] + cl, opening_y[1] - cl)
    zb = (opening_z[0] + cl, opening_z[1] - cl)
    length = back_x - front_x
    fy, fz = _overlay_span(b, opening_y, opening_z) if b.overlay else (yb, zb)
    zc = 0.5 * (fz[0] + fz[1])
    hw = 0.5 * (yb[1] - yb[0])
    rel = (zb[0] - zc, zb[1] - b.side_drop - zc)  # the box's walls, joint frame
    if b.overlay:  # the front in front of the plane; the box has its own front wall
        front = (-tf, 0.0)
        inner_x = (bw, length - bw)
        boxes = [Box((0.0, bw), (-hw, hw), rel)]
    else:
        front = (0.0, tf)
        inner_x = (tf, length - bw)
        boxes = []
    boxes += [
        Box((length - bw, length), (-hw, hw), rel),  # back
        Box(inner_x, (-hw, -hw + bw), rel),  # side
        Box(inner_x, (hw - bw, hw), rel),  # side
        Box(inner_x, (-hw + bw, hw - bw), (rel[0], rel[0] + bw)),  # bottom
    ]
    fz = (fz[0] - zc, fz[1] - zc)
    if b.handle == "grip" and b.grip_height > 0:
        boxes += [
            Box(front, fy, (fz[0], fz[1] - b.grip_height)),
            Box((front[0] + b.grip_depth, front[1]), fy, (fz[1] - b.grip_height, fz[1])),
        ]
    else:
        boxes.append(Box(front, fy, fz))
    handle = None
    if b.handle not in ("none", "grip"):
        size = min(b.handle_size, 0.8 * (fy[1] - fy[0])) if b.handle == "bar" else b.handle_size
        handle = (_handle_mesh(b.handle, size, "y"), (front[0], 0.0, 0.0))
    return _Part("drawer", "prismatic", (front_x, 0.0, zc), (-1.0, 0.0, 0.0), boxes, handle)


def build_drawer(spec: BenchSpec) -> ArticulatedObject:
    """A drawer unit: plinth, feet or neither, a carcass, a top slab with overhang, a
    drawer box with an overlay or inset front and a knob, bar or grip (module docstring)."""
    b = spec.build
    assert isinstance(b, DrawerBuild)
    d, w, t = spec.depth, spec.width, b.wall
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    z0, z1 = b.support_height, spec.height - b.top
    body = _carcass((x0, x1), (y0, y1), (z0, z1), t)
    if b.top > 0:
        body.append(
            Box((x0 - b.overhang, x1), (y0 - b.overhang, y1 + b.overhang), (z1, spec.height))
        )
    body += _stand(b.support, b.support_inset, (x0, x1), (y0, y1), z0)
    back = x1 - t - b.clearance - b.box_short
    part = _drawer_part(b, x0, (y0 + t, y1 - t), (z0 + t, z1 - t), back)
    return _assemble(spec, body, [part])


def _fridge_door(
    b: RefrigeratorBuild, width: float, height: float, upper: bool
) -> tuple[list[Box], Handle | None]:
    """A thick door (joint frame, hinge at y = 0) with a gasket band behind it and a
    bar near its top (fridge) or bottom (freezer, `upper`), or a grip recessed in its
    free edge."""
    t, gd, gk = b.door_thickness, b.gasket_depth, b.gasket
    back = -gd if gk > 0 and gd > 0 else 0.0
    slab, full = (-t, back), (0.0, height)
    boxes = [] if back == 0.0 else [Box((back, 0.0), (gk, width - gk), (gk, height - gk))]
    share = b.handle_fraction[1 if upper else 0]
    length = min(share * height, height - 0.08)
    centre = (0.04 + length / 2) if upper else (height - 0.04 - length / 2)
    if b.handle == "recess":
        rw = min(b.recess_width, width / 4)
        lo, hi = centre - length / 2, centre + length / 2
        boxes += [
            Box(slab, (0.0, width - rw), full),
            Box(slab, (width - rw, width), (0.0, lo)),
            Box(slab, (width - rw, width), (hi, height)),
            Box((-t + min(b.recess_depth, 0.6 * (back + t)), back), (width - rw, width), (lo, hi)),
        ]
        return boxes, None
    boxes.append(Box(slab, (0.0, width), full))
    mount = (-t, width - min(b.handle_inset, width / 4), centre)
    return boxes, (_bar(length, "z"), mount)


def build_refrigerator(spec: BenchSpec) -> ArticulatedObject:
    """A refrigerator: kick plate, feet or neither, a thick-walled carcass with a divider,
    a hinge cover on top, a fridge door below and a freezer door above, both thick and
    hinged on the chirality side (module docstring)."""
    b = spec.build
    assert isinstance(b, RefrigeratorBuild)
    d, w, t = spec.depth, spec.width, b.wall
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    z0, z1 = b.support_height, spec.height - b.hinge_cover
    split = z0 + (z1 - z0) * (1.0 - b.freezer_fraction)
    body = _carcass((x0, x1), (y0, y1), (z0, z1), t)
    body.append(Box((x0, x1 - t), (y0 + t, y1 - t), (split - t / 2, split + t / 2)))  # divider
    body += _stand(b.support, b.support_inset, (x0, x1), (y0, y1), z0)
    if b.hinge_cover > 0:
        body.append(Box((x0, x0 + 0.1), (y0, y0 + b.hinge_cover_width), (z1, spec.height)))
    g, half_gap = b.gap, b.centre_gap / 2
    width = w - 2 * g
    spans = ((z0 + g, split - half_gap), (split + half_gap, z1 - g))
    doors = []
    for k, (lo, hi) in enumerate(spans):
        boxes, handle = _fridge_door(b, width, hi - lo, upper=k == 1)
        doors.append(_door((x0, y0 + g, lo), boxes, handle))
    return _assemble(spec, body, doors)


BUILDERS: Final = {
    "microwave": build_microwave,
    "cabinet": build_cabinet,
    "cabinet2": build_cabinet2,
    "toaster": build_toaster,
    "drawer": build_drawer,
    "refrigerator": build_refrigerator,
}


def build(spec: BenchSpec) -> ArticulatedObject:
    """The object `spec` describes (pure, deterministic)."""
    return BUILDERS[spec.category](spec)


# ---------------------------------------------------------------------------- the scene


def _corners(obj: ArticulatedObject, q: NDArray[np.float64]) -> NDArray[np.float64]:
    """(8, 3) corners of the axis-aligned box round every link at `q` (dof,), in the
    frame of the object's base pose without its translation (camera axes)."""
    base = make_transform(rotation=obj.base_pose[:3, :3])
    at = dataclasses.replace(obj, base_pose=base)
    points = np.concatenate(
        [
            transform_points(pose, link.mesh.vertices)
            for link, pose in zip(at.links, at.link_poses(q), strict=True)
        ]
    )
    lo, hi = points.min(axis=0), points.max(axis=0)
    return np.array(
        [[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])]
    )


def _window(corners: NDArray[np.float64], x: float, axis: int) -> tuple[float, float]:
    """The offsets along `axis` (1: y, 2: z) that keep every corner, moved by x along
    the optical axis, `MARGIN_PX` inside the image: u = cx - fx y / x in [m, W - 1 - m]."""
    depth = corners[:, 0] + x
    f, c, size = (CAMERA.fx, CAMERA.cx, CAMERA.width) if axis == 1 else (
        CAMERA.fy, CAMERA.cy, CAMERA.height)  # fmt: skip
    low = (c - (size - 1 - MARGIN_PX)) / f * depth - corners[:, axis]
    high = (c - MARGIN_PX) / f * depth - corners[:, axis]
    return float(low.max()), float(high.min())


def _fits(corners: NDArray[np.float64], x: float) -> bool:
    if float((corners[:, 0] + x).min()) < MIN_DEPTH:
        return False
    return all(lo <= hi for lo, hi in (_window(corners, x, 1), _window(corners, x, 2)))


def nearest_distance(corners: NDArray[np.float64]) -> float:
    """The smallest x (mm resolution) at which the box `corners` fits the image."""
    lo, hi = MIN_DEPTH - float(corners[:, 0].min()), 50.0
    if not _fits(corners, hi):
        raise ValueError("object too large for the camera")
    while hi - lo > 1e-4:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _fits(corners, mid) else (mid, hi)
    return hi


def table_a2_height(category: str) -> tuple[float, float]:
    """Table A.2's range of the base's height (camera z, m) for `category`: its
    conf/common/category/<category>.yaml `pose.z`."""
    from artic.planning.models import category_config

    low, high = category_config(category).pose.z
    return float(low), float(high)


def _height(
    rng: np.random.Generator, window: tuple[float, float], wanted: tuple[float, float] | None
) -> float:
    """z uniform over `window` (the heights that keep the object in the image), or over
    its overlap with `wanted`; the window's end nearest `wanted` when they do not overlap
    (one draw either way: the same stream)."""
    u = _u(rng, 0.0, 1.0)
    low, high = window
    if wanted is not None:
        overlap = (max(low, wanted[0]), min(high, wanted[1]))
        if overlap[0] > overlap[1]:
            return high if high < wanted[0] else low
        low, high = overlap
    return low + u * (high - low)


def place(
    spec: BenchSpec,
    rng: np.random.Generator,
    builder: Builder = "bench",
    placement: Placement = "frame",
) -> tuple[BenchSpec, ArticulatedObject]:
    """The object positioned: x uniform from `nearest_distance` to `DISTANCE_SPAN` beyond,
    then y and z uniform over the offsets that keep it `MARGIN_PX` inside the image (z
    inside Table A.2's range where it can be: `placement` "table_a2", module docstring).
    builder "artic": artic's own builder of the same numbers (`label_spec`), the control."""
    if builder == "artic":
        from artic.objects.categories import build as build_artic

        obj = build_artic(spec.label_spec())
    else:
        obj = build(spec)
    corners = _corners(obj, spec.q())
    x = _u(rng, (near := nearest_distance(corners)), near + DISTANCE_SPAN)
    y = _u(rng, *_window(corners, x, 1))
    wanted = table_a2_height(spec.category) if placement == "table_a2" else None
    z = _height(rng, _window(corners, x, 2), wanted)
    pose = Pose(x=x, y=y, z=z, yaw=spec.pose.yaw)
    placed = spec.model_copy(update={"pose": pose})
    return placed, dataclasses.replace(obj, base_pose=pose.matrix())


def chirality_of(index: int, sides: Sides) -> Literal[-1, 1]:
    """right = +1 (hinge on the camera's right), left = -1, both: +1 for even i (the
    categories of `SIDED`; the others' chirality is always 1, `make_object`)."""
    if sides == "both":
        return 1 if index % 2 == 0 else -1
    return 1 if sides == "right" else -1


def make_object(
    category: Category,
    sizes: Sizes,
    sides: Sides,
    seed: int,
    index: int,
    builder: Builder = "bench",
    placement: Placement = "frame",
) -> tuple[BenchSpec, ArticulatedObject]:
    """Object `index` of the bench: drawn from `default_rng([seed, index, STREAM])`;
    built by this file (`builder` "bench") or by artic's builder, placed (`place`)."""
    rng = np.random.default_rng([seed, index, STREAM])
    chirality = chirality_of(index, sides) if category in SIDED else 1
    if category == "microwave":
        spec = sample_microwave(rng, index, chirality)
    elif category == "cabinet":
        spec = sample_cabinet(rng, index, chirality, sizes)
    elif category == "cabinet2":
        spec = sample_cabinet2(rng, index, sizes)
    elif category == "toaster":
        spec = sample_toaster(rng, index)
    elif category == "drawer":
        spec = sample_drawer(rng, index)
    else:
        spec = sample_refrigerator(rng, index, chirality)
    return place(spec, rng, builder, placement)


class Image(NamedTuple):
    """One rendered image: depth (H, W) uint16 millimetres (sensor noise applied) and
    its labels (`label_columns(dof)` order)."""

    depth_mm: NDArray[np.uint16]
    labels: dict[str, float]


def render(spec: BenchSpec, obj: ArticulatedObject, seed: int, backend: Any) -> Image:
    """Ray cast `obj` at its configuration with `backend` (CAMERA), add `NOISE` drawn
    from `default_rng([seed, index, STREAM, 1])`, and label it (artic's `image_labels`)."""
    from artic.objects.labels import image_labels
    from artic.render.noise import apply_sensor_noise, depth_to_uint16_mm

    q = spec.q()[None]
    clean = backend.render_many(obj, q)[0].depth
    rng = np.random.default_rng([seed, spec.index, STREAM, 1])
    noisy = apply_sensor_noise(clean, NOISE, rng, CAMERA.fx)
    return Image(depth_to_uint16_mm(noisy), image_labels(spec.label_spec(), obj, q[0]))


# ---------------------------------------------------------------------------- scoring


class Score(NamedTuple):
    """One image's errors (errors.csv)."""

    chirality_estimate: int
    axis_position_cm: float
    yaw_deg: float
    configuration_deg: float
    rotation_thesis_deg: float
    hinge_side_right: bool
    warned: bool
    warnings: list[str]


def score(result: dict[str, Any], labels: dict[str, float], category: str = "microwave") -> Score:
    """Errors of `predict_image`'s `result` against the true `labels` of an object of
    `category`, as `kinematic_errors` defines them (on the columns both have; the means
    over the joints of a two-door object, centimetres of a drawer's q)."""
    from artic.evaluation.kinematics import kinematic_errors
    from artic.objects.labels import label_columns

    dof = 2 if category in TWO_DOORS else 1
    columns = label_columns(dof)
    pred = np.array([[float(result["estimate"][c]) for c in columns]])
    true = np.array([[labels[c] for c in columns]])
    kind = "prismatic" if category == "drawer" else "revolute"
    errors = kinematic_errors(pred, true, columns, dof, kind)
    side = int(result["geometry"]["chirality"])
    warnings = [str(w) for w in result["warnings"]]
    return Score(
        chirality_estimate=side,
        axis_position_cm=float(errors["position_cm"][0]),
        yaw_deg=float(errors["rotation_deg"][0]),
        configuration_deg=float(errors["configuration"][0]),
        rotation_thesis_deg=float(errors["rotation_thesis_deg"][0]),
        hinge_side_right=bool(errors["hinge_side_wrong_pct"][0] == 0),
        warned=any(w.startswith(ESTIMATE_WARNINGS) for w in warnings),
        warnings=warnings,
    )


def model_file(model: Path, category: str) -> Path:
    """`--model`: a folder's model.pt or a file, loadable as an MDN of `category`."""
    from artic.kinematics.predict import Predictor

    path = model / "model.pt" if model.is_dir() else model
    if not path.is_file():
        raise InputError(f"--model {model}: no such file (expected a model.pt or its folder)")
    Predictor.load(path, category)  # InputError naming the file if it is not one
    return path


def method_name(refine: bool) -> str:
    """The `evaluate mdn` method of predict's estimate with or without the refinement."""
    from artic.kinematics.evaluate import REFINED

    return REFINED if refine else "Ours"


def withheld_median(report: Path, category: str, refine: bool = True) -> float:
    """The median axis-position error (cm) of the estimate this run scores (`method_name`:
    "Ours + refinement" when refining, else the network's "Ours") in an `artic evaluate
    mdn` output folder's errors.csv (of `category`, when its manifest.json says)."""
    from artic.artifacts.formats import read_csv, read_json

    manifest = report / "manifest.json"
    if manifest.is_file():
        config = read_json(manifest).get("config", {})
        name = (config.get("category") or {}).get("name", category)
        if name != category:
            raise InputError(f"--report {report}: an evaluation of {name}, not {category}")
    path = report / "errors.csv"
    if not path.is_file():
        raise InputError(f"--report {report}: no errors.csv (an artic evaluate mdn folder?)")
    rows = read_csv(path)
    if not rows or "method" not in rows[0] or "position_cm" not in rows[0]:
        raise InputError(f"{path}: expected the columns method and position_cm")
    method, position = rows[0].index("method"), rows[0].index("position_cm")
    name = method_name(refine)
    ours = [float(r[position]) for r in rows[1:] if r[method] == name]
    if not ours:
        raise InputError(f"{path}: no row of method {name}")
    return float(np.median(ours))


def summary_rows(
    category: str,
    sizes: str,
    errors: list[tuple[str, Score]],
    withheld: float | None,
    refine: bool = True,
    placement: str = "frame",
) -> list[list[Any]]:
    """summary.csv: one row per side present ("right", "left"), then "both" when both
    are or when the images have no hinge side (side "none": cabinet2, toaster, drawer).
    Medians over the images; percentages 0-100; ratio = median / withheld."""
    groups: list[tuple[str, list[Score]]] = [
        (s, [e for side, e in errors if side == s]) for s in ("right", "left")
    ]
    groups = [(s, g) for s, g in groups if g]
    if len(groups) != 1:
        groups.append(("both", [e for _, e in errors]))
    rows = []
    for name, group in groups:
        median = float(np.median([e.axis_position_cm for e in group]))
        rows.append(
            [
                category,
                name,
                sizes,
                placement,
                method_name(refine),
                len(group),
                round(median, 3),
                round(float(np.median([e.yaw_deg for e in group])), 3),
                round(float(np.median([e.configuration_deg for e in group])), 3),
                round(100.0 * float(np.mean([e.hinge_side_right for e in group])), 1),
                round(100.0 * float(np.mean([e.warned for e in group])), 1),
                "" if withheld is None else round(withheld, 3),
                "" if withheld is None else round(median / withheld, 3),
            ]
        )
    return rows


# ---------------------------------------------------------------------------- the run


def run(
    category: str,
    objects: int,
    seed: int,
    model: Path,
    out: Path,
    report: Path | None = None,
    sides: str = "both",
    sizes: str = "table_a1",
    builder: str = "bench",
    refine: bool = True,
    placement: str = "frame",
) -> list[list[Any]]:
    """Generate, render, write, predict and score (module docstring); the summary rows.
    Everything is checked before `out` is created; InputError on bad input."""
    from PIL import Image as PILImage

    from artic.artifacts.formats import write_csv, write_json
    from artic.kinematics.predict import predict_image
    from artic.objects.labels import label_columns
    from artic.render.backend import make_backend

    if category not in CATEGORIES:
        raise InputError(f"--category: {category!r}; expected one of {', '.join(CATEGORIES)}")
    if objects < 1:
        raise InputError(f"--objects: expected >= 1, got {objects}")
    if seed < 0:
        raise InputError(f"--seed: expected >= 0, got {seed}")
    if sides not in ("both", "left", "right"):
        raise InputError(f"--sides: {sides!r}; expected both, left or right")
    if sides != "both" and category not in SIDED:
        raise InputError(f"--sides: {category} has no hinge side to draw; expected both")
    if sizes not in CABINET_SIZES:
        raise InputError(f"--sizes: {sizes!r}; expected table_a1 or generator")
    if builder not in ("bench", "artic"):
        raise InputError(f"--builder: {builder!r}; expected bench or artic")
    if placement not in PLACEMENTS:
        raise InputError(f"--placement: {placement!r}; expected frame or table_a2")
    path = model_file(model, category)
    withheld = withheld_median(report, category, refine) if report is not None else None
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise InputError(f"--out: {out} exists and is not an empty folder")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial-", dir=out.parent))
    try:
        (tmp / "images").mkdir()
        camera = {**CAMERA.model_dump(), "frame_id": FRAME_ID}
        write_json(tmp / "camera.json", camera)
        columns = label_columns(2 if category in TWO_DOORS else 1)
        label_rows, error_rows, specs = [], [], []
        scored: list[tuple[str, Score]] = []
        with make_backend("raycast", CAMERA) as backend:
            for i in range(objects):
                spec, obj = make_object(category, sizes, sides, seed, i, builder,  # type: ignore[arg-type]
                                        placement)  # type: ignore[arg-type]  # fmt: skip
                image = render(spec, obj, seed, backend)
                png = tmp / "images" / f"{i:06d}.png"
                PILImage.fromarray(image.depth_mm).save(png, format="PNG")
                side = "none" if category not in SIDED else (
                    "right" if spec.chirality == 1 else "left")  # fmt: skip
                label_rows.append([i, i, side, *(image.labels[c] for c in columns)])
                specs.append(spec.model_dump_json(exclude_none=True))
                result = predict_image(
                    png, category, str(tmp / "camera.json"), path, None, 0, ESTIMATOR, seed,
                    time.perf_counter(), refine,
                )  # fmt: skip
                result["warnings"] = [w.replace(str(tmp), str(out)) for w in result["warnings"]]
                s = score(result, image.labels, category)
                scored.append((side, s))
                error_rows.append([
                    i, i, side, spec.chirality, s.chirality_estimate, s.axis_position_cm,
                    s.yaw_deg, s.configuration_deg, s.rotation_thesis_deg,
                    int(s.hinge_side_right), int(s.warned),
                    " | ".join(s.warnings),
                ])  # fmt: skip
        write_csv(tmp / "labels.csv", ["image", "object_id", "side", *columns], label_rows)
        (tmp / "objects.jsonl").write_text("".join(f"{s}\n" for s in specs))
        write_csv(tmp / "errors.csv", ERROR_COLUMNS, error_rows)
        rows = summary_rows(category, sizes, scored, withheld, refine, placement)
        write_csv(tmp / "summary.csv", SUMMARY_COLUMNS, rows)
        if out.exists():
            out.rmdir()  # empty (checked above)
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return rows


def _table(rows: list[list[Any]]) -> str:
    """The summary as an aligned text table."""
    header = ["sides", "estimator", "images", "axis cm", "yaw deg", "config deg", "side ok %",
              "warned %", "withheld cm", "ratio"]  # fmt: skip
    body = [[str(v) for v in (r[1], *r[4:])] for r in rows]
    widths = [max(len(x) for x in col) for col in zip(header, *body, strict=True)]
    return "\n".join(
        "  ".join(x.rjust(w) for x, w in zip(line, widths, strict=True)) for line in [header, *body]
    )


def _one_line_error(message: str) -> NoReturn:
    """argparse's error without the usage lines: one line, exit 2."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def main(argv: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog="independent_mdn_objects.py",
        description="Objects of the six categories from a second generator, predicted "
        "through artic predict's code path and scored (errors.csv, summary.csv).",
    )
    parser.add_argument("--category", required=True, help=", ".join(CATEGORIES))
    parser.add_argument("--objects", type=int, required=True, help="objects (one image each)")
    parser.add_argument("--seed", type=int, default=0, help="object i from (seed, i)")
    parser.add_argument("--model", type=Path, required=True, help="train-mdn folder or model.pt")
    parser.add_argument("--report", type=Path, help="artic evaluate mdn folder of the model")
    parser.add_argument("--out", type=Path, required=True, help="output folder (new or empty)")
    parser.add_argument(
        "--sides", default="both", help=f"both | left | right ({', '.join(SIDED)}; else both)"
    )
    parser.add_argument("--sizes", default="table_a1", help="table_a1 | generator")
    parser.add_argument(
        "--builder", default="bench", help="bench (this file's objects) | artic (the control)"
    )
    parser.add_argument(
        "--placement", default="frame", help="frame | table_a2 (the base's height in Table A.2's)"
    )
    parser.add_argument(
        "--no-refine", action="store_true", help="the network's estimate, as predict --no-refine"
    )
    parser.error = _one_line_error  # type: ignore[method-assign]
    args = parser.parse_args(argv)
    logger = logging.getLogger("artic")
    level = logger.level
    logger.setLevel(logging.ERROR)  # predict's warnings: in errors.csv
    try:
        rows = run(
            args.category, args.objects, args.seed, args.model, args.out, args.report,
            args.sides, args.sizes, args.builder, not args.no_refine, args.placement,
        )  # fmt: skip
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    finally:
        logger.setLevel(level)  # callers in the same process (the tests) keep theirs
    what = "artic's builder (control)" if args.builder == "artic" else "this generator"
    print(f"{args.category} ({args.sizes} sizes, {what}, placement {args.placement}), "
          f"{args.objects} objects -> {args.out}")  # fmt: skip
    print(_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
