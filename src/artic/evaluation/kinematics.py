"""Table 3.1 metrics: axis position, axis orientation about z, configuration errors,
and the calibration of predicted intervals.

Errors are per image. For two-DoF objects the position and configuration errors are the
mean over the two joints. The axis orientation about z is the yaw of the axis frame,
which for every category is the object's yaw (`pose_yaw`): the joint frames are the
body's frame rotated about z (docs/formats.md).

`rotation_thesis_deg` is the rotation error as the thesis' evaluation code computes it,
for comparison with Table 3.1's column: the axis quaternion of an object at angle
pi + yaw about z (the thesis generator's objects face the camera at pi) becomes the
angle 2 acos(w) after w is clamped to [0, 1], so every yaw > 0 becomes 180 deg; the
error is the difference of those angles. It is about half the yaw error for a Mean
predictor (docs/reproduction.md, Chapter 3).

`hinge_side_wrong_pct` is 100 on an image whose estimated chirality has the other sign
than the true one (the hinge on the wrong edge of the door: about half a door's width
off), else 0: its mean is the percentage of images with the wrong hinge side.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from artic.objects.labels import joint_column, joint_vector

METRICS = (
    "position_cm",
    "rotation_deg",
    "configuration",
    "rotation_thesis_deg",
    "hinge_side_wrong_pct",
)


def wrap_angle(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles to (-pi, pi]."""
    return np.asarray(np.pi - np.mod(np.pi - a, 2 * np.pi))


def thesis_axis_angle(yaw: NDArray[np.float64]) -> NDArray[np.float64]:
    """The angle the thesis' code reads off the axis quaternion of yaw (radians): pi + yaw
    for yaw <= 0 and pi for yaw > 0 (`2 acos(clamp(w, 0, 1))`, module docstring)."""
    w = np.cos((np.pi + wrap_angle(np.asarray(yaw, dtype=np.float64))) / 2)
    return np.asarray(2 * np.arccos(np.clip(w, 0.0, 1.0)))


def kinematic_errors(
    pred: NDArray[np.float64],
    true: NDArray[np.float64],
    columns: list[str],
    dof: int,
    joint_type: str,
) -> dict[str, NDArray[np.float64]]:
    """Per-image errors of label vectors (N, L): position in cm, rotation about z in
    degrees, configuration in degrees (revolute) or cm (prismatic), the rotation error as
    the thesis' code computes it (degrees) and the hinge side (module docstring)."""
    col = {c: i for i, c in enumerate(columns)}
    position = np.zeros(len(true))
    configuration = np.zeros(len(true))
    for j in range(dof):
        o = [col[c] for c in joint_vector(j, "origin")]
        position += np.linalg.norm(pred[:, o] - true[:, o], axis=1)
        q = col[joint_column(j, "q")]
        configuration += np.abs(pred[:, q] - true[:, q])
    yaw = col["pose_yaw"]
    side = col["chirality"]
    scale = np.degrees(1.0) if joint_type == "revolute" else 100.0
    return {
        "position_cm": 100.0 * position / dof,
        "rotation_deg": np.degrees(np.abs(wrap_angle(pred[:, yaw] - true[:, yaw]))),
        "configuration": scale * configuration / dof,
        "rotation_thesis_deg": np.degrees(
            np.abs(thesis_axis_angle(pred[:, yaw]) - thesis_axis_angle(true[:, yaw]))
        ),
        "hinge_side_wrong_pct": 100.0 * ((pred[:, side] >= 0) != (true[:, side] >= 0)),
    }


def configuration_unit(joint_type: str) -> str:
    return "deg" if joint_type == "revolute" else "cm"


def coverage(
    lower: NDArray[np.float64], upper: NDArray[np.float64], true: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per column: the fraction of rows whose true value lies in [lower, upper]."""
    inside = (true >= lower) & (true <= upper)
    return np.asarray(inside.mean(axis=0), dtype=np.float64)


# Table 3.1 as `evaluate mdn` writes it: rows of summary.csv, errors.csv, calibration.csv
# and the report. errors: method -> metric -> (N,) per-image errors (`kinematic_errors`);
# coverage: nominal level -> (L,) fraction of true values inside the central interval.

Errors = dict[str, dict[str, NDArray[np.float64]]]
Row = list[float | int | str]

SUMMARY_HEADER = ["method", "images"] + [f"{m}_{s}" for m in METRICS for s in ("mean", "std")]
ERRORS_HEADER = ["method", "image", "object_id", *METRICS]


def summary_rows(errors: Errors, methods: tuple[str, ...]) -> list[Row]:
    """summary.csv: per method (in `methods` order, those evaluated) the number of images
    and the mean and standard deviation of each metric."""
    rows: list[Row] = []
    for name in methods:
        if name in errors:
            e = errors[name]
            stats = [v for m in METRICS for v in (float(e[m].mean()), float(e[m].std()))]
            rows.append([name, len(e["position_cm"]), *stats])
    return rows


def per_image_rows(errors: Errors, object_id: NDArray[np.integer]) -> list[Row]:
    """errors.csv: one row per method and image (ICP: the first images only)."""
    rows: list[Row] = []
    for name, e in errors.items():
        for i in range(len(e["position_cm"])):
            rows.append([name, i, int(object_id[i]), *(float(e[m][i]) for m in METRICS)])
    return rows


def calibration_groups(columns: list[str], dof: int) -> dict[str, list[int]]:
    """Column indices of the calibration table's groups."""
    col = {c: i for i, c in enumerate(columns)}
    return {
        "all predicted columns": list(range(len(columns))),
        "axis origin": [col[c] for j in range(dof) for c in joint_vector(j, "origin")],
        "axis yaw": [col["pose_yaw"]],
        "configuration": [col[joint_column(j, "q")] for j in range(dof)],
    }


def calibration_rows(
    coverage: dict[float, NDArray[np.float64]], groups: dict[str, list[int]]
) -> list[Row]:
    """calibration.csv: per nominal level, the mean coverage of each group's columns."""
    rows: list[Row] = []
    for lv in sorted(coverage):
        rows.append([lv, *(float(np.nanmean(coverage[lv][idx])) for idx in groups.values())])
    return rows


def table_3_1_report(
    category: str,
    rows: list[Row],
    coverage: dict[float, NDArray[np.float64]],
    groups: dict[str, list[int]],
    levels: tuple[float, ...],
    unit: str,
    n_test: int,
) -> str:
    """report.md of `evaluate mdn`: the Table 3.1 block (`summary_rows`) and the
    calibration of the MDN's intervals at `levels`."""
    name, n = category, len(METRICS)  # the header names the METRICS in order
    lines = [
        f"# Table 3.1: {name}",
        "",
        f"{n_test} test images of withheld objects; errors as mean ± std. "
        "Ours: the mean of the MDN's most likely component, the one of largest weight "
        "(section 3.3.1); Ours (densest): the component mean of highest mixture density. "
        "Rot. (thesis' metric): the rotation error as the thesis' evaluation code computes "
        "it, for comparison with its Table 3.1 (docs/reproduction.md).",
        "",
        f"| {name} | Axis Pos. Error (cm) | Axis Rot. Error (deg) "
        f"| Config. Error ({unit}) | Rot. (thesis' metric, deg) | Hinge side wrong (%) "
        "| images |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        cells = [f"{float(r[2 + 2 * k]):.2f} ± {float(r[3 + 2 * k]):.2f}" for k in range(n)]
        lines.append(f"| {r[0]} | {' | '.join(cells)} | {r[1]} |")
    lines += [
        "",
        "## Calibration of the MDN",
        "",
        "Fraction of true values inside the predicted central intervals of each label's "
        "marginal (mean over the columns of each group).",
        "",
        "| nominal | " + " | ".join(groups) + " |",
        "|---|" + "---|" * len(groups),
    ]
    for lv in levels:
        cells = [f"{100 * np.nanmean(coverage[lv][idx]):.1f}%" for idx in groups.values()]
        lines.append(f"| {100 * lv:.0f}% | " + " | ".join(cells) + " |")
    lines += ["", "Plots: errors.png, calibration.png, examples.png. Data: summary.csv, "
              "errors.csv, calibration.csv.", ""]  # fmt: skip
    return "\n".join(lines)
