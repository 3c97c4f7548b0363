"""`artic segment`, `artic build-hierarchy` and `artic infer-hierarchy`: one scan (PLY) in,
one output folder out (docs/hierarchy.md, docs/formats.md "Hierarchies (Chapter 4)").

- segment SCAN -> DIR/parts.ply (points, part_id, motion_type, confidence) and
  DIR/segmentation.json; DIR defaults to `<scan stem>_segmented/` beside the scan.
- build-hierarchy PARTS (a PLY with part_id) -> DIR/hierarchy.json, object.urdf,
  meshes/, hierarchy.png; DIR defaults to `<stem>_hierarchy/` beside the file, or, for
  the parts.ply of a segment output `X_segmented/`, to `X_hierarchy/` beside it.
- infer-hierarchy SCAN -> both: hierarchy.json, object.urdf, meshes/, parts.ply,
  hierarchy.png; DIR defaults to `<scan stem>_hierarchy/`.

Inputs are checked before any work: a missing, empty or non-PLY file, NaN or infinite
coordinates, fewer points than the segmenter needs, or millimetre units (unless
`--scale auto`, which divides by 1000 and says so) exit with code 2 and one line. A
cloud above `--max-points` is handled by working on a seeded random subset (logged);
every input point still gets a label. Outputs are in metres, in the scan's frame: with
`--yaw canonical` (the default of segment and infer-hierarchy) the scan's yaw is
estimated and the networks work in the object frame (docs/hierarchy.md, "Scan frame and
yaw"); `--yaw none` takes the scan as it is.

The commands read the scan (`artifacts.scan_file`), run the networks (`hierarchy.infer`)
and write through `artifacts.scan_outputs` and `artifacts.ply`; their options and Rich
summary are the CLI's (`cli/infer_hierarchy.py`), which turns `CommandFailed` into an
internal error (exit 1).
"""

from __future__ import annotations

import logging
import traceback
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray

from artic.artifacts.manifest import LOG
from artic.artifacts.model_store import ModelChoice
from artic.artifacts.ply import write_ply
from artic.artifacts.scan_file import read_scan, require_points
from artic.artifacts.scan_outputs import (
    OutputFolder,
    check_output_folder,
    default_out,
    write_document,
    write_text_files,
)
from artic.errors import InputError
from artic.evaluation.hierarchy_plot import draw_hierarchy
from artic.hierarchy.infer import MAX_POINTS
from artic.hierarchy.models import find_labeller, find_segmenter, hierarchy_config
from artic.hierarchy.report import (
    hierarchy_document,
    input_info,
    part_subset,
    robot_name,
    rounded_timings,
    segmentation_document,
)

if TYPE_CHECKING:
    from artic.hierarchy.canonical import YawEstimate
    from artic.hierarchy.infer import HierarchyResult, LabelledHierarchy, ScanSegmentation

__all__ = [
    "CommandFailed",
    "CommandResult",
    "Options",
    "run_build_hierarchy",
    "run_infer_hierarchy",
    "run_segment",
]

log = logging.getLogger("artic")


@dataclass(frozen=True)
class Options:
    """The settings shared by the three commands (recorded in the manifest)."""

    category: str | None = None  # None: infer-hierarchy's given model's, else storage_furniture
    scale: str = "1"  # "auto" or a positive factor applied to the coordinates
    max_points: int = MAX_POINTS
    seed: int = 0
    yaw: Literal["canonical", "none"] = "canonical"  # segment, infer-hierarchy: HierarchyConfig.yaw


@dataclass(frozen=True)
class CommandResult:
    """What a command did, for the summary: the folder, the parts, the tree."""

    command: str
    out: Path
    num_parts: int
    points: int
    hierarchy: LabelledHierarchy | None = None
    timings: dict[str, float] = field(default_factory=dict)
    models: tuple[ModelChoice, ...] = ()
    yaw: YawEstimate | None = None  # --yaw canonical: the scan's estimated yaw


def _options_dict(opts: Options, models: dict[str, Path]) -> dict[str, Any]:
    return {
        "category": opts.category,
        "scale": opts.scale,
        "max_points": opts.max_points,
        "seed": opts.seed,
        "yaw": opts.yaw,
        **{name: str(path) for name, path in models.items()},
    }


#: a front chosen with less confidence is reported as uncertain (above it, the front of
#: every test scan of storage furniture was right: docs/hierarchy.md "Scan frame and yaw")
YAW_WARNING = 0.9


def uncertain_front(yaw: YawEstimate) -> str | None:
    """The warning for a scan whose front was found with little confidence, else None."""
    if yaw.front_confidence >= YAW_WARNING:
        return None
    return (
        f"the scan's front is uncertain (yaw {yaw.yaw_deg:.1f} deg, front confidence "
        f"{yaw.front_confidence:.2f}); if the parts look wrong, turn the scan so its front "
        "faces -x and pass --yaw none"
    )


def _yaw_record(opts: Options, yaw: YawEstimate | None) -> dict[str, Any]:
    """The "yaw" entry of the documents' "input": the mode, and the estimate (degrees:
    the scan is the object frame turned by yaw_deg about z)."""
    return {"mode": opts.yaw, **({} if yaw is None else yaw.to_dict())}


class CommandFailed(Exception):
    """An unexpected failure while a command wrote its output folder: the traceback is in
    `log_path` (the log of the kept `DIR.partial/`)."""

    def __init__(self, message: str, log_path: Path) -> None:
        super().__init__(message)
        self.log_path = log_path


def _write(folder: OutputFolder, command: str, body: Any) -> None:
    """Run `body(folder.path)`; on failure leave no half-written output (bad input) or
    keep DIR.partial/ with the traceback in its log (CommandFailed)."""
    try:
        body(folder.path)
    except InputError:
        folder.abandon()
        raise
    except Exception as err:
        log.error("internal error in %s:\n%s", command, traceback.format_exc())
        folder.close_log()
        raise CommandFailed(f"{command}: {type(err).__name__}: {err}", folder.path / LOG) from err


def run_segment(
    scan_path: Path, model: Path | None, out: Path | None, opts: Options
) -> CommandResult:
    """`artic segment`: parts.ply + segmentation.json."""
    from artic.hierarchy.infer import required_points, segment_scan

    scan = read_scan(scan_path, opts.scale, opts.max_points, opts.seed)
    out = out or default_out(scan_path, "segment")
    check_output_folder(out, "segment")  # every input before the models are loaded
    segmenter, choice = find_segmenter(model, opts.category, "--model")
    model_path = choice.path
    require_points(scan, required_points(segmenter.model))
    cfg = replace(hierarchy_config(segmenter, None, opts.max_points), yaw=opts.yaw)
    folder = OutputFolder(
        out,
        "segment",
        _options_dict(opts, {"model": model_path}),
        {"scan": scan_path, "model": model_path},
    )
    done: list[ScanSegmentation] = []

    def body(tmp: Path) -> None:
        rng = np.random.default_rng(opts.seed)
        seg = segment_scan(scan.points, segmenter.model, cfg, rng)
        done.append(seg)
        comments = ["artic segment", f"source {scan_path.name}", "frame input, metres"]
        write_ply(
            tmp / "parts.ply",
            scan.points,
            seg.part_id,
            seg.motion_type,
            seg.part_confidence[seg.part_id],
            comments,
        )
        worked_on = input_info(scan.path, len(scan.points), scan.factor, len(seg.sampled))
        worked_on["yaw"] = _yaw_record(opts, seg.yaw)
        models = {"segmenter": str(model_path), "category": segmenter.category}
        document = segmentation_document(seg, worked_on, models)
        write_document(tmp / "segmentation.json", document)

    _write(folder, "segment", body)
    seg = done[0]
    folder.publish(opts.seed, {"parts": seg.num_parts, "points": len(scan.points)})
    return CommandResult(
        "segment", out, seg.num_parts, len(scan.points), None, seg.timings, (choice,), seg.yaw
    )


def _write_hierarchy_files(
    tmp: Path,
    points: NDArray[np.float32],
    part_id: NDArray[np.int64],
    hierarchy: LabelledHierarchy,
    document: dict[str, Any],
    name: str,
) -> None:
    """hierarchy.json, object.urdf, meshes/ and hierarchy.png of a hierarchy over the
    parts of `points` (M, 3) / `part_id` (M,)."""
    from artic.hierarchy.urdf import TreeUrdfConfig, tree_to_urdf

    write_document(tmp / "hierarchy.json", document)
    files = tree_to_urdf(hierarchy.tree, points, part_id, TreeUrdfConfig(name=robot_name(name)))
    write_text_files(tmp, {"object.urdf": files.urdf, **files.meshes})
    draw_hierarchy(tmp / "hierarchy.png", points, part_id, hierarchy.tree, name)


def run_build_hierarchy(
    parts_path: Path, model: Path | None, out: Path | None, opts: Options
) -> CommandResult:
    """`artic build-hierarchy`: hierarchy.json, object.urdf + meshes, hierarchy.png."""
    from artic.hierarchy.infer import build_hierarchy

    scan = read_scan(parts_path, opts.scale, opts.max_points, opts.seed)
    if scan.part_id is None:
        raise InputError(
            f"{parts_path}: no part_id property; segment the scan first (artic segment)"
        )
    if scan.part_id.min() < 0:
        raise InputError(f"{parts_path}: part_id must be >= 0 for every point")
    out = out or default_out(parts_path, "build-hierarchy")
    check_output_folder(out, "build-hierarchy")  # every input before the model is loaded
    labeller, choice = find_labeller(model, opts.category, "--model")
    model_path = choice.path
    input_ids, inverse = np.unique(scan.part_id, return_inverse=True)
    part_id = inverse.astype(np.int64)
    cfg = hierarchy_config(None, labeller, opts.max_points)
    keep = part_subset(part_id, opts.max_points, opts.seed)
    work, work_id = scan.points[keep], part_id[keep]
    folder = OutputFolder(
        out,
        "build-hierarchy",
        _options_dict(replace(opts, yaw="none"), {"model": model_path}),  # cloud as it is
        {"parts": parts_path, "model": model_path},
    )
    done: list[LabelledHierarchy] = []

    def body(tmp: Path) -> None:
        rng = np.random.default_rng(opts.seed)
        hierarchy = build_hierarchy(work, work_id, labeller.model, cfg, rng)
        done.append(hierarchy)
        extra = {
            "input": input_info(scan.path, len(scan.points), scan.factor, len(keep)),
            "models": {
                "segmenter": None,
                "labeller": str(model_path),
                "category": labeller.category,
            },
            "timings_s": rounded_timings(hierarchy.timings),
            "urdf": "object.urdf",
        }
        document = hierarchy_document(hierarchy, part_id, None, input_ids.tolist(), extra)
        _write_hierarchy_files(tmp, work, work_id, hierarchy, document, parts_path.stem)

    _write(folder, "build-hierarchy", body)
    hierarchy = done[0]
    folder.publish(opts.seed, {"parts": hierarchy.tree.num_parts, "points": len(scan.points)})
    return CommandResult(
        "build-hierarchy",
        out,
        hierarchy.tree.num_parts,
        len(scan.points),
        hierarchy,
        hierarchy.timings,
        (choice,),
    )


def run_infer_hierarchy(
    scan_path: Path,
    segmenter_model: Path | None,
    labeller_model: Path | None,
    out: Path | None,
    opts: Options,
) -> CommandResult:
    """`artic infer-hierarchy`: hierarchy.json, object.urdf + meshes, parts.ply,
    hierarchy.png."""
    from artic.hierarchy.infer import infer_hierarchy, required_points

    scan = read_scan(scan_path, opts.scale, opts.max_points, opts.seed)
    out = out or default_out(scan_path, "infer-hierarchy")
    check_output_folder(out, "infer-hierarchy")  # every input before the models are loaded
    # without --category the first model given names it, and the other is found (or
    # checked) for it: two models of two categories are no pipeline
    if segmenter_model is not None or labeller_model is None:
        segmenter, seg_choice = find_segmenter(segmenter_model, opts.category)
        labeller, lab_choice = find_labeller(labeller_model, segmenter.category)
    else:
        labeller, lab_choice = find_labeller(labeller_model, opts.category)
        segmenter, seg_choice = find_segmenter(segmenter_model, labeller.category)
    seg_path, lab_path = seg_choice.path, lab_choice.path
    require_points(scan, required_points(segmenter.model))
    cfg = replace(hierarchy_config(segmenter, labeller, opts.max_points), yaw=opts.yaw)
    models = {"segmenter": seg_path, "labeller": lab_path}
    folder = OutputFolder(
        out, "infer-hierarchy", _options_dict(opts, models), {"scan": scan_path, **models}
    )
    done: list[HierarchyResult] = []

    def body(tmp: Path) -> None:
        rng = np.random.default_rng(opts.seed)
        result = infer_hierarchy(scan.points, segmenter.model, labeller.model, cfg, rng)
        done.append(result)
        seg, hierarchy = result.segmentation, result.hierarchy
        worked_on = input_info(scan.path, len(scan.points), scan.factor, len(seg.sampled))
        worked_on["yaw"] = _yaw_record(opts, result.yaw)
        extra = {
            "input": worked_on,
            "models": {
                "segmenter": str(seg_path),
                "labeller": str(lab_path),
                "category": labeller.category,
            },
            "timings_s": rounded_timings(result.timings),
            "urdf": "object.urdf",
            "ply": "parts.ply",
        }
        document = hierarchy_document(hierarchy, seg.part_id, seg.part_confidence, None, extra)
        work = scan.points[seg.sampled]
        _write_hierarchy_files(
            tmp, work, seg.part_id[seg.sampled], hierarchy, document, scan_path.stem
        )
        motion = np.asarray(hierarchy.tree.motion_types, dtype=np.int64)[seg.part_id]
        comments = [
            "artic infer-hierarchy",
            f"source {scan_path.name}",
            "frame input, metres",
            "motion_type: the part's, as in hierarchy.json",
        ]
        write_ply(
            tmp / "parts.ply",
            scan.points,
            seg.part_id,
            motion,
            seg.part_confidence[seg.part_id],
            comments,
        )

    _write(folder, "infer-hierarchy", body)
    result = done[0]
    folder.publish(opts.seed, {"parts": result.num_parts, "points": len(scan.points)})
    return CommandResult(
        "infer-hierarchy",
        out,
        result.num_parts,
        len(scan.points),
        result.hierarchy,
        result.timings,
        (seg_choice, lab_choice),
        result.yaw,
    )
