"""Test-time geometric refinement of a door or drawer estimate (issue 19, item 1).

The network proposes, the depth image decides. From a hypothesis (a label vector: base
pose x, y, z, yaw, the body's depth, width, height, the chirality and each door's q):

1. render the hypothesis with the raycast backend (`render.backend`): which pixels are
   the body's front, its sides and the door's broad faces, and where each of those faces
   lies in the object's (or the door's) frame;
2. take each observed pixel whose back-projected point lies within a tolerance of the
   plane of the face its rendered pixel lies on (point to plane, not depth: a face seen
   at a grazing angle moves far along the ray), clean each face's points with RANSAC
   (Open3D's `segment_plane`) and fit by least squares:
   - yaw from the body's vertical faces: the front's normal and the side's, fitted
     together (the front normal is the eigenvector of the smallest eigenvalue of
     C_front - C_side, C the faces' horizontal scatter matrices, each parallel plane about
     its own mean), refitted once without the points beyond 3 robust deviations;
   - each door's q from the angle between its plane and the body's front (the door's
     normal is the front's turned by s q about z, s its axis' sign along z: the
     chirality for a one-door object, +1 and -1 for the two-door cabinet's doors);
   - the base position (x, y) by least squares over every face's inlier points, each on
     its face's plane in the object frame (front x = -depth/2, or the control panel's
     -depth/2 - door thickness; side y = +-width/2; door x = -door thickness or 0 in the
     door's frame, which puts the hinge line where the door's plane meets the body's
     front; every door's points join), with a small pull towards the hypothesis so that a
     position the image does not fix (along a closed door's front with no side in view)
     stays the network's;
   - the base height z from the bottom silhouette edge (`_bottom_edge`: every face that
     stands on the base ends there: the body's, and each door hinged at the base, not a
     refrigerator's upper door; its columns' `EDGE_QUANTILE` quantile, as a sensor loses
     edge pixels); the doors' lift above it (`_lift`: a plinth or kick
     plate under the front, which the box model lacks, read off the doors' own bottom
     edge; it moves the label's joint origins, not the rendered box); depth, width and
     height stay the network's here;
3. re-render and repeat (`ITERATIONS`, with a shrinking tolerance), keeping the round
   (or the start) with the lowest depth residual.

It runs from the mixture's top components (up to `COMPONENTS`, a drawer's
`DRAWER_COMPONENTS`) and, for a category with a hinge side to decide (`SIDED`), both
hinge sides (each component's chirality and the other, all else equal; for the top
component also its mirror image about the line of sight, `Hypothesis.reflected`: a
network trained on one side may read an object hinged on the other side as that; and
the best of these again on the other side from its own pose, `_other_side`, so that
both sides meet at the best pose found; a microwave's only where the other side would win
with its door shut, scored there on the network's side), scores every candidate by
a robust depth residual (`depth_residual`: the mean over the union of the rendered and
observed pixels of |rendered - observed| capped at `RESIDUAL_CAP`, a pixel seen in one
image only counting the cap) and keeps the lowest, on the network's hinge side unless the
other side's is lower by more than `SIDE_MARGIN` (`_choose_side`). It falls back to the
network's estimate, and says why in `Refinement.status`, when no candidate's yaw and q
lie inside the mixture's interval (`interval_ok`; a candidate on a hinge side that no
component mean has, as with a model trained on one side, may have its mirror image
inside instead, `judged_ok`: such a network reads an object hinged on the other side as
its mirror image; until 2026-12-06 such a candidate was judged by its residual alone), or when
the chosen candidate's residual is not below the
network's own: the returned estimate's residual is never larger than the network's.
The chosen door candidate then has its width fitted too, and then its depth (`_refit_sizes`:
the width as below, the depth off the far edge of the side in view, `side_depth`; one more
build of the object each; every candidate before it shares the network's sizes).
Then, when its body shows no face the rounds fit the yaw from (a cabinet's front is all
door; seen square-on, no side shows, and the rounds keep the yaw they start from and read
q off the door against it), its body is turned about the door's hinge, the door held
where the image shows it (`hinge_turn`, `about_hinge`: yaw + d, q - sign d, up to 20 deg
each way, q in its range); the turn of the lowest depth residual is refined once more and
kept when its residual is lower and it is judged inside the mixture's interval. Then,
for every category whose doors turn about vertical hinges, when the body's inside shows
through an opened door at the chosen pose (the shell's inner back or side faces), the
rounds run once more from it with those faces in the yaw's fit (`inner_faces`): they turn
with the body, not with the door, so they split the door's angle between the yaw and q
where the front is all door; kept on the same terms. Only from the chosen candidate: from
a start a few degrees off, an inner face's pixels are as often another face's, and rounds
that fit them settle there. The two steps share one build of the chosen object.

A microwave's chosen candidate then has its width searched on the depth residual with the
control panel's side held and the hinge's moved (`hinge_width`, `PANEL_HELD`): each width
drawn from the candidate's object stretched to it (`PosedRenderer.render_stretched`), the
one found built and kept when its residual is lower.

A box whose side the network took for its front (a nearly square object turned about 45
deg with its door shut: the front and the side show the same box) is read again a quarter
turn away (`_turned`): the chosen candidate turned about its middle so that the side in
view becomes the front, its width and depth swapped (the same footprint), from both hinge
sides, refined and sized as above. The depth residual alone cannot tell the two readings
apart (of closed microwaves, the turned candidate of a right reading fitted 15-26% better
as often as that of a side-first one), so a turned candidate has a test of its own: it is
kept only when no hinge-side test (below) found a front's features (a handle, the front's
step, the control panel or its seam) on the chosen candidate's front, the handle test
found a handle on the turned candidates' front (`handle_side`; a side face has none), and
its residual is lower. Its yaw is outside the mixture's interval by
construction; its q is held to it. The status says "turned a quarter".

On a nearly closed door (every door, for a refrigerator) the handle then has the last word
on the hinge side (`handle_side`; the first door's handle, a refrigerator's lower one): a
door is pulled open at its free edge, so its handle (a knob or bar standing proud of the
door's front) lies near the edge away from the hinge. For the best candidate of each side
whose door is open less than `HANDLE_Q_MAX` (and whose residual is near the best), the
pixels of the image in its own camera (`detail`: `artic predict` passes the image before
it was reduced into the model's camera, where a knob is a pixel or two) that lie inside
the candidate's door outline and stand proud of its front plane (a plane fitted to
those pixels, so that a candidate a few degrees off the door does not see its edge
standing proud; a frame round a recessed window is that plane) are opened (isolated
noise goes) and grouped into blobs; the largest compact one is the handle
(`handle_position`). A candidate with the handle in its door's free part votes for its
side, one with it by the hinge for the other side; a side every vote is for is chosen,
with its lowest-residual candidate. A door with no handle, or one too far away for its
handle to stand out of the sensor's noise, leaves the choice to the residuals. On a nearly
closed door the two sides' renders differ by little more than the handle, which the
residual over the whole object hardly weighs (docs/reproduction.md, issue 24). On a
microwave the front's shape has the word next (`front_side`): a door turned about its
hinge stands out of the front in proportion to the distance from the hinge, beside a
control panel that stays in the body's plane, so the front's profile across its width
(`front_profile`, in the image's own camera) has a step at the door's free edge; each
side's model of it (`front_fit`) is fitted, and the side that fits far better is named.
Then the control panel (`panel_side`): a candidate on the wrong side puts its panel over
the door's window, which reads recessed.
When the panel names none either, the seam between the door's free edge and the panel
does (`seam_side`): a line of pixels deeper than their row's neighbours (or missing),
down the middle of the front, a panel's width from one end.

A toaster's door is a flap hinged at its bottom edge (`_Door.flap`): its plane is fitted
across its horizontal axis, in the object's (x, z) plane (`_door_q`), and its normal's
part along z enters the position's least squares at the base height held. That height is
not read off the bottom edge (a 20-50 cm toaster's edge, at 1-2 cm a pixel, reads about
0.6 cm high, and an opened flap lies across it) but, the door opened `FLAP_OPEN_Q` or
more, searched on the depth residual before the first round and after it
(`search_height`, the drawer's search upwards); a closed flap's front is flat, and the
height stays the start's (the network's is better than a silhouette's pixels). No door
plane meets a side, so the chosen candidate's width comes from the
front's far edge against the background (`front_width`) instead of `_fit_width`'s hinge,
and an opened flap's edge beside the control panel gives the panel's share of the width
(`flap_panel_share`), which places the door across the front. Last, the chosen flap's
base is searched with its top held (`flap_base`, an object built per height): a toaster
oven on feet has its door a foot's height up, and the network takes the feet into the box.

A drawer (`JOINT_TYPES`) takes the same rounds with its front in place of the door's
plane, one start per component (no hinge sides, no handle test), and a search on the
depth residual along its opening, across its front and up (`search_opening`, `_fit_drawer`).
The chosen drawer is then read again with an overlay front (`_overlay_front`,
`PartsConfig.drawer_front`: a plate over the whole body front, its back face on the body's
front when shut, as most chests of drawers have; the generator's front sits inside the
opening), its body the width and height the plate shows (`front_span`), and that reading
replaces the inset one when its depth residual is lower and it lies inside the mixture's
interval. The status says "overlay front".

Supported: the six Chapter 3 categories (`SUPPORTED`): doors on vertical hinges (one
door; the two-door cabinet's side by side, each hinged at its outer edge; the
refrigerator's one above the other, both on its hinge side), the toaster's flap and the
drawer. Any other category returns the network's estimate with a status saying so.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import re
from collections.abc import Callable, Collection, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from artic.geometry.camera import CameraIntrinsics
from artic.geometry.transforms import axis_angle, make_transform, rot_z
from artic.objects.model import ArticulatedObject, Joint
from artic.objects.spec import ObjectSpec, PartsConfig, Pose
from artic.render.backend import RenderedImage

#: the categories refined and their joints: doors on vertical hinges (one, or the two-door
#: cabinet's side by side, or the refrigerator's one above the other), the toaster's door
#: hinged at its bottom edge, or one drawer (`_fit`, "A drawer")
JOINT_TYPES = {
    "cabinet": "revolute", "microwave": "revolute", "cabinet2": "revolute",
    "refrigerator": "revolute", "toaster": "revolute", "drawer": "prismatic",
}  # fmt: skip
SUPPORTED = tuple(JOINT_TYPES)
#: the categories whose chirality is a hinge side to decide (both sides are tried, the
#: handle has a say); the two-door cabinet's doors are hinged at its outer edges
SIDED = ("cabinet", "microwave", "refrigerator")
#: the categories whose door is a flap hinged at its bottom edge (`_Door.flap`)
FLAPS = ("toaster",)
#: the categories whose door's width is searched with the control panel's side held
#: (`hinge_width`): a door on one vertical hinge beside a control panel
PANEL_HELD = ("microwave",)
#: render-assign-fit rounds per candidate
ITERATIONS = 3
#: an observed point joins a face when within this of its plane (m), per round
TOLERANCES = (0.08, 0.04, 0.03)
#: mixture components refined (the largest weights), each from both hinge sides
COMPONENTS = 3
#: a drawer's: its components' refined readings agree (where the third's was the best, on
#: 75 of 318 validation images, its residual was a median 0.9% below the better of the
#: first two's), and its time goes to the overlay reading (`_overlay_front`) instead
DRAWER_COMPONENTS = 2
#: RANSAC inlier distance (m) and iterations (Open3D `segment_plane`)
RANSAC_DISTANCE = 0.015
RANSAC_ITERATIONS = 60
#: q is read off the door's plane when it has at least this many inliers (a door seen
#: edge-on gives a few noisy points)
MIN_DOOR_POINTS = 20
#: a face with fewer observed points is not fitted
MIN_FACE_POINTS = 15
#: an observed pixel farther than this from the rendered depth is not assigned (m)
DEPTH_GATE = 0.3
#: a rendered point belongs to a face when within this of the face's plane (m)
FACE_EPS = 0.002
#: the capped |rendered - observed| of the residual (m); a pixel seen in one image counts it
RESIDUAL_CAP = 0.05
#: the robust refit of a face keeps points up to at least this far from its plane (m)
LINE_FLOOR = 0.004
#: weight (in points) of the pull of the base position towards the hypothesis
PRIOR_WEIGHT = 2.0
#: a plane fit turning the yaw further than this from the hypothesis is not used (rad)
MAX_YAW_STEP = math.radians(30.0)
#: refined q is kept inside [0, Q_MAX] (rad); a drawer's inside [0, its depth] (m)
Q_MAX = math.pi
#: the mixture's central interval a refined yaw and q must lie in, the yaw's widened by
#: `INTERVAL_MARGIN`, a door's q by `INTERVAL_MARGIN_Q` (rad), a drawer's q by
#: `INTERVAL_MARGIN_M` (m). The yaw is what rules out a mirror-image explanation (its yaw
#: differs by about twice the object's); q is what the planes read best and the network
#: worst on objects unlike its training ones (a Table A.1 cabinet's door open 22 deg read
#: as closed, [-8, 13] deg at 99%, by a model trained mostly on smaller ones)
INTERVAL_LEVEL = 0.99
INTERVAL_MARGIN = math.radians(5.0)
INTERVAL_MARGIN_Q = math.radians(15.0)
INTERVAL_MARGIN_M = 0.03
#: weight (in points) of the pull of a drawer's q towards the hypothesis: only for the
#: rank of the least squares (a drawer front with no body front rim in view)
Q_PRIOR_WEIGHT = 0.01
#: the first step of the line searches over a length (`_search`, m): a drawer's base across
#: its front and up, a flap's base (`flap_base`), the hinge's side (`hinge_width`)
SEARCH_STEP = 0.01
#: the first step of the search along a drawer's opening (m), and its levels: that line
#: runs the drawer's whole depth (up to 64 cm), so every 2 cm, then 4 mm, then 0.8 mm
#: (47 renders over 60 cm, against 69 every cm, then 2 mm; docs/reproduction.md)
OPENING_STEP = 0.02
OPENING_LEVELS = 3
#: a chosen door candidate whose body shows no face to fit its yaw from is turned about
#: its hinge, the doors held where the image shows them, up to this far each way (rad),
#: every `HINGE_TURN_STEP`, then a fifth of that around the best (`hinge_turn`)
HINGE_TURN_SPAN = math.radians(20.0)
HINGE_TURN_STEP = math.radians(2.0)
#: how far the search moves a drawer's base along its front and up or down (m)
SEARCH_SPAN = 0.05
#: how far `hinge_width` moves the hinge's side each way (m), and the narrowest body it
#: tries
HINGE_WIDTH_SPAN = 0.08
MIN_WIDTH = 0.1
#: a flap's base height is searched this far either side of the start's and the first
#: round's (m): the network's is within about a centimetre (`search_height`)
FLAP_HEIGHT_SPAN = 0.02
#: how far the chosen flap candidate's base is searched below and above its own, its top
#: held (m, `flap_base`): toaster ovens stand on feet (1-3 cm), which the box model lacks
FLAP_BASE_SPAN = (-0.02, 0.04)
#: how far beyond the hypothesis' sides a flap's front is looked for, and how close to
#: its plane (m, `front_width`)
WIDTH_SPAN = 0.12
WIDTH_BAND = 0.03
#: the quantile across the front taken as its far edge's last pixel, and the fewest points
WIDTH_QUANTILE = 0.99
MIN_WIDTH_POINTS = 100
#: a door fixes the width (`_fit_width`: its plane through its hinge at the body's side)
#: when open at least this far; one nearer shut lies along the front, its hinge's place
#: across is the width prior's, and the front's far edge gives the width (`front_width`)
WIDTH_DOOR_Q = math.radians(10.0)
#: a flap opened at least this far stands out of the front: its depth changes along its
#: height, which fixes the base height (`search_height`), and its edge shows beside the
#: control panel (`flap_panel_share`); a closed one's front is flat
FLAP_OPEN_Q = math.radians(15.0)
#: the part of the door's height, and the range of shares, of `flap_panel_share`
PANEL_SHARE_ROWS = (0.3, 1.0)
PANEL_SHARES = (0.1, 0.4)
#: the base height is read off the bottom silhouette edge when it has this many pixels
MIN_EDGE_PIXELS = 5
#: an edge pixel's rendered hypothesis must end within this many rows below it
EDGE_ROWS = 3
#: a depth sensor loses pixels at depth edges: the sensor model's
#: (conf/common/noise/kinect.yaml) each with probability p = 0.5, so a column of the bottom
#: edge whose last pixel is lost reads a pixel high. Of per-column readings spread over a
#: pixel (where the edge falls within it), a share p of them a pixel higher, the
#: (1 - p) / 2 quantile is the edge's own median: the base height is that quantile
#: (`_base_height`; the median read the microwave's base 0.6 cm high, docs/kinematics.md)
EDGE_QUANTILE = 0.25
#: the other hinge side replaces the network's when its residual is lower by this fraction,
#: when the mixture puts all its weight on the network's side; the margin shrinks with that
#: weight w as SIDE_MARGIN (2 w - 1), to 0 for a mixture split evenly between the sides
SIDE_MARGIN = 0.25
#: a quarter-turned candidate (`_turned`) is tried only when its front faces the camera
#: within this (rad); it replaces the chosen one when the handle test (`handle_side`) names
#: its side and its residual is lower (not the other hinge-side tests: a control panel's
#: recess was once found on a second-generator microwave's side face, and none of them ever
#: turned a box right; until 2026-12-07 also lower by 15%, which kept side-first readings
#: whose turn fitted 5-14% better and turned none wrong)
TURN_INCIDENCE = math.radians(70.0)
#: the handle test's name in a refinement's status
HANDLE_TEST = "the handle's side"
#: a point below a face's lowest pixel is still on the face within this of its plane (m;
#: `_face_bottoms`): a plinth recessed behind a door is farther
LIFT_TOLERANCE = 0.025
#: the doors' lift (`_lift`, m): 0 below MIN_LIFT (noise) or above MAX_LIFT (a misread:
#: kitchen plinths and kick plates are 5-15 cm, cabinet legs up to about 15)
MIN_LIFT = 0.015
MAX_LIFT = 0.2
#: ... and read only when the doors' bottom edges agree: interquartile range at most this (m)
LIFT_SPREAD = 0.03
#: fewer observed pixels than this: not refined
MIN_OBSERVED = 50
#: the handle test (`handle_position`): pixels within the door's outline, widened across
#: the door by `HANDLE_BEYOND` and inset up it by `HANDLE_EDGE` (m), standing proud of
#: its front plane by more than max(HANDLE_PROUD[0], HANDLE_NOISE x the plane's robust
#: noise) and less than HANDLE_PROUD[1] (m); a blob of at least `HANDLE_PIXELS` of them
#: (after an opening), at most `HANDLE_EXTENT` (m) across the door, is a handle
HANDLE_EDGE = 0.01
HANDLE_BEYOND = 0.06
HANDLE_PROUD = (0.012, 0.08)
HANDLE_NOISE = 2.5
HANDLE_PIXELS = 6
HANDLE_EXTENT = 0.06
#: a candidate votes in the test when its door is open less than this (rad): on a door
#: open further the residuals tell the sides apart, and a candidate on the wrong side
#: puts the door's outline where other surfaces stand proud of it (10 deg until
#: 2026-12-04: both sides' candidates read a panelled door open 2 deg as 11-12 deg)
HANDLE_Q_MAX = math.radians(15.0)
#: nor when its residual is more than this many times the best candidate's: a door open
#: far, seen by a candidate that has it closed, has its edge standing proud like a handle
HANDLE_RESIDUAL = 1.6
#: the door's plane is where the hypothesis puts it when this share of the points of its
#: outline's core (inset by `HANDLE_BEYOND` across the door: at its edges an oblique view
#: sees the body's side, or through a gap the body's inside, behind the door's plane in
#: its own coordinates) lie within the threshold of it; else the test abstains
HANDLE_PLANE_SHARE = 0.5
#: more of the door's outline than this share standing proud of its median plane is a
#: surface (a frame round a recessed window or panel), which the handle must stand proud of
HANDLE_SURFACE_SHARE = 0.15
#: the binary opening of the proud pixels (rows, columns): isolated noise and one-row
#: slivers along horizontal edges go, a vertical bar one pixel wide stays (a handle 1.5
#: cm thick 2 m away in the 192x108 camera)
HANDLE_OPENING = (2, 1)
#: a handle this far across the door from the hinge (as a share of its width) or further
#: is at the free edge
HANDLE_FREE = 0.65

#: the categories with a control panel beside the door's free edge, flush with the closed
#: door's front (`panel_side`)
PANEL_BESIDE = ("microwave",)
#: `_other_side` scores a door beside a control panel on the network's hinge side at the
#: pose of the other side's winning candidate only when that door is open less than this
#: (rad): shut, both sides' doors are the same flat front
PANEL_MIRROR_Q_MAX = math.radians(5.0)
#: in `panel_side`, how far a candidate's control panel reads recessed: the median of
#: (observed - rendered) depth over its pixels (the middle `PANEL_ROWS` of its height,
#: at least `MIN_PANEL_PIXELS`); a side is named when the other side's panel reads
#: recessed by more than `PANEL_RECESS` (m) and its own less than that (flush or proud)
#: and at least `PANEL_MARGIN` (m) less, both candidates' doors open less than
#: `PANEL_Q_MAX`. Only a recess counts: a door a few degrees open stands proud before the
#: panel's end of the front, so a candidate whose panel lies there reads it proud
#: whichever side is right
PANEL_RECESS = 0.003
PANEL_MARGIN = 0.004
PANEL_Q_MAX = math.radians(8.0)
PANEL_ROWS = (0.2, 0.8)
MIN_PANEL_PIXELS = 10
#: in `seam_profile`: rows sampled over the middle `PANEL_ROWS` of the front's height, the
#: front's width in bins; a pixel is deep when missing or more than `SEAM_DEEP` (m)
#: behind its row's running median (over a twelfth of the front's width: a seam a few
#: pixels wide does not move it, an oblique front's slope does); the median filter runs
#: on the row with its missing pixels filled from their neighbours
SEAM_ROWS = 32
SEAM_BINS = 48
SEAM_DEEP = 0.02
#: in `seam_side`: a seam is a run of at most `SEAM_WIDTH` bins, each deep on at least
#: `SEAM_SHARE` of the rows, inside the front (between the first and last bins deep on
#: fewer than half: beyond them lie the background and a side face); at `SEAM_AT` of the
#: front's width from its left end (as the image shows it: the +y end) it names hinge
#: side +1 (the panel at +y), from its right end -1. A door open further than
#: `HANDLE_Q_MAX` shows its own edges as seams
SEAM_WIDTH = 3
SEAM_SHARE = 0.6
SEAM_AT = (0.1, 0.4)
#: in `front_profile`: the front's depth in `SEAM_BINS` bins across it, the median of the
#: image's points within `FRONT_BAND` (m) of the front's plane over the middle `PANEL_ROWS`
#: of its height, a bin counted with at least `MIN_BIN_POINTS` points, a profile with at
#: least `FRONT_SEEN` of its bins
FRONT_BAND = 0.1
MIN_BIN_POINTS = 5
FRONT_SEEN = 0.75
#: in `front_fit`: the door's share of the front tried (the rest is the control panel)
FRONT_DOOR_SHARES = tuple(float(v) for v in np.linspace(0.6, 0.85, 11))
#: in `front_fit`: the robust fit's residuals capped at `FRONT_CAP` (m), its deviations
#: floored at `FRONT_FLOOR` (m)
FRONT_CAP = 0.02
FRONT_FLOOR = 0.002
#: in `front_side`: a side is named when the other side's fit is `FRONT_RATIO` times worse
FRONT_RATIO = 1.5

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Hypothesis:
    """One object hypothesis: base pose, geometry, hinge side and configuration (one q
    per movable joint, in joint order)."""

    x: float
    y: float
    z: float
    yaw: float
    depth: float
    width: float
    height: float
    chirality: int
    qs: tuple[float, ...]
    joint_type: str = "revolute"
    #: how far the doors' bottom edge stands above the base (m): a plinth or kick plate
    #: under the front, which the box model does not have (`_lift`). It moves the joint
    #: origins of the label up (`PosedRenderer.label`), not the rendered box
    lift: float = 0.0

    @classmethod
    def from_label(
        cls, label: Array, columns: list[str], joint_type: str = "revolute"
    ) -> Hypothesis:
        """From a label vector (L,) with `columns` (docs/formats.md); sizes floored at
        10 cm (an object's walls need room), each q clipped to its range (`q_max`)."""
        v = dict(zip(columns, np.asarray(label, dtype=np.float64).tolist(), strict=True))
        depth = max(v["depth"], 0.1)
        top = q_max(joint_type, depth)
        qs = tuple(float(np.clip(v[f"j{j}_q"], 0.0, top)) for j in range(joint_count(columns)))
        return cls(
            v["pose_x"], v["pose_y"], v["pose_z"], v["pose_yaw"],
            depth, max(v["width"], 0.1), max(v["height"], 0.1),
            1 if v["chirality"] >= 0 else -1, qs, joint_type,
        )  # fmt: skip

    def with_pose(
        self, x: float, y: float, z: float, yaw: float, qs: tuple[float, ...]
    ) -> Hypothesis:
        return dataclasses.replace(self, x=x, y=y, z=z, yaw=yaw, qs=qs)

    def mirrored(self) -> Hypothesis:
        """The other hinge side, all else equal."""
        return dataclasses.replace(self, chirality=-self.chirality)

    def reflected(self) -> Hypothesis:
        """The mirror image about the vertical plane through the camera and the base: the
        other hinge side, the yaw reflected about the line of sight (what a network that
        read an object's mirror image would have seen turned the other way)."""
        bearing = math.atan2(self.y, self.x)
        return dataclasses.replace(self, yaw=2 * bearing - self.yaw)

    def pose_matrix(self) -> Array:
        """(4, 4) object-to-camera transform."""
        return make_transform(rot_z(self.yaw), np.array([self.x, self.y, self.z]))

    def door_poses(self, joints: Sequence[Joint]) -> list[Array]:
        """(4, 4) each door's (or the drawer's) link pose in the camera frame, `joints`
        the object's movable joints: each turned about (or moved along) its axis by its q."""
        pose = self.pose_matrix()
        return [pose @ j.origin @ j.motion(q) for j, q in zip(joints, self.qs, strict=True)]

    def spec(self, category: str, parts: PartsConfig) -> ObjectSpec:
        limits = ((0.0, q_max(self.joint_type, self.depth)),) * len(self.qs)
        return ObjectSpec(
            category=category, index=0, dof=len(self.qs), joint_type=self.joint_type,
            depth=self.depth, width=self.width, height=self.height, chirality=self.chirality,
            pose=Pose(x=self.x, y=self.y, z=self.z, yaw=self.yaw),
            joint_limits=limits, parts=parts,
        )  # fmt: skip


def joint_count(columns: Sequence[str]) -> int:
    """The number of movable joints a label's `columns` describe (one `j<j>_q` each)."""
    return sum(1 for c in columns if re.fullmatch(r"j\d+_q", c))


def q_max(joint_type: str, depth: float) -> float:
    """The largest q a refinement returns: `Q_MAX` for a door, the object's depth for a
    drawer (it cannot come out further than it is long)."""
    return depth if joint_type == "prismatic" else Q_MAX


@dataclass(frozen=True)
class Candidate:
    """One refined candidate: where it started (component, hinge side), its residual."""

    component: int
    weight: float
    chirality: int
    residual: float
    inside_interval: bool
    label: Array
    #: the refined hypothesis the label is of
    hypothesis: Hypothesis | None = None
    #: a quarter turn from the chosen candidate (`_turned`)
    turned: bool = False


@dataclass(frozen=True)
class Refinement:
    """The refined estimate (L,) (the network's when not refined), what happened
    (`status`), the network's and the returned estimate's residuals (m) and the
    candidates tried."""

    label: Array
    refined: bool
    status: str
    residual_network: float
    residual_refined: float
    candidates: tuple[Candidate, ...]

    def as_json(self) -> dict[str, Any]:
        """The `refinement` field of `artic predict`'s JSON."""
        return {
            "status": self.status,
            "refined": self.refined,
            "residual_network": _rounded(self.residual_network),
            "residual_refined": _rounded(self.residual_refined),
            "candidates": [
                {
                    "component": c.component,
                    "weight": round(c.weight, 6),
                    "chirality": c.chirality,
                    "residual": _rounded(c.residual),
                    "inside_interval": c.inside_interval,
                    "turned": c.turned,
                }
                for c in self.candidates
            ],
        }


def _rounded(value: float) -> float | None:
    return round(value, 6) if math.isfinite(value) else None


def depth_residual(rendered: NDArray[np.floating], observed: NDArray[np.floating]) -> float:
    """Mean over the union of the valid (> 0) pixels of |rendered - observed| capped at
    `RESIDUAL_CAP` metres; a pixel valid in one image only counts the cap. inf when
    neither has a pixel. Computed on the rows and columns the union spans (the same
    pixels in the same order as on the whole image: the same number, ~3x faster)."""
    r, o = rendered > 0, observed > 0
    union = r | o
    rows, cols = np.flatnonzero(union.any(axis=1)), np.flatnonzero(union.any(axis=0))
    if len(rows) == 0:
        return math.inf
    span = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    diff = np.minimum(np.abs(rendered[span].astype(np.float64) - observed[span]), RESIDUAL_CAP)
    diff = np.where((r & o)[span], diff, RESIDUAL_CAP)
    return float(diff[union[span]].mean())


class PosedRenderer:
    """Renders one object geometry (depth, width, height, chirality) at any base pose
    and q with the raycast backend, building the object and its ray-casting scenes once.

    The raycast backend keeps its scenes for the last geometry it saw (links and joints
    by identity), built in each rigid group's own frame, independent of the base pose;
    building them costs ~10-30 ms an object here against ~1 ms for an image. So each
    render is of `dataclasses.replace(object, base_pose=...)`, which shares the links and
    reuses the scenes. A test checks the images equal those of a freshly built object at
    the same pose."""

    def __init__(self, hypothesis: Hypothesis, category: str, parts: PartsConfig,
                 camera: CameraIntrinsics, threads: int = 1) -> None:  # fmt: skip
        from artic.objects.categories import build
        from artic.render.raycast import RaycastBackend

        self.geometry = (hypothesis.depth, hypothesis.width, hypothesis.height)
        self.chirality = hypothesis.chirality
        self.object: ArticulatedObject = build(hypothesis.spec(category, parts))
        self.backend = RaycastBackend(camera, threads=threads)
        #: the doors' (or the drawer's) joints, in joint order
        self.joints = self.object.movable_joints
        self.doors = tuple(_Door.of(self.object, joint) for joint in self.joints)
        self.parts = parts
        self.door_thickness = parts.door_thickness
        #: the body shell's wall: its inner faces (`_Faces.back`, `inner`) in from its outer
        self.wall = parts.panel_thickness

    def fits(self, h: Hypothesis) -> bool:
        return (h.depth, h.width, h.height) == self.geometry and h.chirality == self.chirality

    def render(self, h: Hypothesis) -> tuple[RenderedImage, list[Array]]:
        """The image of `h` and each door link's pose (4, 4)."""
        return self.render_many([h])[0], h.door_poses(self.joints)

    def render_many(self, hs: Sequence[Hypothesis]) -> list[RenderedImage]:
        """The images of `hs` (this geometry each), cast together (`render_posed`): the
        same images as rendering each one alone."""
        if not all(self.fits(h) for h in hs):
            raise ValueError("PosedRenderer: another geometry or hinge side")
        qs = np.array([h.qs for h in hs], dtype=np.float64)
        return self.backend.render_posed(self.object, [h.pose_matrix() for h in hs], qs)

    def render_stretched(self, hs: Sequence[Hypothesis]) -> list[RenderedImage]:
        """The images of `hs` (this hinge side; any depth, width and height), each drawn
        from this object with its body frame scaled to its sizes (`RaycastBackend.
        render_posed`'s stretches): no object built, but walls, gaps and the doors'
        thickness scale with the body (a few millimetres at the sizes' spread), so the
        images are near, not equal to, those of objects built at the sizes. For searches
        over a size; what they find is judged on a built object."""
        if any(h.chirality != self.chirality for h in hs):
            raise ValueError("PosedRenderer: another hinge side")
        qs = np.array([h.qs for h in hs], dtype=np.float64)
        scales = np.array([[h.depth, h.width, h.height] for h in hs]) / np.array(self.geometry)
        return self.backend.render_posed(self.object, [h.pose_matrix() for h in hs], qs, scales)

    def label(self, h: Hypothesis, category: str, columns: list[str]) -> Array:
        """The label vector (L,) of `h` in `columns` order, every column consistent with
        the object (`objects.labels.image_labels`)."""
        from artic.objects.labels import image_labels

        if not self.fits(h):
            raise ValueError("PosedRenderer: another geometry or hinge side")
        posed = dataclasses.replace(self.object, base_pose=h.pose_matrix())
        labels = image_labels(h.spec(category, self.parts), posed, np.array(h.qs))
        label = np.array([labels[c] for c in columns], dtype=np.float64)
        for j in range(joint_count(columns)):  # the doors stand `lift` above the base
            label[columns.index(f"j{j}_origin_z")] += h.lift
        return label

    def close(self) -> None:
        self.backend.close()


@dataclass(frozen=True)
class _Door:
    """What the fits need of one movable joint: its frame's point in the body frame (3,),
    the part mask's value for its link (`RenderedImage.part_mask`), the sign of its axis
    along the body's z (a door's normal is the body front's turned by sign x q about z),
    whether its link stands on the base (its faces end at the bottom edge), and its axis
    in the body frame (3,): vertical for a door on a side hinge, along y for a flap hinged
    at its bottom edge (the toaster's), along x for a drawer."""

    origin: Array
    part: int
    sign: int
    at_base: bool
    axis: Array
    #: the x of its link's front face in its own frame: a drawer's front is at 0 (inset)
    #: or -thickness (an overlay front, `PartsConfig.drawer_front`)
    front: float = 0.0

    @classmethod
    def of(cls, obj: ArticulatedObject, joint: Joint) -> _Door:
        names = [link.name for link in obj.links]
        axis = joint.origin[:3, :3] @ joint.axis
        origin = joint.origin[:3, 3].copy()
        link = obj.links[names.index(joint.child)]
        return cls(origin, names.index(joint.child) + 1, 1 if float(axis[2]) >= 0 else -1,
                   abs(float(origin[2])) < FACE_EPS, axis,
                   float(link.mesh.vertices[:, 0].min()))  # fmt: skip

    @property
    def flap(self) -> bool:
        """A door hinged at a horizontal edge (its axis across the front)."""
        return abs(float(self.axis[1])) > 0.5

    def turn(self, q: float) -> Array:
        """(3, 3) the door's rotation in the body frame at q (a side-hinged door's about
        z, a flap's about its horizontal axis)."""
        return axis_angle(self.axis, q) if self.flap else rot_z(self.sign * q)


@dataclass(frozen=True)
class _Faces:
    """Observed points (N, 3) of each face, with each point's face offset (N,) (the
    coordinate the rendered pixel has across its face, in the object's or door's frame)."""

    front: tuple[Array, Array]
    side: tuple[Array, Array]
    #: the base's height (camera z) read at each bottom silhouette edge pixel (K,)
    bottom: Array
    #: the height (camera z) of the bottom edge of the broad faces of the doors standing
    #: on the base, per image column of each face (`_face_bottoms`; K,)
    door_bottom: Array
    #: each door's broad faces (or the drawer's front), in joint order
    doors: tuple[tuple[Array, Array], ...]
    #: the body's inside seen through an opened door: its back wall's inner face (each
    #: point's object x) and its side walls' inner faces (object y); parallel to the
    #: front and the side, they turn with the body's yaw and not with the door
    back: tuple[Array, Array] = (np.zeros((0, 3)), np.zeros(0))
    inner: tuple[Array, Array] = (np.zeros((0, 3)), np.zeros(0))


def _faces(
    h: Hypothesis,
    image: RenderedImage,
    door_poses: Sequence[Array],
    doors: Sequence[_Door],
    observed: NDArray[np.floating],
    rays: NDArray[np.float32],
    tolerance: float,
    thickness: float,
    wall: float = 0.0,
) -> _Faces:
    """Group the observed pixels near the rendered hypothesis by the rendered face (the
    body's inner faces with its shell's `wall` thickness, none when 0)."""
    rendered, mask = image.depth, image.part_mask
    both = (rendered > 0) & (observed > 0) & (np.abs(observed - rendered) < DEPTH_GATE)
    rows, cols = np.nonzero(both)
    d = rays[rows, cols].astype(np.float64)
    p_rendered = d * rendered[rows, cols, None].astype(np.float64)
    p_observed = d * observed[rows, cols, None].astype(np.float64)
    pose = h.pose_matrix()
    # object-frame and door-frame coordinates of the rendered and the observed points
    body = (p_rendered - pose[:3, 3]) @ pose[:3, :3]
    body_seen = (p_observed - pose[:3, 3]) @ pose[:3, :3]
    part = mask[rows, cols]
    is_body = part == 1

    def near(frame: Array, seen: Array, axis: int) -> NDArray[np.bool_]:
        # point to plane, not depth: a face seen at a grazing angle moves far along the ray
        return np.asarray(np.abs(seen[:, axis] - frame[:, axis]) < tolerance)

    front = is_body & (body[:, 0] < -h.depth / 2 + FACE_EPS)
    side = is_body & ~front & (np.abs(body[:, 1]) > h.width / 2 - FACE_EPS)
    inside = is_body & ~front & ~side & (wall > 0)
    back = inside & (np.abs(body[:, 0] - (h.depth / 2 - wall)) < FACE_EPS)
    inner = inside & (np.abs(np.abs(body[:, 1]) - (h.width / 2 - wall)) < FACE_EPS)
    ends_at_base = front | side
    door_faces = []
    door_level: list[NDArray[np.bool_]] = []
    door_frames: list[Array] = []
    for door_pose, door in zip(door_poses, doors, strict=True):
        local = (p_rendered - door_pose[:3, 3]) @ door_pose[:3, :3]
        local_seen = (p_observed - door_pose[:3, 3]) @ door_pose[:3, :3]
        if h.joint_type == "prismatic":
            # a drawer's front (x = 0 in its frame, an overlay front's -thickness); its
            # bottom is above the base
            on = (part == door.part) & (np.abs(local[:, 0] - door.front) < FACE_EPS)
        else:
            # either broad face of a door: its front (x = -thickness) or, opened far, its back
            on = (part == door.part) & (
                (np.abs(local[:, 0] + thickness) < FACE_EPS) | (np.abs(local[:, 0]) < FACE_EPS)
            )
            if door.at_base:
                ends_at_base = ends_at_base | on
        on &= near(local, local_seen, 0)
        if door.at_base and h.joint_type == "revolute" and not door.flap:
            broad_front = np.abs(local[:, 0] + thickness) < FACE_EPS
            door_level += [on & broad_front, on & ~broad_front]
            door_frames += [door_pose, door_pose]
        door_faces.append((p_observed[on], local[on, 0]))
    front &= near(body, body_seen, 0)
    side &= near(body, body_seen, 1)
    back &= near(body, body_seen, 0)
    inner &= near(body, body_seen, 1)
    # a flap's base height is searched on the residual instead (`search_height`)
    bottom = (np.zeros(0) if any(door.flap for door in doors)
              else _bottom_edge(rows, cols, ends_at_base, observed, rendered, rays))  # fmt: skip
    door_bottoms = [_face_bottoms(rows[m], cols[m], frame, observed, rays)
                    for m, frame in zip(door_level, door_frames, strict=True)]  # fmt: skip
    return _Faces(
        (p_observed[front], body[front, 0]),
        (p_observed[side], body[side, 1]),
        bottom,
        np.concatenate([np.zeros(0), *door_bottoms]),
        tuple(door_faces),
        (p_observed[back], body[back, 0]),
        (p_observed[inner], body[inner, 1]),
    )


def _face_bottoms(
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    frame: Array,
    observed: NDArray[np.floating],
    rays: NDArray[np.float32],
) -> Array:
    """The height (camera z, m) of one face's bottom edge in each image column of its
    observed pixels (`rows`, `cols`; the face is the plane x = const of `frame` (4, 4),
    at the median x of those pixels): down the column from its lowest pixel, the face goes
    on while the points lie within `LIFT_TOLERANCE` of its plane (one pixel off it, the
    sensor's noise, does not end it); the edge is its last pixel's lower edge (as
    `_bottom_edge`). Below it the background or a surface behind the face's plane: a
    plinth recessed behind a door, which the box model does not have. A column where a
    nearer surface hides the face's bottom (the body in front of an opened door's lower
    part) or whose face reaches the image's bottom border does not count."""
    height = observed.shape[0]
    if len(rows) < MIN_FACE_POINTS or height < 3:
        return np.zeros(0)

    def local_x(r: NDArray[np.intp], c: NDArray[np.intp]) -> Array:
        p = rays[r, c].astype(np.float64) * observed[r, c, None]
        return np.asarray((p - frame[:3, 3]) @ frame[:3, 0])

    plane = float(np.median(local_x(rows, cols)))
    lowest = np.full(observed.shape[1], -1)
    np.maximum.at(lowest, cols, rows)
    col = np.flatnonzero(lowest >= 0)

    def on_face(r: NDArray[np.intp]) -> NDArray[np.bool_]:
        near = np.abs(local_x(r, col) - plane) < LIFT_TOLERANCE
        return np.asarray((observed[r, col] > 0) & near)

    end = lowest[col]
    running = np.ones(len(col), dtype=bool)
    for _ in range(height):
        # the next pixel on the face, or (one noisy pixel) the one after it
        one, two = np.minimum(end + 1, height - 1), np.minimum(end + 2, height - 1)
        on_one, on_two = on_face(one), on_face(two) & (end + 2 < height)
        running &= (end + 1 < height) & (on_one | on_two)
        if not running.any():
            break
        end = np.where(running, np.where(on_two, two, one), end)
    below = np.minimum(end + 1, height - 1)
    # what ends the face: the background, or a point behind its plane (seen from the camera)
    normal, ray = frame[:3, 0], rays[below, col].astype(np.float64)
    along = ray @ normal  # the plane's depth on the ray below: (plane + t . n) / (ray . n)
    plane_depth = (plane + float(frame[:3, 3] @ normal)) / np.where(along == 0, np.nan, along)
    depth = observed[below, col].astype(np.float64)
    behind = (depth <= 0) | (depth > plane_depth + LIFT_TOLERANCE)
    step = float(rays[1, 0, 2] - rays[0, 0, 2])
    z = (rays[end, col, 2].astype(np.float64) + 0.5 * step) * observed[end, col]
    return np.asarray(z[(end + 1 < height) & behind])


def _bottom_edge(
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    on_face: NDArray[np.bool_],
    observed: NDArray[np.floating],
    rendered: NDArray[np.floating],
    rays: NDArray[np.float32],
) -> Array:
    """The height of the object's base (camera z, m) read at each bottom silhouette edge.

    Per image column: the lowest face pixel, then down the observed column to its last
    return before the background, at most `EDGE_ROWS` rows further; the column counts
    when the rendered hypothesis also ends within `EDGE_ROWS` rows below that face pixel
    (an edge, not a hole in the face or a face running on). Every face the groups hold
    (the body's front and sides, the door) ends at the base (object z = 0); a vertical
    face keeps its depth down a pixel column, so the edge, half a pixel below the last
    return's centre, lies at z = -(v + 1/2 - cy) / fy * depth."""
    height = observed.shape[0]
    r, c = rows[on_face], cols[on_face]
    if len(r) == 0:
        return np.zeros(0)
    lowest = np.full(observed.shape[1], -1)
    np.maximum.at(lowest, c, r)
    col = np.flatnonzero(lowest >= 0)
    top = lowest[col]
    ends = np.zeros(len(col), dtype=bool)
    last = top.copy()
    running = np.ones(len(col), dtype=bool)
    for k in range(1, EDGE_ROWS + 2):
        row = np.minimum(top + k, height - 1)
        inside = top + k < height
        ends |= inside & (rendered[row, col] <= 0) & (k <= EDGE_ROWS)
        valid = inside & (observed[row, col] > 0)
        last = np.where(running & valid, top + k, last)
        running &= valid
    # an edge: the return ends (not at the image border) within EDGE_ROWS rows
    edge = ends & ~running & (last + 1 < height)
    r, c = last[edge], col[edge]
    step = float(rays[1, 0, 2] - rays[0, 0, 2]) if height > 1 else 0.0
    z_dir = rays[r, c, 2].astype(np.float64) + 0.5 * step
    return np.asarray(z_dir * observed[r, c], dtype=np.float64)


def _ransac(points: Array, seed: int) -> NDArray[np.bool_]:
    """Inliers (N,) of the dominant plane (Open3D's RANSAC, seeded, on one OpenMP thread:
    its threads draw their samples in whatever order they run, so on more than one the
    inliers, and the refined estimate, change from run to run); all False below
    `MIN_FACE_POINTS` points."""
    keep = np.zeros(len(points), dtype=bool)
    if len(points) < MIN_FACE_POINTS:
        return keep
    from artic.render.open3d_core import open3d_core

    o3d = open3d_core()
    o3d.utility.random.seed(seed)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    # ~0.04 ms; on a busy 2-core host ~0.1 ms a fit instead of ~6 ms of thread start-up
    with _threadpools().limit(limits=1, user_api="openmp"):
        _, inliers = cloud.segment_plane(RANSAC_DISTANCE, 3, RANSAC_ITERATIONS)
    keep[np.asarray(inliers, dtype=np.int64)] = True
    return keep if keep.sum() >= MIN_FACE_POINTS else np.zeros(len(points), dtype=bool)


def _group_means(points: Array, offsets: Array, keep: NDArray[np.bool_]) -> Array:
    """(N, 2) the mean horizontal position of the kept points on each point's parallel
    plane (the same face offset to the millimetre: a control panel 2 cm before the body's
    rim, a door's front and back); 0 for a plane with no kept point."""
    if len(points) == 0:
        return np.zeros((0, 2))
    _, group = np.unique(np.round(offsets * 1000.0), return_inverse=True)
    weight = keep.astype(np.float64)
    count = np.maximum(np.bincount(group, weight), 1.0)
    means = np.stack([np.bincount(group, weight * points[:, a]) / count for a in range(2)], axis=1)
    return np.asarray(means[group])


def _scatter(points: Array, offsets: Array) -> Array:
    """(2, 2) scatter of the points' horizontal coordinates, each set of points on one
    parallel plane about its own mean (`_group_means`), so that parallel planes do not
    tilt the fitted normal."""
    xy = points[:, :2] - _group_means(points, offsets, np.ones(len(points), dtype=bool))
    return np.asarray(xy.T @ xy)


def _line_residuals(face: tuple[Array, Array], keep: NDArray[np.bool_], n: Array) -> Array:
    """Signed distances (N,) of a face's points from their planes of normal `n` (2,), each
    plane through the mean of its kept points."""
    points, offsets = face
    return np.asarray((points[:, :2] - _group_means(points, offsets, keep)) @ n)


def _robust_normal(
    front: tuple[Array, Array],
    keep_front: NDArray[np.bool_],
    side: tuple[Array, Array],
    keep_side: NDArray[np.bool_],
) -> tuple[Array, NDArray[np.bool_], NDArray[np.bool_]]:
    """The front normal (2,) of a total least-squares fit over the `front` points and the
    perpendicular `side` points (`_scatter`), refitted after dropping the points farther
    than 3 robust standard deviations (at least `LINE_FLOOR`) from the fit (a neighbouring
    face's points that RANSAC kept, such as the top's along the front edge); the kept
    points of each."""
    kf, ks = keep_front.copy(), keep_side.copy()
    n = np.array([1.0, 0.0])
    for rounds in range(2):
        scatter = _scatter(front[0][kf], front[1][kf]) - _scatter(side[0][ks], side[1][ks])
        n = np.linalg.eigh(scatter)[1][:, 0]
        if rounds == 1:
            break
        rf = np.abs(_line_residuals(front, kf, n))
        rs = np.abs(_line_residuals(side, ks, np.array([-n[1], n[0]])))
        kept = np.concatenate([rf[kf], rs[ks]])
        limit = max(3.0 * 1.4826 * float(np.median(kept)), LINE_FLOOR)
        kf, ks = kf & (rf < limit), ks & (rs < limit)
        if kf.sum() + ks.sum() < MIN_FACE_POINTS:
            kf, ks = keep_front.copy(), keep_side.copy()
    return n, kf, ks


def _angle(v: Array) -> float:
    return math.atan2(float(v[1]), float(v[0]))


def _wrap(a: float) -> float:
    return math.pi - (math.pi - a) % (2 * math.pi)


def _fit_yaw(
    h: Hypothesis,
    front: tuple[Array, Array],
    keep_front: NDArray[np.bool_],
    side: tuple[Array, Array],
    keep_side: NDArray[np.bool_],
) -> tuple[float, NDArray[np.bool_], NDArray[np.bool_]]:
    """The yaw of the front's normal fitted with the perpendicular sides
    (`_robust_normal`), the hypothesis' when no point is kept or the fit turns it further
    than `MAX_YAW_STEP`; the kept points of each."""
    if keep_front.sum() + keep_side.sum() == 0:
        return h.yaw, keep_front, keep_side
    n, kf, ks = _robust_normal(front, keep_front, side, keep_side)
    outward = -np.array([math.cos(h.yaw), math.sin(h.yaw)])  # the front faces -x_object
    n = n if n @ outward >= 0 else -n
    fitted = _angle(-n)
    return (fitted if abs(_wrap(fitted - h.yaw)) <= MAX_YAW_STEP else h.yaw), kf, ks


def _fit(
    h: Hypothesis, faces: _Faces, doors: Sequence[_Door], seed: int, rim: bool = True
) -> Hypothesis:
    """One least-squares step (module docstring, step 2) from the grouped points; a
    drawer's without its body's front rim unless `rim` (`refine_hypothesis`)."""
    inl_front, inl_side, inl_doors = _face_inliers(faces, seed)
    if h.joint_type == "prismatic":
        if not rim:
            inl_front = np.zeros_like(inl_front)
        return _fit_drawer(h, faces, inl_front, inl_side, inl_doors[0], doors[0].origin)
    # yaw from the body's vertical faces: front normal n minimises n'C_f n + n_perp'C_s n_perp,
    # the inner faces (seen through an opened door) with the front's and the side's planes
    inl_back, inl_inner = _inner_inliers(faces, seed)
    nf, ns = len(inl_front), len(inl_side)
    yaw, keep_x, keep_y = _fit_yaw(
        h, _joined(faces.front, faces.back), np.concatenate([inl_front, inl_back]),
        _joined(faces.side, faces.inner), np.concatenate([inl_side, inl_inner]),
    )  # fmt: skip
    inl_front, inl_side = keep_x[:nf], keep_y[:ns]
    rot = rot_z(yaw)
    rows: list[Array] = []
    rhs: list[Array] = []
    pts, offset = faces.front
    a = rot[:, 0]  # object x in the camera frame
    rows.append(np.tile(a, (int(inl_front.sum()), 1)))
    rhs.append(pts[inl_front] @ a - offset[inl_front])
    pts, offset = faces.side
    a = rot[:, 1]
    rows.append(np.tile(a, (int(inl_side.sum()), 1)))
    rhs.append(pts[inl_side] @ a - offset[inl_side])
    qs = list(h.qs)
    base = _base_height(h, faces)
    for j, (door, face, keep) in enumerate(zip(doors, faces.doors, inl_doors, strict=True)):
        # q from the door's front normal against the body's front (`_door_q`)
        if keep.sum() >= MIN_DOOR_POINTS:
            qs[j], keep = _door_q(door, face, keep, yaw, h.qs[j])
        # base position: each inlier on its face's plane
        a = (rot @ door.turn(qs[j]))[:, 0]  # the door's x: a . (p - t - R o_joint)
        pts, offset = face
        rows.append(np.tile(a, (int(keep.sum()), 1)))
        # a flap's normal tilts out of the horizontal: its part along z is the base height's
        rhs.append(pts[keep] @ a - a @ (rot @ door.origin) - offset[keep] - a[2] * base)
    # plus a pull towards the hypothesis
    prior = math.sqrt(PRIOR_WEIGHT)
    rows.append(prior * np.eye(3)[:2])
    rhs.append(prior * np.array([h.x, h.y]))
    # the base height held: the position across the faces is (x, y) alone
    t = np.linalg.lstsq(np.concatenate(rows)[:, :2], np.concatenate(rhs), rcond=None)[0]
    h = dataclasses.replace(h, lift=_lift(h, faces, base))
    return h.with_pose(float(t[0]), float(t[1]), base, yaw, tuple(qs))


def _door_q(
    door: _Door, face: tuple[Array, Array], keep: NDArray[np.bool_], yaw: float, q: float
) -> tuple[float, NDArray[np.bool_]]:
    """A door's q from its broad faces' points (`face`, RANSAC's `keep`) and the body's
    `yaw`: of the two readings of the fitted normal's sign, the one nearest the
    hypothesis' `q`, clipped to [0, `Q_MAX`]; and the points the robust fit kept. A
    side-hinged door's normal is horizontal, the body front's turned by sign x q about z
    (`_robust_normal` on the camera's horizontal coordinates); a flap's turns about its
    horizontal axis, so its normal is fitted in the object's (x, z) plane, across that
    axis."""
    no_side, none = (np.zeros((0, 3)), np.zeros(0)), np.zeros(0, dtype=bool)
    if not door.flap:
        n_door, keep, _ = _robust_normal(face, keep, no_side, none)
        options = [door.sign * _wrap(_angle(s * n_door) - (yaw + math.pi)) for s in (1.0, -1.0)]
    else:
        pts, offset = face
        rot = rot_z(yaw)
        # object-frame x and z first (`_robust_normal` fits in the first two coordinates)
        local = np.column_stack([pts @ rot[:, 0], pts[:, 2], pts @ rot[:, 1]])
        n_xz, keep, _ = _robust_normal((local, offset), keep, no_side, none)
        x0 = np.array([1.0, 0.0, 0.0])  # the door's x at q = 0, into the body
        options = []
        for s in (1.0, -1.0):
            n = s * np.array([n_xz[0], 0.0, n_xz[1]])
            options.append(math.atan2(float(np.cross(x0, n) @ door.axis), float(x0 @ n)))
    return float(np.clip(min(options, key=lambda v: abs(v - q)), 0.0, Q_MAX)), keep


def _face_inliers(
    faces: _Faces, seed: int
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], list[NDArray[np.bool_]]]:
    """RANSAC inliers (`_ransac`) of the body's front, its side and each door's faces."""
    inl_front = _ransac(faces.front[0], seed)
    inl_side = _ransac(faces.side[0], seed + 1)
    inl_doors = [_ransac(pts, seed + 2 + j) for j, (pts, _) in enumerate(faces.doors)]
    return inl_front, inl_side, inl_doors


def _inner_inliers(faces: _Faces, seed: int) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """RANSAC inliers (`_ransac`) of the body's inner back face and inner side faces."""
    after = seed + 2 + len(faces.doors)  # the seeds after `_face_inliers`'
    return _ransac(faces.back[0], after), _ransac(faces.inner[0], after + 1)


def _joined(*faces: tuple[Array, Array]) -> tuple[Array, Array]:
    """Faces' points and offsets (`_Faces`) as one face of parallel planes."""
    return (np.concatenate([f[0] for f in faces]), np.concatenate([f[1] for f in faces]))


def search_opening(
    h: Hypothesis, renderer: PosedRenderer, observed: NDArray[np.floating]
) -> Hypothesis:
    """What a drawer's planes leave open, searched on the depth residual, one line at a
    time. Its front's plane fixes where the front is, not how far the drawer is out: q
    and the base's distance along the object's x trade one for the other, so q is
    searched along that line (the front fixed, the base moved back by as much as the
    drawer comes out) over [0, `q_max`]; then the base's position along the front (the
    object's y, which no plane fixes when no side is in view) and its height (the bottom
    edge hides under an open drawer) within `SEARCH_SPAN` of the fit. The opening every
    `OPENING_STEP`, then a fifth of the step around the best, `OPENING_LEVELS` levels;
    the others every `SEARCH_STEP`, then a fifth of it; of equal residuals (a part the
    image does not show: the same render), the smallest move (`_search`)."""
    c, s = math.cos(h.yaw), math.sin(h.yaw)  # the object's x in the camera frame

    (q,) = h.qs

    def opening(d: float) -> Hypothesis:
        return h.with_pose(h.x + d * c, h.y + d * s, h.z, h.yaw, (q + d,))

    h = _line_search(opening, -q, q_max(h.joint_type, h.depth) - q, renderer, observed,
                     OPENING_STEP, levels=OPENING_LEVELS)  # fmt: skip

    def across(d: float) -> Hypothesis:
        return h.with_pose(h.x - d * s, h.y + d * c, h.z, h.yaw, h.qs)

    h = _line_search(across, -SEARCH_SPAN, SEARCH_SPAN, renderer, observed)

    return search_height(h, renderer, observed)


def search_height(
    h: Hypothesis,
    renderer: PosedRenderer,
    observed: NDArray[np.floating],
    span: float = SEARCH_SPAN,
) -> Hypothesis:
    """The base height of the lowest depth residual within `span` of `h`'s
    (`_line_search`): where the bottom edge does not give it (under an open drawer, whose
    bottom hides the body's edge below it; a toaster's, whose edge at this camera's pixel
    of 1-2 cm reads about 0.6 cm high and misses where an opened flap lies across it)."""

    def up(d: float) -> Hypothesis:
        return h.with_pose(h.x, h.y, h.z + d, h.yaw, h.qs)

    return _line_search(up, -span, span, renderer, observed)


def front_width(
    h: Hypothesis, observed: NDArray[np.floating], camera: CameraIntrinsics, thickness: float
) -> Hypothesis | None:
    """`h` with the width its front shows, the side facing the camera held in place (the
    base moved across by half the change); None when the front shows too little. A door
    hinged at its bottom edge turns about an axis across the front, so no door plane
    meets a side (`_fit_width`'s hinge): the side in view fixes where that side is, not
    how far the other one lies. The front does: the observed points within `WIDTH_BAND`
    of the front's plane (the closed door's face and the control panel's, `thickness`
    before the body; or the body's own rim, the door opened), over the body's height and
    within `WIDTH_SPAN` of its sides, reach across the front to its far edge against the
    background. That edge is their `WIDTH_QUANTILE` quantile towards the far side, half a
    pixel beyond (`_pixel_across`; `MIN_WIDTH_POINTS` at least)."""
    c, s = math.cos(h.yaw), math.sin(h.yaw)  # the object's y in the camera frame: (-s, c)
    seen = 1.0 if h.x * s - h.y * c > 0 else -1.0  # the side whose normal faces the camera
    local = _object_points(h, observed, camera)
    front = -h.depth / 2
    near = np.abs(local[:, 0] - (front - thickness)) < WIDTH_BAND
    near |= np.abs(local[:, 0] - front) < WIDTH_BAND
    near &= (local[:, 2] > 0.0) & (local[:, 2] < h.height)
    near &= np.abs(local[:, 1]) < h.width / 2 + WIDTH_SPAN
    if int(near.sum()) < MIN_WIDTH_POINTS:
        return None
    across = -seen * local[near, 1]  # towards the far side
    far = float(np.quantile(across, WIDTH_QUANTILE)) + 0.5 * _pixel_across(h, camera)
    width = max(far + h.width / 2, 0.1)  # the side in view lies at -h.width / 2 across
    d = width - h.width
    return dataclasses.replace(h, width=width, x=h.x + seen * d / 2 * s, y=h.y - seen * d / 2 * c)


def side_depth(
    h: Hypothesis, observed: NDArray[np.floating], camera: CameraIntrinsics
) -> Hypothesis | None:
    """`h` with the depth its side in view shows, the front held in place (the base moved
    back by half the change); None when that side shows too little (`MIN_WIDTH_POINTS`).
    The observed points within `WIDTH_BAND` of the side's plane, over the body's height,
    reach back along it to its far edge against the background: their `WIDTH_QUANTILE`
    quantile, half a pixel beyond (`_pixel_across`), as `front_width` reads the front's.
    None too when a point there lies on the image's border row or column: the side runs out
    of the image (an object near the camera), and its end is not the object's back."""
    c, s = math.cos(h.yaw), math.sin(h.yaw)
    seen = 1.0 if h.x * s - h.y * c > 0 else -1.0  # the side in view lies at y = seen w / 2
    local = _object_points(h, observed, camera)
    near = np.abs(local[:, 1] - seen * h.width / 2) < WIDTH_BAND
    near &= (local[:, 2] > 0.0) & (local[:, 2] < h.height)
    near &= (local[:, 0] > -h.depth / 2) & (local[:, 0] < h.depth / 2 + WIDTH_SPAN)
    if int(near.sum()) < MIN_WIDTH_POINTS:
        return None
    edge = float(np.quantile(local[near, 0], WIDTH_QUANTILE))
    rows, cols = np.nonzero(np.where(np.isfinite(observed), observed, 0) > 0)  # local's pixels
    at_edge = near & (local[:, 0] >= edge)
    if (
        rows[at_edge].min() == 0
        or cols[at_edge].min() == 0
        or rows[at_edge].max() == camera.height - 1
        or cols[at_edge].max() == camera.width - 1
    ):
        return None
    far = edge + 0.5 * _pixel_across(h, camera, side=True)
    depth = max(far + h.depth / 2, 0.1)  # the front lies at -h.depth / 2
    d = depth - h.depth
    return dataclasses.replace(h, depth=depth, x=h.x + d / 2 * c, y=h.y + d / 2 * s)


def _object_points(h: Hypothesis, depth: NDArray[np.floating], camera: CameraIntrinsics) -> Array:
    """(N, 3) the valid pixels of `depth` (H, W metres in `camera`; NaN is no return)
    back-projected (`CameraIntrinsics.back_project`), in `h`'s object frame."""
    pose = h.pose_matrix()
    image = np.where(np.isfinite(depth), depth, 0)
    return np.asarray((camera.back_project(image) - pose[:3, 3]) @ pose[:3, :3])


def _pixel_across(h: Hypothesis, camera: CameraIntrinsics, side: bool = False) -> float:
    """One pixel's width across `h`'s front (m; along its side in view with `side`): a
    pixel at the object's distance over the cosine of the angle between the line of sight
    and the face's normal (at most 5x; the side's normal is the front's turned a quarter)."""
    angle = h.yaw - math.atan2(h.y, h.x)
    incidence = max(abs(math.sin(angle) if side else math.cos(angle)), 0.2)
    return math.hypot(h.x, h.y) / camera.fx / incidence


def flap_panel_share(
    h: Hypothesis,
    door: _Door,
    observed: NDArray[np.floating],
    camera: CameraIntrinsics,
    parts: PartsConfig,
) -> float | None:
    """The share of the front's width a control panel beside an opened flap takes, read
    off the door's edge on the panel's side; None below `FLAP_OPEN_Q` (a closed door
    lies in the panel's plane: nothing in the depth separates them) or when the door shows
    too little. The points within `WIDTH_BAND` of either of the door's broad faces over
    the upper part of its height (`PANEL_SHARE_ROWS`) and out of the panel's plane by as
    much (near the hinge the door still lies in it) give its edge as their
    `WIDTH_QUANTILE` quantile towards the panel, half a pixel beyond; the panel is what
    lies past that edge and a `gap`. The share is clipped to `PANEL_SHARES`."""
    (q,) = h.qs
    if q < FLAP_OPEN_Q:
        return None
    body = _object_points(h, observed, camera)
    local = (body - door.origin) @ door.turn(q)  # the door's frame: x its normal, z up it
    thick = parts.door_thickness
    on = (np.abs(local[:, 0] + thick) < WIDTH_BAND) | (np.abs(local[:, 0]) < WIDTH_BAND)
    low, high = PANEL_SHARE_ROWS
    on &= (local[:, 2] > low * h.height) & (local[:, 2] < high * h.height)
    on &= np.abs(body[:, 1]) < h.width / 2 + WIDTH_BAND
    on &= body[:, 0] < -h.depth / 2 - thick - WIDTH_BAND  # out of the panel's plane
    if int(on.sum()) < MIN_WIDTH_POINTS:
        return None
    panel = -1.0 if float(door.origin[1]) > 0 else 1.0  # the panel's side of the door
    edge = float(np.quantile(panel * body[on, 1], WIDTH_QUANTILE)) + 0.5 * _pixel_across(h, camera)
    share = (h.width / 2 - edge - parts.gap) / h.width
    return float(np.clip(share, *PANEL_SHARES))


def _line_search(
    move: Callable[[float], Hypothesis],
    low: float,
    high: float,
    renderer: PosedRenderer,
    observed: NDArray[np.floating],
    step: float = SEARCH_STEP,
    ends: bool = False,
    levels: int = 2,
) -> Hypothesis:
    """`move(d)` of the lowest depth residual for d in [low, high] (`_search`, each value's
    image cast with `renderer`)."""

    def residuals(values: Array) -> list[float]:
        images = renderer.render_many([move(float(d)) for d in values])
        return [depth_residual(image.depth, observed) for image in images]

    return move(_search(residuals, low, high, step, ends, levels))


def _search(
    residuals: Callable[[Array], Sequence[float]],
    low: float,
    high: float,
    step: float,
    ends: bool = False,
    levels: int = 2,
) -> float:
    """The d in [low, high] (0 included, and with `ends` low and high too) of the lowest
    of `residuals(values)`: every `step`, then `levels` - 1 times every fifth of the last
    step within four of them of the best; of equal residuals (a part the image does not
    show: the same render), the smallest move."""

    known: dict[float, float] = {}  # each pass's middle value is the last pass's best

    def best(values: Array) -> float:
        new = [float(v) for v in values if float(v) not in known]
        if new:
            known.update(zip(new, residuals(np.array(new)), strict=True))
        scores = np.array([known[float(v)] for v in values])
        return float(values[np.lexsort((np.abs(values), scores))[0]])

    coarse = np.unique(np.concatenate([np.arange(0.0, low - 1e-9, -step),
                                       np.arange(0.0, high + 1e-9, step),
                                       [low, high] if ends else []]))  # fmt: skip
    d = best(coarse)
    for _ in range(levels - 1):
        fine = d + np.arange(-4, 5) * step / 5
        d = best(fine[(fine >= low) & (fine <= high)])
        step = step / 5
    return d


def _base_height(h: Hypothesis, faces: _Faces) -> float:
    """The base height (camera z) off the bottom silhouette edge's readings, their
    `EDGE_QUANTILE` quantile (the edge pixels the sensor lost read high); `h`'s own below
    `MIN_EDGE_PIXELS` readings (the base out of the image, or hidden)."""
    if len(faces.bottom) < MIN_EDGE_PIXELS:
        return h.z
    return float(np.quantile(faces.bottom, EDGE_QUANTILE))


def _lift(h: Hypothesis, faces: _Faces, base: float) -> float:
    """How far the doors stand above the `base` height (camera z) the bottom silhouette
    edge gave (`_bottom_edge`): the bottom edge of the doors' broad faces, its
    `EDGE_QUANTILE` quantile over the columns as the base's (`_face_bottoms`; not the
    body's front: a plinth recessed 3 cm behind it is within the
    noise's reach of its plane, where behind a door it is a door's thickness further)
    minus the base; 0 below `MIN_LIFT` (the sensor's noise on an object with no plinth)
    and above `MAX_LIFT` (no plinth or kick plate is that tall: a misread); the hypothesis'
    own lift below `MIN_EDGE_PIXELS` columns or when the edges' interquartile range exceeds
    `LIFT_SPREAD` (a door's bottom edge is level, so its columns agree to a pixel or two).
    Legs or a wall-hung cabinet lift nothing: the doors' bottom is the silhouette's there,
    and the base reads there too."""
    edges = faces.door_bottom
    if len(edges) < MIN_EDGE_PIXELS:
        return h.lift
    low, high = np.quantile(edges, [0.25, 0.75])
    if high - low > LIFT_SPREAD:  # a door's bottom edge is level: these edges are not it
        return h.lift
    lift = float(np.quantile(edges, EDGE_QUANTILE)) - base  # as the base: lost edge pixels
    return lift if MIN_LIFT <= lift <= MAX_LIFT else 0.0


def _fit_drawer(
    h: Hypothesis,
    faces: _Faces,
    inl_front: NDArray[np.bool_],
    inl_side: NDArray[np.bool_],
    inl_drawer: NDArray[np.bool_],
    joint_origin: Array,
) -> Hypothesis:
    """One least-squares step for a drawer. Its front is parallel to the body's, so the
    yaw comes from the body's front rim, the drawer's front (each on its own parallel
    plane) and a side; then the base position (x, y) and the opening q together, by least
    squares: the rim on x = -depth/2, a side on y = +-width/2 and the drawer's front on
    x = -depth/2 - q (object frame), with a pull towards the hypothesis (q's only keeps
    the system's rank: a drawer front with no rim in view moves the base, not q)."""
    pts_f, off_f = faces.front
    (pts_d, off_d), (q,) = faces.doors[0], h.qs
    n_front = len(pts_f)
    # the drawer front's plane in the object frame: its own frame's x plus the joint's
    ahead = float(joint_origin[0]) - q
    fronts = (np.concatenate([pts_f, pts_d]), np.concatenate([off_f, off_d + ahead]))
    yaw, kept, inl_side = _fit_yaw(h, fronts, np.concatenate([inl_front, inl_drawer]),
                                   faces.side, inl_side)  # fmt: skip
    inl_front, inl_drawer = kept[:n_front], kept[n_front:]
    rot = rot_z(yaw)
    a, b = rot[:, 0], rot[:, 1]  # object x and y in the camera frame
    rows: list[Array] = []
    rhs: list[Array] = []
    for (pts, offset), keep, axis, q_coef in (
        (faces.front, inl_front, a, 0.0),
        (faces.side, inl_side, b, 0.0),
        # the drawer's x: a . (p - t - R o_joint) + q (it moves along -x)
        (faces.doors[0], inl_drawer, a, -1.0),
    ):
        rows.append(np.tile([axis[0], axis[1], q_coef], (int(keep.sum()), 1)))
        rhs.append(pts[keep] @ axis - offset[keep])
    rhs[-1] = rhs[-1] - a @ (rot @ joint_origin)
    prior = np.diag([math.sqrt(PRIOR_WEIGHT)] * 2 + [math.sqrt(Q_PRIOR_WEIGHT)])
    rows.append(prior)
    rhs.append(prior @ np.array([h.x, h.y, q]))
    t = np.linalg.lstsq(np.concatenate(rows), np.concatenate(rhs), rcond=None)[0]
    q = float(np.clip(t[2], 0.0, q_max(h.joint_type, h.depth)))
    return h.with_pose(float(t[0]), float(t[1]), _base_height(h, faces), yaw, (q,))


def refine_hypothesis(
    start: Hypothesis,
    renderer: PosedRenderer,
    observed: NDArray[np.floating],
    rays: NDArray[np.float32],
    seed: int = 0,
    inside: bool = False,
) -> tuple[Hypothesis, float]:
    """`ITERATIONS` render-assign-fit rounds from `start`; of the start and each round's
    result, the one with the lowest depth residual, and that residual. `inside`: the yaw
    fitted with the body's inner faces too (`_Faces.back`, `inner`; `inner_faces`). For a
    drawer, the first round leaves the body's front rim out of the fit and is followed by
    the search along its opening (`search_opening`): the rim is a 2 cm strip, and from a
    start a few centimetres off its pixels see into the drawer, not the rim. For a flap
    (the toaster's door) opened `FLAP_OPEN_Q` or more, the base height, which no bottom
    edge gives it, is searched (`search_height`) before the first round (its points are
    assigned at that height) and after it; a closed flap's stays the start's."""
    h = start
    image, door_poses = renderer.render(h)
    best = (h, depth_residual(image.depth, observed))
    if _opened_flap(renderer, h):
        h = search_height(h, renderer, observed, FLAP_HEIGHT_SPAN)
        image, door_poses = renderer.render(h)
    for k in range(ITERATIONS):
        tolerance = TOLERANCES[min(k, len(TOLERANCES) - 1)]
        faces = _faces(h, image, door_poses, renderer.doors, observed, rays, tolerance,
                       renderer.door_thickness, renderer.wall if inside else 0.0)  # fmt: skip
        h = _fit(h, faces, renderer.doors, seed, rim=k > 0)
        if k == 0 and h.joint_type == "prismatic":
            h = search_opening(h, renderer, observed)
        elif k == 0 and _opened_flap(renderer, h):
            h = search_height(h, renderer, observed, FLAP_HEIGHT_SPAN)
        image, door_poses = renderer.render(h)
        residual = depth_residual(image.depth, observed)
        if residual < best[1]:
            best = (h, residual)
    return best


def _opened_flap(renderer: PosedRenderer, h: Hypothesis) -> bool:
    """`h`'s door is a flap opened `FLAP_OPEN_Q` or more (its height is searched)."""
    return renderer.doors[0].flap and h.qs[0] >= FLAP_OPEN_Q


@functools.cache
def _threadpools() -> Any:
    """threadpoolctl's controller (finding the loaded libraries once: ~4 ms each time)."""
    from threadpoolctl import ThreadpoolController

    from artic.render.open3d_core import open3d_core

    open3d_core()  # loaded before the controller lists the libraries

    return ThreadpoolController()


def interval_ok(
    label: Array, columns: list[str], lower: Array, upper: Array, joint_type: str = "revolute"
) -> bool:
    """True when the label's yaw and each q lie inside [lower, upper] (label units)
    widened by `INTERVAL_MARGIN` (a door's q by `INTERVAL_MARGIN_Q`, a drawer's by
    `INTERVAL_MARGIN_M`): the quantities the planes read."""
    q_margin = INTERVAL_MARGIN_M if joint_type == "prismatic" else INTERVAL_MARGIN_Q
    qs = [(f"j{j}_q", q_margin) for j in range(joint_count(columns))]
    for name, margin in [("pose_yaw", INTERVAL_MARGIN), *qs]:
        i = columns.index(name)
        if not lower[i] - margin <= label[i] <= upper[i] + margin:
            return False
    return True


def mirror_label(label: Array, h: Hypothesis, columns: list[str]) -> Array:
    """`label` (of `h`) as a network trained on the other hinge side reads it: its yaw
    reflected about the line of sight (`Hypothesis.reflected`), the rest as it is (what
    `interval_ok` reads of it, the q, a mirror image keeps)."""
    read = np.array(label, dtype=np.float64)
    read[columns.index("pose_yaw")] = _wrap(h.reflected().yaw)
    return read


def covered_sides(means: Array, columns: list[str]) -> frozenset[int]:
    """The hinge sides the mixture's component `means` (m, L) put weight on."""
    chirality = np.asarray(means)[:, columns.index("chirality")]
    return frozenset(1 if c >= 0 else -1 for c in chirality.tolist())


def judged_ok(
    label: Array,
    h: Hypothesis,
    covered: Collection[int],
    columns: list[str],
    lower: Array,
    upper: Array,
) -> bool:
    """`interval_ok` of the candidate `h` (its `label`); on a side the mixture never puts
    weight on (not in `covered`), of the candidate or of its mirror image (`mirror_label`):
    a network trained on the other side reads such an object as its mirror image, or, where
    the image does not show the side (a closed door), as itself on its own side."""
    if interval_ok(label, columns, lower, upper, h.joint_type):
        return True
    return h.chirality not in covered and interval_ok(
        mirror_label(label, h, columns), columns, lower, upper, h.joint_type
    )


def refine(
    observed: NDArray[np.floating],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    estimate: Array,
    weights: Array,
    means: Array,
    lower: Array,
    upper: Array,
    parts: PartsConfig | None = None,
    detail: tuple[NDArray[np.floating], CameraIntrinsics] | None = None,
    threads: int = 1,
) -> Refinement:
    """Refine the network's `estimate` (L,) of the depth image `observed` (H, W) metres in
    `camera` (the model's camera; 0 = no return), given the mixture's `weights` (m,),
    component `means` (m, L) and central interval [`lower`, `upper`] (L,) in label units
    (`INTERVAL_LEVEL`), for an object of `category` built with `parts` (default: the
    categories' defaults). `detail`: the same view in the camera it was taken with (depth,
    camera), for the handle, front and seam tests (`handle_side`, `front_side`,
    `seam_side`); default `observed` in `camera`. `threads`: the candidates' ray casting's
    (the result does not depend on it). Never raises on an image: a refinement that cannot
    run returns the network's estimate and says why (module docstring)."""
    parts = parts or PartsConfig()
    estimate = np.asarray(estimate, dtype=np.float64)
    none: tuple[Candidate, ...] = ()
    if category not in SUPPORTED:
        return Refinement(
            estimate, False, f"not refined: {category} not supported yet", math.nan, math.nan, none
        )
    observed = np.where(np.isfinite(observed), observed, 0).astype(np.float32)
    if observed.shape != (camera.height, camera.width):
        return Refinement(
            estimate, False, "not refined: the image is not in the model's camera",
            math.nan, math.nan, none,
        )  # fmt: skip
    if int((observed > 0).sum()) < MIN_OBSERVED:
        return Refinement(
            estimate, False, f"not refined: fewer than {MIN_OBSERVED} valid pixels",
            math.nan, math.nan, none,
        )  # fmt: skip
    if not (np.isfinite(estimate).all() and np.isfinite(np.asarray(means)).all()):
        return Refinement(
            estimate, False, "not refined: the network's estimate is not finite",
            math.nan, math.nan, none,
        )  # fmt: skip
    network = Hypothesis.from_label(estimate, columns, JOINT_TYPES[category])
    covered = covered_sides(means, columns)
    try:
        residual_network, candidates = _candidates(
            network, observed, camera, category, columns, weights, means, lower, upper, parts,
            covered, threads,
        )  # fmt: skip
    except (ValueError, np.linalg.LinAlgError) as err:  # an object the builder refuses
        return Refinement(
            estimate, False, f"fallback: the refinement failed ({str(err).splitlines()[0]})",
            math.nan, math.nan, none,
        )  # fmt: skip
    weight = side_weight(network.chirality, weights, means, columns)
    candidates.extend(_other_side(candidates, observed, camera, category, columns, parts,
                                  lower, upper, covered,
                                  network_side=(network.chirality, weight)))  # fmt: skip
    inside = [c for c in candidates if c.inside_interval]
    overlay = False
    if network.joint_type == "prismatic":
        # the overlay reading of the closest fit inside the interval (what `_pick_side`
        # keeps of a drawer's one side), or of all when none is: judged by the same interval
        nearest = min(inside or candidates, key=lambda c: c.residual)
        read, overlay = _overlay_front(nearest, observed, camera, category, columns, parts,
                                       lower, upper)  # fmt: skip
        inside = [read] if overlay else inside
    if not inside:
        status = f"fallback: no candidate inside the mixture's {INTERVAL_LEVEL:.0%} interval"
        return Refinement(estimate, False, status, residual_network, residual_network,
                          tuple(candidates))  # fmt: skip
    image, view = detail if detail is not None else (observed, camera)
    best, named_by = _pick_side(
        inside, network.chirality, weight, columns, category, parts, (image, view),
        (observed, camera),
    )  # fmt: skip
    best = _refit_sizes(best, observed, camera, category, columns, parts, lower, upper)
    if best.hypothesis is not None and _vertical_hinges(category):
        # the body turned about the hinge, then read off its inner faces: one build of
        # the chosen object (both keep its geometry)
        with _posed(best.hypothesis, category, parts, camera, None) as chosen:
            best = hinge_turn(best, observed, camera, category, columns, parts, covered,
                              lower, upper, chosen)  # fmt: skip
            best = inner_faces(best, observed, camera, category, columns, parts, covered,
                               lower, upper, chosen)  # fmt: skip
    best = hinge_width(best, observed, camera, category, columns, parts)
    # a quarter turn, when no test found a front's features on the chosen front
    turned = [] if named_by else _turned(best, observed, camera, category, columns, parts,
                                         lower, upper)  # fmt: skip
    if turned:
        candidates.extend(turned)
        # ... and a handle on the turned candidates' front (a side face has none; the other
        # hinge-side tests admit no turn: `TURN_INCIDENCE`), the side it names the turn's
        side = handle_side(turned, columns, category, parts, image, view, (observed, camera))
        other = min([c for c in turned if c.chirality == side] or turned, key=lambda c: c.residual)
        if side is not None and other.residual < best.residual:
            best, named_by = other, HANDLE_TEST
    if not best.residual < residual_network:
        status = "fallback: no candidate has a lower depth residual than the network's estimate"
        return Refinement(estimate, False, status, residual_network, residual_network,
                          tuple(candidates))  # fmt: skip
    turn = ", turned a quarter" if best.turned else ""
    named = f" ({named_by})" if named_by else ""
    front = ", overlay front" if overlay else ""
    status = (f"refined: component {best.component}, chirality {best.chirality:+d}{turn}"
              f"{front}{named}")  # fmt: skip
    return Refinement(best.label, True, status, residual_network, best.residual, tuple(candidates))


def _pick_side(
    candidates: list[Candidate],
    network_side: int,
    weight: float,
    columns: list[str],
    category: str,
    parts: PartsConfig,
    detail: tuple[NDArray[np.floating], CameraIntrinsics],
    model_view: tuple[NDArray[np.float32], CameraIntrinsics],
) -> tuple[Candidate, str]:
    """The candidate to keep and what named its hinge side: the lowest residual on the
    network's side unless the other side's is lower by a margin (`_choose_side`, the
    mixture's `weight` on `network_side`), then the hinge-side tests of a door's category in
    turn (module docstring), the first to name a side deciding; the control panel's three
    say None but for `PANEL_BESIDE`; the test's name, "" when none named a side. `detail`:
    the image in its own camera; `model_view`: in the model's."""
    best = _choose_side(candidates, network_side, weight)
    image, view = detail
    observed, camera = model_view
    tests: tuple[tuple[str, Callable[[], int | None]], ...] = (
        (HANDLE_TEST,
         lambda: handle_side(candidates, columns, category, parts, image, view, model_view)),
        ("the front's shape",
         lambda: front_side(candidates, columns, category, parts, image, view)),
        ("the control panel's side",
         lambda: panel_side(candidates, columns, category, parts, observed, camera)),
        ("the seam beside the control panel",
         lambda: seam_side(candidates, columns, category, parts, image, view)),
    )  # fmt: skip
    side, named_by = None, ""
    for name, test in tests if category in SIDED else ():
        side = test()
        if side is not None:
            named_by = name
            break
    if side is not None and side != best.chirality:
        # a vote by the other side's candidate may name a side with no candidate inside
        named = [c for c in candidates if c.chirality == side]
        best = min(named, key=lambda c: c.residual) if named else best
    return best, named_by


def _other_side(
    candidates: list[Candidate],
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    lower: Array,
    upper: Array,
    covered: Collection[int] = (1, -1),
    *,
    network_side: tuple[int, float],
) -> list[Candidate]:
    """The lowest-residual candidate inside the interval, refined again from its own pose
    and q on the other hinge side (`Hypothesis.mirrored`), as one more candidate judged as
    every candidate (`judged_ok`, `covered` the mixture's sides); [] for a
    category without a side to decide (`SIDED`) or with no such candidate. The starts of
    one side can all stay in a worse pose than the other side's best (a door the image
    shows closed held open, the yaw a few degrees off), and then the other side wins by
    more than `_choose_side`'s margin though the image cannot tell the sides apart (a
    closed door's mirror image fits as well); from the same pose both sides meet.

    A door beside a control panel (`PANEL_BESIDE`) only when the other side would win
    (`_choose_side` with `network_side`: the network's side and the mixture's weight on
    it) with its door open less than `PANEL_MIRROR_Q_MAX`, and then scored at that very
    pose on the network's side (no rounds): shut, both sides' doors are the same flat
    front. An opened door there has another front on the other side, not the same box's
    mirror image, and its start from this pose is no better than the others; rounds from
    a shut door's pose can drift to a reading of the box's side as its front; and where
    the network's side stands anyway, the mirror of the other side's best can only turn a
    tie between two readings of a square box (measured: docs/kinematics.md)."""
    inside = [c for c in candidates if c.inside_interval and c.hypothesis is not None]
    if category not in SIDED or not inside:
        return []
    panel = category in PANEL_BESIDE
    best = _choose_side(inside, *network_side) if panel else min(inside, key=lambda c: c.residual)
    assert best.hypothesis is not None
    start = best.hypothesis.mirrored()
    opened = max(map(abs, start.qs)) >= PANEL_MIRROR_Q_MAX
    if panel and (best.chirality == network_side[0] or opened):
        return []
    result = _rounds_from(start, observed, camera, category, columns, parts, rounds=not panel)
    if result is None:
        return []
    fitted, residual, label = result
    inside_interval = judged_ok(label, fitted, covered, columns, lower, upper)
    return [Candidate(best.component, best.weight, fitted.chirality, residual, inside_interval,
                      label, fitted)]  # fmt: skip


def _turned(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    lower: Array,
    upper: Array,
) -> list[Candidate]:
    """`best` turned a quarter turn about its middle, its width and depth swapped (the
    same footprint, the front on the side in view), from both hinge sides, each refined
    (`refine_hypothesis`, then `_refit_sizes`): the reading of a box whose side the network
    took for its front. Only when that front faces the camera within `TURN_INCIDENCE`
    and for a category with one door on a vertical hinge (`SIDED`); the turned yaw lies
    outside the mixture's interval by construction, so only the q is held to it."""
    h = best.hypothesis
    if h is None or category not in SIDED:
        return []
    bearing = math.atan2(h.y, h.x)  # a front faces the camera squarely at yaw = bearing
    yaw = max((h.yaw + math.pi / 2, h.yaw - math.pi / 2),
              key=lambda y: math.cos(y - bearing))  # fmt: skip
    if abs(_wrap(yaw - bearing)) > TURN_INCIDENCE:
        return []
    free_yaw = columns.index("pose_yaw")
    lower, upper = lower.copy(), upper.copy()
    lower[free_yaw], upper[free_yaw] = -math.inf, math.inf
    turned = []
    for side in (best.chirality, -best.chirality):
        start = dataclasses.replace(h, yaw=_wrap(yaw), depth=h.width, width=h.depth,
                                    chirality=side)  # fmt: skip
        result = _rounds_from(start, observed, camera, category, columns, parts)
        if result is None or not interval_ok(result[2], columns, lower, upper):
            continue
        fitted, residual, label = result
        c = Candidate(best.component, best.weight, side, residual, True, label, fitted, turned=True)
        turned.append(_refit_sizes(c, observed, camera, category, columns, parts, lower, upper))
    return turned


def _candidates(
    network: Hypothesis,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    weights: Array,
    means: Array,
    lower: Array,
    upper: Array,
    parts: PartsConfig,
    covered: Collection[int],
    threads: int = 1,
) -> tuple[float, list[Candidate]]:
    """The network's residual and every refined candidate (module docstring), each judged
    by `judged_ok` (`covered`: the mixture's hinge sides), their rays cast on `threads`
    threads."""
    rays = camera.ray_directions()
    # a door from both hinge sides; a drawer and the two-door cabinet have one
    sides = (1, -1) if category in SIDED else (network.chirality,)
    renderers = {
        c: PosedRenderer(_side(network, c), category, parts, camera, threads) for c in sides
    }
    try:
        image, _ = renderers[network.chirality].render(network)
        residual_network = depth_residual(image.depth, observed)
        count = DRAWER_COMPONENTS if network.joint_type == "prismatic" else COMPONENTS
        order = np.argsort(-np.asarray(weights), kind="stable")[:count]
        candidates = []
        for rank, k in enumerate(order.tolist()):
            component = Hypothesis.from_label(means[k], columns, network.joint_type)
            # the estimate's geometry for every start: one object per hinge side
            base = network.with_pose(component.x, component.y, component.z, component.yaw,
                                     component.qs)  # fmt: skip
            side = component.chirality
            starts = [_side(base, c) for c in sorted(sides, key=lambda c: c != side)]
            if rank == 0 and len(sides) == 2:  # and the top component's mirror image
                starts.append(_side(base, -side).reflected())
            for start in starts:
                h, residual = refine_hypothesis(
                    start, renderers[start.chirality], observed, rays, seed=rank
                )
                label = renderers[h.chirality].label(h, category, columns)
                candidates.append(Candidate(
                    int(k), float(weights[k]), h.chirality, residual,
                    judged_ok(label, h, covered, columns, lower, upper), label, h,
                ))  # fmt: skip
    finally:
        for r in renderers.values():
            r.close()
    return residual_network, candidates


def _refit_sizes(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    lower: Array,
    upper: Array,
) -> Candidate:
    """The chosen door candidate with its width fitted (`_fit_width`; without a side face
    to fit it from, the front's far edge, `front_width`), then its depth (the side in
    view's far edge, `side_depth`), each followed by `refine_hypothesis`'s rounds on that
    geometry and kept when its depth residual is lower and its yaw and q stay inside the
    mixture's interval. The sizes are the network's until here: every candidate shares
    one built object per hinge side, and a side face at the wrong width pulls a hinge on
    the other side of the object by the difference (one or two builds more for the chosen
    candidate: ~10-30 ms each). A flap's base last, its top held (`flap_base`)."""
    h = best.hypothesis
    if h is None or h.joint_type != "revolute":
        return best
    start, widened = _width_start(h, observed, camera, category, parts)
    best, kept = _refit(best, start, observed, camera, category, columns, widened, lower, upper)
    parts = widened if kept else parts
    assert best.hypothesis is not None
    deeper = side_depth(best.hypothesis, observed, camera)
    best = _refit(best, deeper, observed, camera, category, columns, parts, lower, upper)[0]
    return flap_base(best, observed, camera, category, columns, parts, lower, upper)


def flap_base(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    lower: Array,
    upper: Array,
) -> Candidate:
    """The chosen flap candidate (the toaster's) with its base raised or lowered (within
    `FLAP_BASE_SPAN`, `_search`) and its top held, to the height of the lowest depth
    residual; kept when that residual is lower and its yaw and q lie inside the mixture's
    interval (`interval_ok`, as `_refit`'s). The box model's door is hinged at the base,
    and a toaster oven on feet has its door, and its body, a foot's height above what it
    stands on: moving the whole box up (`search_height`) lifts its top out of the roof's
    place, so the residual settles between the two. The base is then the body's bottom,
    its height the body's (the feet are not modelled). One object build per height tried
    (~3 ms each for a toaster)."""
    h = best.hypothesis
    if h is None or category not in FLAPS:
        return best
    top = h.z + h.height
    # d = 0 is the candidate itself, its residual known
    tried: dict[float, tuple[float, Hypothesis, Array | None]] = {
        0.0: (best.residual, h, best.label)
    }

    def residual(d: float) -> float:
        if d not in tried:
            raised = dataclasses.replace(h, z=h.z + d, height=top - h.z - d)
            tried[d] = (math.inf, raised, None)
            try:
                renderer = PosedRenderer(raised, category, parts, camera)
            except ValueError:  # a height the builder refuses
                return math.inf
            try:
                image, _ = renderer.render(raised)
                label = renderer.label(raised, category, columns)
                tried[d] = (depth_residual(image.depth, observed), raised, label)
            finally:
                renderer.close()
        return tried[d][0]

    d = _search(lambda values: [residual(float(v)) for v in values], *FLAP_BASE_SPAN,
                SEARCH_STEP, ends=True)  # fmt: skip
    value, raised, label = tried[d]
    if label is None or not value < best.residual:
        return best
    if not interval_ok(label, columns, lower, upper, raised.joint_type):
        return best
    return _kept(best, raised, value, label)


def about_hinge(h: Hypothesis, doors: Sequence[_Door], delta: float) -> Hypothesis:
    """`h`'s body turned by `delta` (rad) about the vertical line of the first door's
    hinge, the doors held where they are: their hinge lines and planes stay, each q
    changing by -sign x delta (a refrigerator's two doors share their hinge line)."""
    pose = h.pose_matrix()
    hinge = (pose[:3, :3] @ doors[0].origin + pose[:3, 3])[:2]
    base = hinge + rot_z(delta)[:2, :2] @ (np.array([h.x, h.y]) - hinge)
    qs = tuple(q - door.sign * delta for q, door in zip(h.qs, doors, strict=True))
    return dataclasses.replace(h, x=float(base[0]), y=float(base[1]), yaw=h.yaw + delta, qs=qs)


def _yaw_fitted(
    h: Hypothesis, renderer: PosedRenderer, observed: NDArray[np.float32], camera: CameraIntrinsics
) -> bool:
    """Whether the rounds fit `h`'s yaw: the body's front or side has RANSAC inliers
    (`_face_inliers`) at the last round's tolerance; with none, `_fit_yaw` keeps the yaw."""
    image, door_poses = renderer.render(h)
    faces = _faces(h, image, door_poses, renderer.doors, observed, camera.ray_directions(),
                   TOLERANCES[-1], renderer.door_thickness)  # fmt: skip
    front, side, _ = _face_inliers(faces, 0)
    return bool(front.any() or side.any())


def _vertical_hinges(category: str) -> bool:
    """Whether `category`'s doors turn about vertical hinges (not a flap, not a drawer)."""
    return JOINT_TYPES.get(category) == "revolute" and category not in FLAPS


@contextlib.contextmanager
def _posed(
    h: Hypothesis,
    category: str,
    parts: PartsConfig,
    camera: CameraIntrinsics,
    shared: PosedRenderer | None,
) -> Iterator[PosedRenderer]:
    """`shared` when it draws `h`'s geometry and hinge side, else one built for `h` (and
    closed after): the steps after the choice share one build of the chosen object."""
    if shared is not None and shared.fits(h):
        yield shared
        return
    renderer = PosedRenderer(h, category, parts, camera)
    try:
        yield renderer
    finally:
        renderer.close()


def hinge_turn(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    covered: Collection[int],
    lower: Array,
    upper: Array,
    shared: PosedRenderer | None = None,
) -> Candidate:
    """The chosen candidate of a category whose doors turn about one vertical hinge line
    (`SIDED`), when its body shows no face the rounds fit its yaw from (`_yaw_fitted`),
    with its body turned about that line (`about_hinge`, up to `HINGE_TURN_SPAN` each way,
    every q kept in its range) to the turn of the lowest depth residual, then refined from
    there (`refine_hypothesis`); kept when its residual is lower and it is judged inside
    the mixture's interval (`judged_ok`). The door fixes the sum of yaw and q, the body's
    faces the yaw; with none in view (a cabinet's front is all door, and seen square-on
    no side shows) the rounds keep the yaw they start from, which only this search moves.
    Where they fit it, the residual's minimum lies off their yaw by up to a few degrees
    (the sensor's noise, sizes a centimetre off), so the search is not run. `shared`: a
    renderer of the candidate's object (`_posed`; else one more build, ~10-30 ms)."""
    h = best.hypothesis
    if h is None or category not in SIDED:
        return best
    with _posed(h, category, parts, camera, shared) as renderer:
        doors = renderer.doors  # on one vertical hinge line (`SIDED`), as `about_hinge` needs
        assert all(np.allclose(d.origin[:2], doors[0].origin[:2]) for d in doors)
        if _yaw_fitted(h, renderer, observed, camera):
            return best
        # each q - sign x delta stays in [0, top]
        top = q_max(h.joint_type, h.depth)
        low, high = -HINGE_TURN_SPAN, HINGE_TURN_SPAN
        for q, door in zip(h.qs, doors, strict=True):
            bounds = sorted((door.sign * q, door.sign * (q - top)))
            low, high = max(low, bounds[0]), min(high, bounds[1])
        low, high = min(0.0, low), max(0.0, high)
        # the ends too: a shut door's q = 0 is where the truth often is
        turned = _line_search(lambda d: about_hinge(h, doors, d), low, high, renderer, observed,
                              HINGE_TURN_STEP, ends=True)  # fmt: skip
        if turned.yaw == h.yaw:  # no turn
            return best
        fitted, residual = refine_hypothesis(turned, renderer, observed, camera.ray_directions())
        label = renderer.label(fitted, category, columns)
    return _judged(best, fitted, residual, label, covered, columns, lower, upper)


def inner_faces(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    covered: Collection[int],
    lower: Array,
    upper: Array,
    shared: PosedRenderer | None = None,
) -> Candidate:
    """The chosen candidate of a category whose doors turn about vertical hinges, when the
    body's inside shows through an opened door at its pose (RANSAC inliers of the shell's
    inner back or side faces, `_Faces.back`, `inner`), refined again with those faces in
    the yaw's fit (`refine_hypothesis`'s `inside`); kept when its residual is lower and it
    is judged inside the mixture's interval (`judged_ok`). A door's plane fixes the sum of
    the body's yaw and q; the body's outer faces split it, and where the front is all door
    and no side shows, they do not: the inner faces, which turn with the body, do. Not in
    the rounds of every candidate: from a start a few degrees off, an inner face's pixels
    are as often another face's (a side wall's taken for the back), and the rounds settle
    on the wrong plane; from the chosen candidate they are mostly its own, and the residual
    judges. A flap's angle and its body's yaw turn about other axes. `shared`: as
    `hinge_turn`'s."""
    h = best.hypothesis
    if h is None or not _vertical_hinges(category):
        return best
    with _posed(h, category, parts, camera, shared) as renderer:
        rays = camera.ray_directions()
        image, door_poses = renderer.render(h)
        faces = _faces(h, image, door_poses, renderer.doors, observed, rays, TOLERANCES[-1],
                       renderer.door_thickness, renderer.wall)  # fmt: skip
        if not any(keep.any() for keep in _inner_inliers(faces, 0)):
            return best
        fitted, residual = refine_hypothesis(h, renderer, observed, rays, inside=True)
        label = renderer.label(fitted, category, columns)
    return _judged(best, fitted, residual, label, covered, columns, lower, upper)


def hinge_width(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
) -> Candidate:
    """The chosen candidate of a category whose door has a control panel beside it
    (`PANEL_HELD`) with its width searched on the depth residual, the panel's side held
    and the hinge's side moved (the base moved across by half the change, the door's yaw
    and q held): the width read off the far side's edge (`_refit_sizes`) leaves the hinge
    where that width puts it, and the panel's side is where the image shows it while the
    hinge's is not. A cabinet's door spans its whole front, and where its yaw and q are
    split wrong the hinge moved on the residual makes up for the turn instead of reading
    the width (docs/reproduction.md: no better on the cabinet). Each width
    (`HINGE_WIDTH_SPAN` each way, every `SEARCH_STEP`, then a fifth of it) is drawn from
    the candidate's object stretched to it (`PosedRenderer.render_stretched`: no object
    built per width); the width found is built and kept when its depth residual on the
    built object is lower (one more build; the yaw and q the mixture's interval judges
    are held)."""
    h = best.hypothesis
    if h is None or category not in PANEL_HELD:
        return best
    c, s = math.cos(h.yaw), math.sin(h.yaw)  # the object's y in the camera frame: (-s, c)
    renderer = PosedRenderer(h, category, parts, camera)
    try:
        hinge = 1.0 if float(renderer.doors[0].origin[1]) > 0 else -1.0  # its side along y

        def wider(d: float) -> Hypothesis:
            shift = hinge * d / 2
            return dataclasses.replace(h, width=h.width + d, x=h.x - shift * s, y=h.y + shift * c)

        def residuals(values: Array) -> list[float]:
            images = renderer.render_stretched([wider(float(d)) for d in values])
            return [depth_residual(image.depth, observed) for image in images]

        low = max(-HINGE_WIDTH_SPAN, MIN_WIDTH - h.width)
        d = _search(residuals, low, HINGE_WIDTH_SPAN, SEARCH_STEP)
    finally:
        renderer.close()
    if d == 0.0:
        return best
    moved = wider(d)
    try:
        built = PosedRenderer(moved, category, parts, camera)
    except ValueError:  # a width the builder refuses
        return best
    try:
        image, _ = built.render(moved)
        residual = depth_residual(image.depth, observed)
        label = built.label(moved, category, columns)
    finally:
        built.close()
    if not residual < best.residual:
        return best
    return _kept(best, moved, residual, label)


def _overlay_front(
    best: Candidate,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    lower: Array,
    upper: Array,
) -> tuple[Candidate, bool]:
    """A drawer candidate (`refine`: its closest fit) read again with an overlay front
    (`PartsConfig.drawer_front`: a plate over the whole body front, its back face on the
    body's front when shut), and whether that reading replaced it (`_refit`: a lower depth
    residual, its yaw and q inside the mixture's interval). It starts from the same pose
    with the front's face where the inset reading put it (q less the front's thickness):
    an inset reading of an overlay front reads the drawer open by about the front's
    thickness more than it is, and shows the body's front rim round the front where the
    plate covers it. The plate covers the body's front (but `gap` round it), so the start
    takes the width and height the front shows (`front_span`; the network's when it shows
    too little), centred on it: the body is the carcass the plate covers, a plinth, legs
    or a top slab beyond it not part of the box model."""
    h = best.hypothesis
    if h is None or parts.drawer_front == "overlay":
        return best, False
    overlay = parts.model_copy(update={"drawer_front": "overlay"})
    start = dataclasses.replace(h, qs=(max(h.qs[0] - parts.door_thickness, 0.0),))
    span = front_span(h, observed, camera, -h.depth / 2 - h.qs[0])
    if span is not None:
        # an edge out of the image: the hypothesis' plate's
        plate = (-h.width / 2 + parts.gap, h.width / 2 - parts.gap, parts.gap,
                 h.height - parts.gap)  # fmt: skip
        low, high, bottom, top = (p if e is None else e for e, p in zip(span, plate, strict=True))
        middle, c, s = (low + high) / 2, math.cos(h.yaw), math.sin(h.yaw)
        start = dataclasses.replace(
            start, width=max(high - low + 2 * parts.gap, 0.1), x=h.x - middle * s,
            y=h.y + middle * c, z=h.z + bottom - parts.gap,
            height=max(top - bottom + 2 * parts.gap, 0.1),
        )  # fmt: skip
    return _refit(best, start, observed, camera, category, columns, overlay, lower, upper)


def front_span(
    h: Hypothesis, observed: NDArray[np.floating], camera: CameraIntrinsics, plane: float
) -> tuple[float | None, float | None, float | None, float | None] | None:
    """Where a front on the plane x = `plane` of `h`'s object frame ends: either side
    (object y, m: low, high) and below and above (object z, m: bottom, top); None when it
    shows too little (`MIN_WIDTH_POINTS`). The observed points within `WIDTH_BAND` of the
    plane and within `WIDTH_SPAN` of the body's sides, bottom and top: their
    `WIDTH_QUANTILE` quantile towards each edge, half a pixel beyond (`_pixel_across`; a
    row's height at the object's distance), as `front_width` reads a front's far edge.
    An edge with a point beyond that quantile on the image's border is None: the front
    runs out of the image there (as `side_depth`'s)."""
    local = _object_points(h, observed, camera)
    near = np.abs(local[:, 0] - plane) < WIDTH_BAND
    near &= (local[:, 2] > -WIDTH_SPAN) & (local[:, 2] < h.height + WIDTH_SPAN)
    near &= np.abs(local[:, 1]) < h.width / 2 + WIDTH_SPAN
    if int(near.sum()) < MIN_WIDTH_POINTS:
        return None
    rows, cols = np.nonzero(np.where(np.isfinite(observed), observed, 0) > 0)  # local's pixels
    border = ((rows == 0) | (cols == 0) | (rows == camera.height - 1)
              | (cols == camera.width - 1))[near]  # fmt: skip
    half = (0.5 * _pixel_across(h, camera), 0.5 * math.hypot(h.x, h.y) / camera.fy)
    span: list[float | None] = []
    for axis, pixel in zip((1, 2), half, strict=True):
        values = local[near, axis]
        for q, sign in ((1.0 - WIDTH_QUANTILE, -1.0), (WIDTH_QUANTILE, 1.0)):
            edge = float(np.quantile(values, q))
            cut = bool(border[sign * values >= sign * edge].any())
            span.append(None if cut else edge + sign * pixel)
    low, high, bottom, top = span
    return low, high, bottom, top


def _width_start(
    h: Hypothesis,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    parts: PartsConfig,
) -> tuple[Hypothesis | None, PartsConfig]:
    """`h` with the width its image shows (`_refit_sizes`; None when it shows none) and
    the parts to build it with (a flap's control panel share read off its edge)."""
    rays = camera.ray_directions()
    renderer = PosedRenderer(h, category, parts, camera)
    try:
        if renderer.doors[0].flap:  # no hinge meets a side: the front's width, the panel's
            start = front_width(h, observed, camera, renderer.door_thickness)
            share = flap_panel_share(start or h, renderer.doors[0], observed, camera, parts)
            if share is not None:
                return start or h, parts.model_copy(update={"control_panel_fraction": share})
            return start, parts
        image, door_poses = renderer.render(h)
        # the first round's tolerance: a side 4 cm from where the width puts it is still its
        faces = _faces(h, image, door_poses, renderer.doors, observed, rays, TOLERANCES[0],
                       renderer.door_thickness)  # fmt: skip
        # no side face where the width puts it (a width 10 cm off puts it beyond the
        # first round's tolerance; or no side in view): the front's far edge, as a flap's
        start = _fit_width(h, faces, renderer.doors) or front_width(
            h, observed, camera, renderer.door_thickness
        )
        return start, parts
    finally:
        renderer.close()


def _refit(
    best: Candidate,
    start: Hypothesis | None,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    lower: Array,
    upper: Array,
) -> tuple[Candidate, bool]:
    """`refine_hypothesis`'s rounds from `start` (another geometry than `best`'s) and
    whether they replaced `best`: when their depth residual is lower and their yaw and q
    lie inside the mixture's interval."""
    result = None if start is None else _rounds_from(start, observed, camera, category,
                                                     columns, parts)  # fmt: skip
    if result is None:
        return best, False
    fitted, residual, label = result
    inside = interval_ok(label, columns, lower, upper, fitted.joint_type)
    if not (residual < best.residual and inside):
        return best, False
    return _kept(best, fitted, residual, label), True


def _judged(
    best: Candidate,
    fitted: Hypothesis,
    residual: float,
    label: Array,
    covered: Collection[int],
    columns: list[str],
    lower: Array,
    upper: Array,
) -> Candidate:
    """`best` replaced by a refit of it (`fitted`, its residual and label) when the refit's
    residual is lower and it is judged inside the mixture's interval (`judged_ok`)."""
    if not (residual < best.residual and judged_ok(label, fitted, covered, columns, lower, upper)):
        return best
    return _kept(best, fitted, residual, label)


def _kept(best: Candidate, fitted: Hypothesis, residual: float, label: Array) -> Candidate:
    """`best` replaced by a refit of it that was kept (`fitted`, its residual and label):
    judged inside the mixture's interval."""
    return dataclasses.replace(best, residual=residual, label=label, hypothesis=fitted,
                               inside_interval=True)  # fmt: skip


def _rounds_from(
    start: Hypothesis,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    rounds: bool = True,
) -> tuple[Hypothesis, float, Array] | None:
    """`refine_hypothesis`'s rounds from `start` on an object built at its geometry: the
    result, its residual and its label; None for a geometry the builder refuses (a width
    read narrower than the object's walls). `rounds` False: `start` as it is, scored (one
    image)."""
    try:
        renderer = PosedRenderer(start, category, parts, camera)
    except ValueError:
        return None
    try:
        if rounds:
            fitted, residual = refine_hypothesis(start, renderer, observed, camera.ray_directions())
        else:
            fitted, residual = start, depth_residual(renderer.render(start)[0].depth, observed)
        return fitted, residual, renderer.label(fitted, category, columns)
    finally:
        renderer.close()


def _fit_width(h: Hypothesis, faces: _Faces, doors: Sequence[_Door]) -> Hypothesis | None:
    """The base position (x, y) and the width by least squares, the yaw and q held: the
    body's front on x = -depth/2, a side on y = +-width/2 and each door on its plane
    through its hinge at +-width/2 (object frame), with `_fit`'s pull towards the
    hypothesis (the width's too). None without a side face and a door face to fix it: one
    with `MIN_DOOR_POINTS` inliers opened `WIDTH_DOOR_Q` or more (a door nearer shut lies
    along the front, and the width would be the prior's)."""
    inl_front, inl_side, inl_doors = _face_inliers(faces, 0)
    opened = [k.sum() >= MIN_DOOR_POINTS and q >= WIDTH_DOOR_Q
              for k, q in zip(inl_doors, h.qs, strict=True)]  # fmt: skip
    if inl_side.sum() < MIN_FACE_POINTS or not any(opened):
        return None
    rot = rot_z(h.yaw)
    a, b = rot[:, 0], rot[:, 1]
    pts, offset = faces.front
    rows = [np.tile([a[0], a[1], 0.0], (int(inl_front.sum()), 1))]
    rhs = [pts[inl_front] @ a - offset[inl_front]]
    pts, offset = faces.side
    half = 0.5 * np.sign(offset[inl_side])  # the side's y is +-width/2
    rows.append(np.column_stack([np.full(len(half), b[0]), np.full(len(half), b[1]), half]))
    rhs.append(pts[inl_side] @ b)
    for door, q, (pts, offset), keep in zip(doors, h.qs, faces.doors, inl_doors, strict=True):
        d = (rot @ door.turn(q))[:, 0]  # the door's x in the camera frame
        fixed = rot @ np.array([door.origin[0], 0.0, door.origin[2]])
        across = door.origin[1] / h.width * float(d @ b)  # the hinge's y scales with the width
        rows.append(np.tile([d[0], d[1], across], (int(keep.sum()), 1)))
        rhs.append(pts[keep] @ d - d @ fixed - offset[keep])
    prior = math.sqrt(PRIOR_WEIGHT)
    rows.append(prior * np.eye(3))
    rhs.append(prior * np.array([h.x, h.y, h.width]))
    t = np.linalg.lstsq(np.concatenate(rows), np.concatenate(rhs), rcond=None)[0]
    return dataclasses.replace(h, x=float(t[0]), y=float(t[1]), width=max(float(t[2]), 0.1))


def side_weight(side: int, weights: Array, means: Array, columns: list[str]) -> float:
    """The share of the mixture's weight on components whose chirality has `side`'s sign
    (a chirality of 0 reads as +1, as `Hypothesis.from_label`)."""
    w = np.asarray(weights, dtype=np.float64)
    chirality = np.asarray(means, dtype=np.float64)[:, columns.index("chirality")]
    on_side = (chirality >= 0) == (side > 0)
    total = float(w.sum())
    return float(w[on_side].sum() / total) if total > 0 else 0.5


def _choose_side(
    candidates: list[Candidate], network_side: int, side_weight: float = 1.0
) -> Candidate:
    """The lowest-residual candidate, the network's hinge side unless the other side's best
    residual is lower by more than a margin of it: `SIDE_MARGIN` (2 w - 1) for the mixture's
    weight w on the network's side (`side_weight`). A closed door's mirror image fits the
    depth about as well: there a confident network's side stands; a mixture split between
    the sides (w near 0.5, which `artic predict` warns about) leaves the choice to the
    residual."""
    best = min(candidates, key=lambda c: c.residual)
    same = [c for c in candidates if c.chirality == network_side]
    if best.chirality == network_side or not same:
        return best
    keep = min(same, key=lambda c: c.residual)
    margin = SIDE_MARGIN * float(np.clip(2.0 * side_weight - 1.0, 0.0, 1.0))
    return best if best.residual < (1.0 - margin) * keep.residual else keep


def handle_position(
    h: Hypothesis,
    category: str,
    parts: PartsConfig,
    depth: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> float | None:
    """Where the image shows the handle of `h`'s door: the position of its centre across
    the door from the hinge (0) to the free edge (1; beyond: below 0 or above 1), or None
    when no handle stands out (module docstring, `HANDLE_*`): the pixels inside the door's
    (widened) outline standing proud of its front plane (as the image has it: their
    median) by more than the threshold, after a binary opening (`HANDLE_OPENING`:
    isolated noise and one-row slivers go), grouped into connected blobs; the largest blob at most
    `HANDLE_EXTENT` across the door with at least `HANDLE_PIXELS` pixels is the handle.
    `depth` (H, W) metres in `camera`."""
    from scipy import ndimage

    from artic.objects.categories import build

    obj = build(h.spec(category, parts))
    joint = obj.movable_joints[0]  # the first door (a refrigerator's lower one)
    door = next(link for link in obj.links if link.name == joint.child)
    lo, hi = door.mesh.vertices.min(axis=0), door.mesh.vertices.max(axis=0)
    pose = h.door_poses(obj.movable_joints)[0]
    image = np.where(np.isfinite(depth), depth, 0)
    rows, cols = np.nonzero(image > 0)
    local = (camera.back_project(image) - pose[:3, 3]) @ pose[:3, :3]  # door frame: hinge y = 0
    # across the door, its outline widened by HANDLE_BEYOND (a door wider than the
    # hypothesis' has its handle beyond it); up it, inset by HANDLE_EDGE
    up = (local[:, 2] > lo[2] + HANDLE_EDGE) & (local[:, 2] < hi[2] - HANDLE_EDGE)
    inside = up & (local[:, 1] > lo[1] - HANDLE_BEYOND) & (local[:, 1] < hi[1] + HANDLE_BEYOND)
    core = up & (local[:, 1] > lo[1] + HANDLE_BEYOND) & (local[:, 1] < hi[1] - HANDLE_BEYOND)
    near = inside & (np.abs(local[:, 0] - lo[0]) < HANDLE_PROUD[1])
    if near.sum() < MIN_FACE_POINTS or core.sum() < MIN_FACE_POINTS:
        return None
    offset = local[:, 0] - _door_plane(local, near)  # towards the camera is -x
    noise = 1.4826 * float(np.median(np.abs(offset[near])))
    threshold = max(HANDLE_PROUD[0], HANDLE_NOISE * noise)
    if float(np.mean(np.abs(offset[core]) < threshold)) < HANDLE_PLANE_SHARE:
        return None
    proud = inside & (offset < -threshold) & (offset > -HANDLE_PROUD[1])
    if proud.sum() > HANDLE_SURFACE_SHARE * inside.sum():
        # a surface, not a handle: a frame round a recessed window or panel (the median
        # plane is the recess); the handle stands proud of the frame
        offset = offset - float(np.median(offset[proud]))
        proud = inside & (offset < -threshold) & (offset > -HANDLE_PROUD[1])
    mask = np.zeros(image.shape, dtype=bool)
    mask[rows[proud], cols[proud]] = True
    mask = ndimage.binary_opening(mask, structure=np.ones(HANDLE_OPENING, dtype=bool))
    blobs, count = ndimage.label(mask)
    if count == 0:
        return None
    free = hi[1] if abs(hi[1]) > abs(lo[1]) else lo[1]  # the free edge's y (hinge: 0)
    across = np.full(image.shape, np.nan)
    across[rows, cols] = local[:, 1] / free  # 0 at the hinge, 1 at the free edge
    best: tuple[int, float] | None = None
    for k, found in enumerate(ndimage.find_objects(blobs), start=1):
        y = across[found][blobs[found] == k]
        compact = float(y.max() - y.min()) * abs(free) <= HANDLE_EXTENT
        if len(y) >= HANDLE_PIXELS and compact and (best is None or len(y) > best[0]):
            best = (len(y), float(np.mean(y)))
    return None if best is None else best[1]


def _door_plane(local: Array, near: NDArray[np.bool_]) -> Array:
    """The door's front as the image has it, at each point (N,): the plane x = a + b y +
    c z (door frame) fitted by least squares to the `near` points, refitted once without
    those beyond 3 robust deviations (at least `LINE_FLOOR`; a handle's points). A
    candidate's door a few degrees off the image's (its q or yaw) would otherwise have
    the door's hinge or free edge standing proud of the hypothesis' plane like a handle."""
    design = np.column_stack([np.ones(len(local)), local[:, 1], local[:, 2]])
    coef = np.linalg.lstsq(design[near], local[near, 0], rcond=None)[0]
    residual = np.abs(local[:, 0] - design @ coef)
    limit = max(3.0 * 1.4826 * float(np.median(residual[near])), LINE_FLOOR)
    keep = near & (residual < limit)
    if keep.sum() >= MIN_FACE_POINTS:
        coef = np.linalg.lstsq(design[keep], local[keep, 0], rcond=None)[0]
    return np.asarray(design @ coef)


def handle_side(
    candidates: list[Candidate],
    columns: list[str],
    category: str,
    parts: PartsConfig,
    depth: NDArray[np.floating],
    camera: CameraIntrinsics,
    model_view: tuple[NDArray[np.float32], CameraIntrinsics] | None = None,
) -> int | None:
    """The hinge side the handle names (module docstring). Each side's lowest-residual
    candidate whose door is open less than `HANDLE_Q_MAX` and whose residual is within
    `HANDLE_RESIDUAL` times the lowest votes: for its own side when its door has the
    handle (`handle_position`) in its free part (at least `HANDLE_FREE` of the way from
    the hinge), for the other when it has it by the hinge (at most 1 - `HANDLE_FREE`). A
    side is named when every vote is for it; None without a vote or with split votes.
    `model_view` (the image in the model's camera, as the candidates were scored): each
    hypothesis with the width its front shows where that fits the image better
    (`_front_read`): a door's handle lies at its free edge, which a width read 10-20 cm
    too wide moves off it (a box turned 35-45 deg); None: the candidates' widths."""
    votes = set()
    for side, h in _nearly_closed(candidates, columns, HANDLE_Q_MAX).items():
        if model_view is not None:
            own = min(c.residual for c in candidates if c.chirality == side)
            h = _front_read(h, own, category, columns, parts, *model_view)
        at = handle_position(h, category, parts, depth, camera)
        if at is not None and at >= HANDLE_FREE:
            votes.add(side)
        elif at is not None and at <= 1.0 - HANDLE_FREE:
            votes.add(-side)
    return votes.pop() if len(votes) == 1 else None


def _front_read(
    h: Hypothesis,
    residual: float,
    category: str,
    columns: list[str],
    parts: PartsConfig,
    observed: NDArray[np.float32],
    camera: CameraIntrinsics,
) -> Hypothesis:
    """`h` (of depth residual `residual` in `camera`) with the width its front shows
    (`front_width`), when that, built and scored as it is (one build, one image), has a
    lower depth residual than `residual`; else `h`. The front's far edge misreads a door
    opened a few degrees past the front's band, which the residual turns down."""
    read = front_width(h, observed, camera, parts.door_thickness)
    if read is None:
        return h
    scored = _rounds_from(read, observed, camera, category, columns, parts, rounds=False)
    return read if scored is not None and scored[1] < residual else h


def panel_recess(
    h: Hypothesis,
    category: str,
    parts: PartsConfig,
    observed: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> float | None:
    """The median of (observed - rendered) depth (m) over the control panel of `h` (the
    body's pixels on the panel's front, the middle `PANEL_ROWS` of its height) in the
    model's camera; None below `MIN_PANEL_PIXELS` pixels."""
    renderer = PosedRenderer(h, category, parts, camera)
    try:
        image, _ = renderer.render(h)
    finally:
        renderer.close()
    rendered = image.depth
    rows, cols = np.nonzero((rendered > 0) & (image.part_mask == 1) & (observed > 0))
    points = camera.ray_directions()[rows, cols].astype(np.float64) * rendered[rows, cols, None]
    pose = h.pose_matrix()
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    up = local[:, 2] / h.height
    on = (
        (local[:, 0] < -h.depth / 2 - parts.door_thickness / 2)
        & (up > PANEL_ROWS[0])
        & (up < PANEL_ROWS[1])
    )
    if on.sum() < MIN_PANEL_PIXELS:
        return None
    return float(np.median(observed[rows[on], cols[on]] - rendered[rows[on], cols[on]]))


def panel_side(
    candidates: list[Candidate],
    columns: list[str],
    category: str,
    parts: PartsConfig,
    observed: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> int | None:
    """The hinge side the control panel names, for a nearly closed door with a panel
    beside its free edge (`PANEL_BESIDE`): the two sides' candidates (each side's lowest
    residual, within `HANDLE_RESIDUAL` times the lowest, its door open less than
    `PANEL_Q_MAX`) put the panel at opposite ends of one front. A door with a window recessed
    in its frame (or one the sensor sees through, to the mesh behind) makes the end that
    is the door read recessed where a candidate puts its panel there (`panel_recess`),
    while the end that is the panel reads flush (or proud: its buttons). A side is named
    when its panel reads flush or proud (recessed by less than `PANEL_RECESS`) and at
    least `PANEL_MARGIN` less recessed than the other side's, which reads recessed by
    more than `PANEL_RECESS`; None otherwise (a flat door, the artic
    generator's, whose handle decides; a door without a window)."""
    if category not in PANEL_BESIDE:
        return None
    sides = _nearly_closed(candidates, columns, PANEL_Q_MAX)
    if len(sides) < 2:
        return None
    recess: dict[int, float] = {}
    for side, h in sides.items():
        value = panel_recess(h, category, parts, observed, camera)
        if value is None:
            return None
        recess[side] = value
    for side in (1, -1):
        flush = recess[side] < min(PANEL_RECESS, recess[-side] - PANEL_MARGIN)
        if recess[-side] > PANEL_RECESS and flush:
            return side
    return None


def seam_profile(
    h: Hypothesis,
    parts: PartsConfig,
    depth: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> Array | None:
    """Across the front of `h`'s body (from its +y end, the image's left, to its -y end)
    in `SEAM_BINS` bins: the share of `SEAM_ROWS` rows (the middle `PANEL_ROWS` of its
    height) with a deep pixel in the bin (`SEAM_DEEP`). `depth` (H, W) metres in
    `camera`; None when fewer than half the rows are in the image with their front at
    least half seen."""
    from scipy import ndimage

    pose = h.pose_matrix()
    front = -h.depth / 2 - parts.door_thickness
    image = np.where(np.isfinite(depth), depth, 0)
    hits, rows = np.zeros(SEAM_BINS), 0
    for z in h.height * np.linspace(*PANEL_ROWS, SEAM_ROWS):
        ends = np.array([[front, h.width / 2, z], [front, -h.width / 2, z]])
        (ul, vl), (ur, vr) = camera.project(ends @ pose[:3, :3].T + pose[:3, 3])
        a, b, v = round(ul), round(ur), round((vl + vr) / 2)
        if not (0 <= v < camera.height and a >= 0 and b < camera.width and b - a >= SEAM_BINS):
            continue
        row = image[v, a : b + 1]
        valid = np.nonzero(row > 0)[0]
        if len(valid) < len(row) / 2:
            continue
        filled = np.interp(np.arange(len(row)), valid, row[valid])
        level = ndimage.median_filter(filled, size=(len(row) // 12) | 1, mode="nearest")
        deep = (row <= 0) | (row > level + SEAM_DEEP)
        bins = np.minimum(np.arange(len(row)) * SEAM_BINS // len(row), SEAM_BINS - 1)
        hits += np.bincount(bins[deep], minlength=SEAM_BINS) > 0
        rows += 1
    return hits / rows if rows >= SEAM_ROWS / 2 else None


def seam_side(
    candidates: list[Candidate],
    columns: list[str],
    category: str,
    parts: PartsConfig,
    depth: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> int | None:
    """The hinge side the seam between a nearly closed door and the control panel beside
    its free edge names (`PANEL_BESIDE`; module docstring), read on the front of the
    lowest-residual candidate when both sides have a candidate with its door open less
    than `HANDLE_Q_MAX` (`_nearly_closed`): the side whose panel the seams found are at
    (`SEAM_AT`, `seam_profile`); None without a seam, or with seams at both ends."""
    if category not in PANEL_BESIDE or len(_nearly_closed(candidates, columns, HANDLE_Q_MAX)) < 2:
        return None
    best = min(candidates, key=lambda c: c.residual)
    profile = seam_profile(Hypothesis.from_label(best.label, columns), parts, depth, camera)
    if profile is None:
        return None
    from scipy import ndimage

    inner = np.nonzero(profile < 0.5)[0]
    if len(inner) < SEAM_BINS // 4:
        return None
    first, last = int(inner[0]), int(inner[-1])  # the front's ends: runs lie between them
    runs, _ = ndimage.label(profile[first : last + 1] >= SEAM_SHARE)
    votes = set()
    for found in ndimage.find_objects(runs):
        lo, hi = found[0].start, found[0].stop  # bins first + lo ... first + hi - 1
        if hi - lo > SEAM_WIDTH:
            continue
        at = ((lo + hi - 1) / 2 + 0.5) / (last + 1 - first)
        if SEAM_AT[0] <= at <= SEAM_AT[1]:
            votes.add(1)
        elif SEAM_AT[0] <= 1.0 - at <= SEAM_AT[1]:
            votes.add(-1)
    return votes.pop() if len(votes) == 1 else None


def front_profile(
    h: Hypothesis,
    parts: PartsConfig,
    depth: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> Array | None:
    """The depth of the front of `h`'s body across it, in `SEAM_BINS` bins from its -y end
    to its +y end: the median object-frame x (m; smaller is nearer the camera) of the
    points of `depth` (H, W metres in `camera`) within `FRONT_BAND` of the front's plane,
    over the middle `PANEL_ROWS` of the body's height (NaN in a bin with fewer than
    `MIN_BIN_POINTS`). None when the front spans fewer than `SEAM_BINS` pixels (a bin
    would be less than a pixel) or fewer than `FRONT_SEEN` of the bins are seen."""
    pose = h.pose_matrix()
    front = -h.depth / 2 - parts.door_thickness
    ends = np.array([[front, h.width / 2, h.height / 2], [front, -h.width / 2, h.height / 2]])
    (ul, _), (ur, _) = camera.project(ends @ pose[:3, :3].T + pose[:3, 3])
    if abs(ur - ul) < SEAM_BINS:
        return None
    from scipy import ndimage

    local = _object_points(h, depth, camera)
    up = local[:, 2] / h.height
    on = (
        (up > PANEL_ROWS[0])
        & (up < PANEL_ROWS[1])
        & (np.abs(local[:, 1]) < h.width / 2)
        & (np.abs(local[:, 0] - front) < FRONT_BAND)
    )
    if int(on.sum()) < MIN_BIN_POINTS * math.ceil(FRONT_SEEN * SEAM_BINS):
        return None  # too few points to see `FRONT_SEEN` of the bins (none: nothing to bin)
    across = ((local[on, 1] + h.width / 2) / h.width * SEAM_BINS).astype(int)
    across = np.clip(across, 0, SEAM_BINS - 1)
    bins = np.arange(SEAM_BINS)
    median = np.asarray(ndimage.median(local[on, 0], across, bins), dtype=np.float64)
    counted = np.bincount(across, minlength=SEAM_BINS) >= MIN_BIN_POINTS
    profile = np.where(counted, median, np.nan)
    return profile if counted.mean() >= FRONT_SEEN else None


def front_fit(profile: Array, side: int) -> float:
    """How well the front's `profile` (`front_profile`) reads as a door hinged on `side`
    beside a flat control panel: the least mean residual (m, each capped at `FRONT_CAP`)
    over the door's shares of the front (`FRONT_DOOR_SHARES`) of a robust (Huber) fit of
    the body's front as a line across the bins, plus, on the door's bins, an offset and a
    line that starts at the hinge (a door turned about its hinge stands out in proportion
    to the distance from it). Side +1 has its hinge at the -y end (bin 0)."""
    across = (np.arange(SEAM_BINS) + 0.5) / SEAM_BINS
    from_hinge = across if side > 0 else 1.0 - across
    seen = np.isfinite(profile)
    best = math.inf
    for share in FRONT_DOOR_SHARES:
        door = (from_hinge < share).astype(np.float64)
        design = np.column_stack([np.ones(SEAM_BINS), across, door, door * from_hinge])[seen]
        x = profile[seen]
        weight = np.ones(len(x))
        for _ in range(5):
            coef = np.linalg.lstsq(design * weight[:, None], x * weight, rcond=None)[0]
            residual = np.abs(x - design @ coef)
            scale = max(1.4826 * float(np.median(residual)), FRONT_FLOOR)
            weight = np.sqrt(np.minimum(1.0, 2.0 * scale / np.maximum(residual, 1e-12)))
        best = min(best, float(np.mean(np.minimum(residual, FRONT_CAP))))
    return best


def front_side(
    candidates: list[Candidate],
    columns: list[str],
    category: str,
    parts: PartsConfig,
    depth: NDArray[np.floating],
    camera: CameraIntrinsics,
) -> int | None:
    """The hinge side the front's shape names (`PANEL_BESIDE`; module docstring), read on
    the front of the lowest-residual candidate when its door is open less than
    `HANDLE_Q_MAX` (the front is then one surface, whichever the side): the side whose
    hinged door beside a flat panel fits the front's profile `FRONT_RATIO` times better
    than the other's (`front_fit`); None otherwise (a door closed flush fits both sides
    alike)."""
    if category not in PANEL_BESIDE or not candidates:
        return None
    best = min(candidates, key=lambda c: c.residual)
    h = Hypothesis.from_label(best.label, columns)
    if max(h.qs) >= HANDLE_Q_MAX:
        return None
    profile = front_profile(h, parts, depth, camera)
    if profile is None:
        return None
    fits = {side: front_fit(profile, side) for side in (1, -1)}
    for side in (1, -1):
        if FRONT_RATIO * fits[side] < fits[-side]:
            return side
    return None


def _nearly_closed(
    candidates: list[Candidate], columns: list[str], q_limit: float
) -> dict[int, Hypothesis]:
    """Per hinge side, its lowest-residual candidate's hypothesis when its doors are open
    less than `q_limit` and its residual is within `HANDLE_RESIDUAL` times the lowest (a
    door open far, seen by a candidate that has it closed, shows its edge standing proud):
    the candidates `handle_side`, `panel_side` and `seam_side` read."""
    floor = min((c.residual for c in candidates), default=math.inf)
    out: dict[int, Hypothesis] = {}
    for side in (1, -1):
        same = [c for c in candidates if c.chirality == side]
        if not same:
            continue
        best = min(same, key=lambda c: c.residual)
        h = Hypothesis.from_label(best.label, columns)
        if max(h.qs) < q_limit and best.residual <= HANDLE_RESIDUAL * floor:
            out[side] = h
    return out


def _side(h: Hypothesis, chirality: int) -> Hypothesis:
    return h if h.chirality == chirality else h.mirrored()
