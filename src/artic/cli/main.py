"""`artic`: the command-line entry point.

Subcommands are registered here and import their heavy dependencies (numpy, open3d,
pybullet, hydra) only when they run, so `artic --help` answers quickly.
"""

from __future__ import annotations

import importlib
import logging
import sys
from pathlib import Path
from typing import Any

import typer

from artic import __version__
from artic.cli.failures import NoTracebacks, OneLineErrors, handle_errors

app = typer.Typer(
    name="artic",
    cls=OneLineErrors,
    help="Structured robotic manipulation: articulated-object datasets, depth rendering, "
    "kinematic models. Each subcommand is a stage: it reads files and writes one output "
    "folder with a manifest.json. Config overrides are Hydra-style KEY=VALUE arguments.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

#: subcommand -> module exposing STAGE (imported only when the subcommand runs)
STAGE_MODULES: dict[str, str] = {
    "generate-dataset": "artic.cli.generate_dataset",
    "render-depth": "artic.cli.render_depth",
    "render-scan": "artic.cli.render_scan",  # run as `artic render-depth render=scan`
    "train-mdn": "artic.cli.train_mdn",
    "evaluate-mdn": "artic.cli.evaluate_mdn",
    "plan-demos": "artic.cli.plan_demos",
    "fit-dmp": "artic.cli.fit_dmp",
    "policy-search": "artic.cli.policy_search",
    "evaluate-bootstrap": "artic.cli.evaluate_bootstrap",
    "train-segmenter": "artic.cli.train_segmenter",
    "train-hierarchy": "artic.cli.train_hierarchy",
    "evaluate-hierarchy": "artic.cli.evaluate_hierarchy",
}

_OVERRIDES = typer.Argument(None, help="Hydra overrides, e.g. category=drawer dataset.objects=50")
_CFG = typer.Option(False, "--cfg", help="Print the resolved config and exit.")
_FORCE = typer.Option(False, "--force", help="Recompute even if the output is up to date.")
_EXTRA = {"allow_extra_args": False, "ignore_unknown_options": True}
_TASK = typer.Option(None, "--task", help="Chapter 5 task: drawer, microwave, tball (= task=NAME)")


def _with_task(overrides: list[str] | None, task: str | None) -> list[str]:
    """`--task NAME` is shorthand for the Hydra override `task=NAME`; both naming
    different tasks is bad input (exit 2) rather than one silently winning."""
    from artic.errors import InputError

    given = [o.partition("=")[2] for o in overrides or [] if o.partition("=")[0] == "task"]
    if task and any(g != task for g in given):
        raise InputError(f"--task {task} and task={given[-1]} name different tasks; give one")
    if task and given:
        return list(overrides or [])
    return [*(overrides or []), *([f"task={task}"] if task else [])]


def stage_command(command: str, overrides: list[str] | None) -> str:
    """The stage a subcommand runs: `render-depth render=scan` runs the scan stage
    (render-depth's config tree, its own schema, stage name and output folder)."""
    if command == "render-depth" and "render=scan" in (overrides or []):
        return "render-scan"
    return command


def load_stage(command: str) -> Any:
    """The `Stage` behind a subcommand name."""
    return importlib.import_module(STAGE_MODULES[command]).STAGE


def run_stage_command(command: str, overrides: list[str] | None, cfg: bool, force: bool) -> None:
    from artic.cli.stage_runner import resolved_config, run_stage
    from artic.cli.summary import print_result

    stage = load_stage(stage_command(command, overrides))
    if cfg:
        import yaml

        typer.echo(yaml.safe_dump(resolved_config(stage, list(overrides or [])), sort_keys=False))
        return
    print_result(command, run_stage(stage, list(overrides or []), force=force))


@app.command("generate-dataset", context_settings=_EXTRA)
@handle_errors
def generate_dataset(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Procedural articulated objects (Appendix A): URDF + OBJ meshes + ObjectSpec JSON.

    Example: artic generate-dataset category=refrigerator dataset.objects=200
    """
    run_stage_command("generate-dataset", overrides, cfg, force)


@app.command("render-depth", context_settings=_EXTRA)
@handle_errors
def render_depth(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Labelled depth images across each object's articulation (section 3.2.3); with
    render=scan, fused multi-view point clouds with part labels (Chapter 4).

    Example: artic render-depth dataset=artifacts/objects/refrigerator
    """
    run_stage_command("render-depth", overrides, cfg, force)


@app.command("train-mdn", context_settings=_EXTRA)
@handle_errors
def train_mdn(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Train the per-category mixture density network (section 3.2, Eq. 3.1 and 3.2).

    Example: artic train-mdn category=microwave
    """
    run_stage_command("train-mdn", overrides, cfg, force)


@app.command("train-segmenter", context_settings=_EXTRA)
@handle_errors
def train_segmenter(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Train the part segmenter of one category on its scans (section 4.3).

    Example: artic train-segmenter category=storage_furniture
    """
    run_stage_command("train-segmenter", overrides, cfg, force)


@app.command("train-hierarchy", context_settings=_EXTRA)
@handle_errors
def train_hierarchy(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Train the graph labelling network of one category on its scans (section 4.4).

    Example: artic train-hierarchy category=storage_furniture
    """
    run_stage_command("train-hierarchy", overrides, cfg, force)


@app.command("plan-demos", context_settings=_EXTRA)
@handle_errors
def plan_demos(
    overrides: list[str] | None = _OVERRIDES,
    task: str | None = _TASK,
    cfg: bool = _CFG,
    force: bool = _FORCE,
) -> None:
    """Motion-planned demonstrations on a kinematic model (Algorithm 2).

    Example: artic plan-demos --task drawer
    """
    run_stage_command("plan-demos", _with_task(overrides, task), cfg, force)


@app.command("fit-dmp", context_settings=_EXTRA)
@handle_errors
def fit_dmp(
    overrides: list[str] | None = _OVERRIDES,
    task: str | None = _TASK,
    cfg: bool = _CFG,
    force: bool = _FORCE,
) -> None:
    """Dynamic movement primitives fitted to demonstrations by LWR (Eq. 2.4-2.7).

    Example: artic fit-dmp demos=artifacts/demos/drawer
    """
    run_stage_command("fit-dmp", _with_task(overrides, task), cfg, force)


@app.command("policy-search", context_settings=_EXTRA)
@handle_errors
def policy_search(
    overrides: list[str] | None = _OVERRIDES,
    task: str | None = _TASK,
    cfg: bool = _CFG,
    force: bool = _FORCE,
) -> None:
    """Policy search from the bootstrapped policy or from random init (section 5.2.2).

    Example: artic policy-search --task drawer
    """
    run_stage_command("policy-search", _with_task(overrides, task), cfg, force)


evaluate_app = typer.Typer(
    help="Evaluation reports on withheld objects (tables of the thesis).", no_args_is_help=True
)
app.add_typer(evaluate_app, name="evaluate")


@evaluate_app.command("mdn", context_settings=_EXTRA)
@handle_errors
def evaluate_mdn(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Table 3.1 for one category: Ours vs Mean, NN, ICP, and calibration.

    Example: artic evaluate mdn category=microwave
    """
    run_stage_command("evaluate-mdn", overrides, cfg, force)


@evaluate_app.command("hierarchy", context_settings=_EXTRA)
@handle_errors
def evaluate_hierarchy(
    overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
) -> None:
    """Tables 4.1 and 4.2 for one category: part mAP, E_type, E_exist, E_dir, E_root,
    Tree F1 (ground-truth and predicted segmentation, clean and noisy scans).

    Example: artic evaluate hierarchy category=storage_furniture
    """
    run_stage_command("evaluate-hierarchy", overrides, cfg, force)


@evaluate_app.command("bootstrap", context_settings=_EXTRA)
@handle_errors
def evaluate_bootstrap(
    overrides: list[str] | None = _OVERRIDES,
    task: str | None = _TASK,
    cfg: bool = _CFG,
    force: bool = _FORCE,
) -> None:
    """Figure 5.2: bootstrapped vs random initialisation over seeds, and success rates.

    Example: artic evaluate bootstrap --task drawer
    """
    run_stage_command("evaluate-bootstrap", _with_task(overrides, task), cfg, force)


@app.command("predict")
@handle_errors
def predict(
    image: Path = typer.Argument(..., help="depth image: .npy (float metres) or 16-bit .png (mm)"),
    category: str = typer.Option(..., "--category", help="object category (one model each)"),
    camera: Path = typer.Option(
        ..., "--camera", help="intrinsics JSON: fx, fy, cx, cy, width, height"
    ),
    mask: Path | None = typer.Option(
        None, "--mask", help="object mask (.png or .npy, nonzero = object)"
    ),
    samples: int = typer.Option(0, "--samples", min=0, help="draws from the predicted mixture"),
    estimator: str = typer.Option(
        "most-likely",
        "--estimator",
        help="most-likely (3.3.1: largest-weight component) | densest | max-point (Table 3.2)",
    ),
    model: Path | None = typer.Option(
        None, "--model", help="model.pt (default: artifacts/models/mdn/CATEGORY/model.pt)"
    ),
    seed: int = typer.Option(0, "--seed", help="seed of the samples"),
) -> None:
    """Kinematic model, configuration and geometry from one depth image, as JSON.

    Example: artic predict depth.png --category microwave --camera kinect.json --samples 100
    """
    import json

    from artic.cli.predict import predict as run
    from artic.errors import InputError
    from artic.kinematics import ESTIMATORS

    if estimator not in ESTIMATORS:
        raise InputError(f"--estimator: '{estimator}' (available: {', '.join(ESTIMATORS)})")
    result = run(image, category, camera, model, mask, samples, estimator, seed)
    typer.echo(json.dumps(result, indent=2))


_SCALE = typer.Option(
    "1", "--scale", help="auto (millimetre clouds are divided by 1000) or a factor to metres"
)
_MAX_POINTS = typer.Option(
    200_000, "--max-points", help="larger clouds: a seeded random subset is segmented"
)
_SEED = typer.Option(0, "--seed", help="seed of the subsampling and graph resampling")
_CATEGORY4 = typer.Option(
    None, "--category", help="model category (default models: storage_furniture)"
)


@app.command("segment")
@handle_errors
def segment_command(
    scan: Path = typer.Argument(..., help="point cloud (.ply, metres)"),
    category: str | None = _CATEGORY4,
    model: Path | None = typer.Option(
        None, "--model", help="default: artifacts/models/segmenter/CATEGORY/model.pt"
    ),
    out: Path | None = typer.Option(None, "--out", help="default: <scan stem>_segmented/"),
    scale: str = _SCALE,
    max_points: int = _MAX_POINTS,
    seed: int = _SEED,
) -> None:
    """Part instances and motion types of every point (section 4.3): parts.ply.

    Example: artic segment scan.ply --category storage_furniture
    """
    from artic.cli.infer_hierarchy import Options, print_summary, run_segment

    print_summary(run_segment(scan, model, out, Options(category, scale, max_points, seed)))


@app.command("build-hierarchy")
@handle_errors
def build_hierarchy_command(
    parts: Path = typer.Argument(..., help="segmented point cloud (.ply with part_id)"),
    category: str | None = _CATEGORY4,
    model: Path | None = typer.Option(
        None, "--model", help="default: artifacts/models/hierarchy/CATEGORY/model.pt"
    ),
    out: Path | None = typer.Option(None, "--out", help="default: <name>_hierarchy/"),
    scale: str = _SCALE,
    max_points: int = _MAX_POINTS,
    seed: int = _SEED,
) -> None:
    """Part graph -> labelled graph -> kinematic tree, URDF (sections 4.4, 4.2.3).

    Example: artic build-hierarchy scan_segmented/parts.ply
    """
    from artic.cli.infer_hierarchy import Options, print_summary, run_build_hierarchy

    opts = Options(category, scale, max_points, seed)
    print_summary(run_build_hierarchy(parts, model, out, opts))


@app.command("infer-hierarchy")
@handle_errors
def infer_hierarchy_command(
    scan: Path = typer.Argument(..., help="point cloud (.ply, metres)"),
    out: Path | None = typer.Option(None, "--out", help="default: <scan stem>_hierarchy/"),
    category: str | None = _CATEGORY4,
    segmenter: Path | None = typer.Option(
        None, "--segmenter", help="default: artifacts/models/segmenter/CATEGORY/model.pt"
    ),
    labeller: Path | None = typer.Option(
        None, "--labeller", help="default: artifacts/models/hierarchy/CATEGORY/model.pt"
    ),
    scale: str = _SCALE,
    max_points: int = _MAX_POINTS,
    seed: int = _SEED,
) -> None:
    """Scan -> kinematic hierarchy (Fig. 4.2): hierarchy.json, object.urdf, parts.ply,
    hierarchy.png.

    Example: artic infer-hierarchy scan.ply --out scan_hierarchy
    """
    from artic.cli.infer_hierarchy import Options, print_summary, run_infer_hierarchy

    opts = Options(category, scale, max_points, seed)
    print_summary(run_infer_hierarchy(scan, segmenter, labeller, out, opts))


@app.command("pipeline")
@handle_errors
def pipeline(
    name: str = typer.Argument(..., help="stages/NAME.yaml, or a path to a pipeline file"),
    variables: list[str] | None = typer.Argument(
        None, help="pipeline variables NAME=VALUE (declared under vars: in the file)"
    ),
    force: bool = typer.Option(False, "--force", help="Recompute every stage."),
    dry_run: bool = typer.Option(False, "--dry-run", help="List the stages and exit."),
) -> None:
    """Run a chain of stages from stages/NAME.yaml, skipping those that are up to date.

    Example: artic pipeline smoke;  artic pipeline bootstrap task=tball
    """
    from artic.cli.pipeline import parse_vars, run_pipeline

    run_pipeline(name, force=force, dry_run=dry_run, values=parse_vars(list(variables or [])))


@app.command("bootstrap")
@handle_errors
def bootstrap(
    task: str = typer.Option("drawer", "--task", help="drawer, microwave or tball"),
    force: bool = typer.Option(False, "--force", help="Recompute every stage."),
    dry_run: bool = typer.Option(False, "--dry-run", help="List the stages and exit."),
) -> None:
    """Algorithm 1 for one task: plan demos, fit the policy, policy search from it and from
    random init, evaluate (the pipeline stages/bootstrap.yaml).

    Example: artic bootstrap --task drawer
    """
    from artic.cli.pipeline import run_pipeline

    run_pipeline("bootstrap", force=force, dry_run=dry_run, values={"task": task})


def _version(value: bool) -> None:
    if value:
        typer.echo(f"artic {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Only warnings and errors."),
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version."
    ),
) -> None:
    logging.basicConfig(
        level=logging.WARNING if quiet else logging.INFO,
        format="%(message)s",
        stream=sys.stderr,
        force=True,
    )
    for handler in logging.getLogger().handlers:
        handler.addFilter(NoTracebacks())


def main() -> None:
    # before any subcommand imports NumPy or PyTorch: the same kernels on every CPU
    from artic.reproducibility import pin_numerics

    pin_numerics()
    app()
