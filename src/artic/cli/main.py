"""`artic`: the command-line entry point.

One command per registered stage is generated from the stage registry
(`cli/registry.py`: every module of `artic.cli` defining `STAGE = Stage(...)`), read
without importing the stage modules; the other commands are written here. Commands
import their heavy dependencies (numpy, open3d, pybullet, hydra) only when they run, so
`artic --help` answers quickly.
"""

from __future__ import annotations

import atexit
import gc
import logging
import os
import sys
from collections.abc import Callable
from enum import StrEnum
from pathlib import Path
from typing import Literal

import typer

from artic import __version__
from artic.cli.failures import NoTracebacks, OneLineErrors, handle_errors
from artic.cli.registry import (
    RegistryError,
    StageEntry,
    load_stage,
    resolve,
    say_alias,
    stage_entries,
)

app = typer.Typer(
    name="artic",
    cls=OneLineErrors,
    help="Structured robotic manipulation: articulated-object datasets, depth rendering, "
    "kinematic models. Each subcommand is a stage: it reads files and writes one output "
    "folder with a manifest.json. Config overrides are Hydra-style KEY=VALUE arguments.",
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
)

_OVERRIDES = typer.Argument(None, help="Hydra overrides, e.g. category=drawer dataset.objects=50")
_CFG = typer.Option(False, "--cfg", help="Print the resolved config and exit.")
_FORCE = typer.Option(False, "--force", help="Recompute even if the output is up to date.")
_EXTRA = {"allow_extra_args": False, "ignore_unknown_options": True}
_TASK = typer.Option(
    None,
    "--task",
    help="the task (= task=NAME): Chapter 5 drawer, microwave, tball; Chapter 6 traj, door, "
    "push; Chapter 7 door, drawer, slide, lever",
)


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


def _with_options(overrides: list[str] | None, options: dict[str, str]) -> list[str]:
    """The stage's `options` (`Stage.options`) among the overrides turned into overrides:
    `--NAME A,B` of a list field into `NAME=[A,B]`, `--NAME` of a flag into `NAME=true`;
    any other `--` word is bad input."""
    from artic.errors import InputError

    tokens, out = list(overrides or []), []
    while tokens:
        token = tokens.pop(0)
        name = token[2:].replace("-", "_")
        if not token.startswith("--"):
            out.append(token)
        elif options.get(name) == "flag":
            out.append(f"{name}=true")
        elif options.get(name) == "list" and tokens and not tokens[0].startswith("--"):
            out.append(f"{name}=[{tokens.pop(0)}]")
        elif options.get(name) == "list":
            raise InputError(f"{token}: expects a value, e.g. {token} a,b")
        else:
            known = ", ".join(f"--{o.replace('_', '-')}" for o in options) or "none"
            raise InputError(f"no such option: {token} (this command's options: {known}; "
                             f"config fields as KEY=VALUE)")  # fmt: skip
    return out


def run_stage_command(command: str, overrides: list[str] | None, cfg: bool, force: bool) -> None:
    """Run the stage behind `artic COMMAND OVERRIDES` (a stage name, or an alias)."""
    from artic.cli.stage_runner import resolved_config, run_stage
    from artic.cli.summary import print_result
    from artic.config.compose import validate

    entry = resolve(command, overrides)
    overrides = _with_options(overrides, entry.options)
    stage = load_stage(entry.name)
    if cfg:
        import yaml

        raw = resolved_config(stage, list(overrides or []))
        validate(stage.schema, raw)  # as the run would: a config it refuses is not printed
        typer.echo(yaml.safe_dump(raw, sort_keys=False))
        say_alias(command, entry)
        return
    result = run_stage(stage, list(overrides or []), force=force)
    say_alias(command, entry)
    print_result(" ".join(entry.command), result)


def _stage_command(entry: StageEntry) -> Callable[..., None]:
    """The Typer callback of a stage: `[OVERRIDES]... [--task NAME] [--cfg] [--force]`."""
    name = entry.name

    def with_task(
        overrides: list[str] | None = _OVERRIDES,
        task: str | None = _TASK,
        cfg: bool = _CFG,
        force: bool = _FORCE,
    ) -> None:
        run_stage_command(name, _with_task(overrides, task), cfg, force)

    def without_task(
        overrides: list[str] | None = _OVERRIDES, cfg: bool = _CFG, force: bool = _FORCE
    ) -> None:
        run_stage_command(name, overrides, cfg, force)

    command: Callable[..., None] = with_task if entry.task_option else without_task
    command.__name__ = command.__qualname__ = name.replace("-", "_")
    return handle_errors(command)


evaluate_app = typer.Typer(
    help="Evaluation reports on withheld objects (tables of the thesis).", no_args_is_help=True
)
#: command groups: a stage declared as `command="evaluate mdn"` is `mdn` under `evaluate`
GROUPS: dict[str, typer.Typer] = {"evaluate": evaluate_app}


def _options_help(options: dict[str, str]) -> str:
    """The help's line on a stage's `options` (read by `_with_options`)."""
    said = [f"--{name.replace('_', '-')} A,B (= {name}=[A,B])" if kind == "list"
            else f"--{name.replace('_', '-')} (= {name}=true)"
            for name, kind in options.items()]  # fmt: skip
    return f"\n\nOptions: {'; '.join(said)}." if said else ""


def _add_stage_commands() -> None:
    for entry in stage_entries().values():
        *group, word = entry.command
        if len(group) > 1 or (group and group[0] not in GROUPS):
            raise RegistryError(f"{entry.module}: no command group {' '.join(group)}")
        target = GROUPS[group[0]] if group else app
        target.command(word, help=entry.help + _options_help(entry.options),
                       context_settings=_EXTRA)(_stage_command(entry))  # fmt: skip


_add_stage_commands()
for _group, _typer in GROUPS.items():
    app.add_typer(_typer, name=_group)


@app.command("predict")
@handle_errors
def predict(
    image: Path = typer.Argument(..., help="depth image: .npy (float metres) or 16-bit .png (mm)"),
    category: str = typer.Option(..., "--category", help="object category (one model each)"),
    camera: str = typer.Option(
        ...,
        "--camera",
        help="camera preset (kinect_v1, kinect_v1_128, thesis_sim) or intrinsics JSON: "
        "fx, fy, cx, cy, width, height, or ROS CameraInfo (K) / Open3D layouts",
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
        None,
        "--model",
        help="model.pt (default: artifacts/models/mdn/CATEGORY/ if trained here, else the "
        "shipped model; see artic models)",
    ),
    seed: int = typer.Option(0, "--seed", help="seed of the samples"),
    refine: bool = typer.Option(True, "--refine/--no-refine", help="geometric refinement"),
) -> None:
    """Kinematic model, configuration and geometry from one depth image, as JSON.

    Example: artic predict depth.png --category microwave --camera kinect_v1 --samples 100
    """
    import json
    import time

    started = time.perf_counter()
    from artic.kinematics.predict import predict_image

    result = predict_image(image, category, camera, model, mask, samples, estimator, seed,
                           started, refine)  # fmt: skip
    typer.echo(json.dumps(result, indent=2))


@app.command("models")
@handle_errors
def models_command(
    as_json: bool = typer.Option(False, "--json", help="one JSON document instead of a table"),
) -> None:
    """The model store: shipped models and those trained here (artifacts/models/), with
    their category, size, preset, config and data hashes, commit and evaluation figures.

    Example: artic models
    """
    from artic.cli.models import show_models

    show_models(as_json)


_SCALE = typer.Option(
    "1", "--scale", help="auto (millimetre clouds are divided by 1000) or a factor to metres"
)
_MAX_POINTS = typer.Option(
    200_000, "--max-points", help="larger clouds: a seeded random subset is segmented"
)
_SEED = typer.Option(0, "--seed", help="seed of the subsampling and graph resampling")
_CATEGORY4 = typer.Option(
    None, "--category", help="model category (default: the given model's, else storage_furniture)"
)


class YawMode(StrEnum):
    """--yaw of segment / infer-hierarchy (`HierarchyConfig.yaw`)."""

    canonical = "canonical"
    none = "none"


_YAW = typer.Option(
    YawMode.canonical,
    "--yaw",
    help="canonical: the scan's front may face any way (its yaw is estimated, results "
    "come back in the scan's frame); none: the scan is in the object frame, front "
    "towards -x",
)


def _yaw_mode(value: YawMode) -> Literal["canonical", "none"]:
    return "none" if value is YawMode.none else "canonical"


@app.command("segment")
@handle_errors
def segment_command(
    scan: Path = typer.Argument(..., help="point cloud (.ply, metres)"),
    category: str | None = _CATEGORY4,
    model: Path | None = typer.Option(
        None, "--model", help="default: the store's segmenter (artic models)"
    ),
    out: Path | None = typer.Option(None, "--out", help="default: <scan stem>_segmented/"),
    scale: str = _SCALE,
    max_points: int = _MAX_POINTS,
    seed: int = _SEED,
    yaw: YawMode = _YAW,
) -> None:
    """Part instances and motion types of every point (section 4.3): parts.ply.

    The scan: metres (or --scale), z up, its front facing any direction
    (--yaw canonical) or -x (--yaw none).

    Example: artic segment scan.ply --category storage_furniture
    """
    from artic.cli.infer_hierarchy import run
    from artic.hierarchy.commands import Options, run_segment

    opts = Options(category, scale, max_points, seed, yaw=_yaw_mode(yaw))
    run(run_segment, scan, model, out, opts)


@app.command("build-hierarchy")
@handle_errors
def build_hierarchy_command(
    parts: Path = typer.Argument(..., help="segmented point cloud (.ply with part_id)"),
    category: str | None = _CATEGORY4,
    model: Path | None = typer.Option(
        None, "--model", help="default: the store's labeller (artic models)"
    ),
    out: Path | None = typer.Option(None, "--out", help="default: <name>_hierarchy/"),
    scale: str = _SCALE,
    max_points: int = _MAX_POINTS,
    seed: int = _SEED,
) -> None:
    """Part graph -> labelled graph -> kinematic tree, URDF (sections 4.4, 4.2.3).

    Example: artic build-hierarchy scan_segmented/parts.ply
    """
    from artic.cli.infer_hierarchy import run
    from artic.hierarchy.commands import Options, run_build_hierarchy

    opts = Options(category, scale, max_points, seed)
    run(run_build_hierarchy, parts, model, out, opts)


@app.command("infer-hierarchy")
@handle_errors
def infer_hierarchy_command(
    scan: Path = typer.Argument(..., help="point cloud (.ply, metres)"),
    out: Path | None = typer.Option(None, "--out", help="default: <scan stem>_hierarchy/"),
    category: str | None = _CATEGORY4,
    segmenter: Path | None = typer.Option(
        None, "--segmenter", help="default: the store's (artic models)"
    ),
    labeller: Path | None = typer.Option(
        None, "--labeller", help="default: the store's (artic models)"
    ),
    scale: str = _SCALE,
    max_points: int = _MAX_POINTS,
    seed: int = _SEED,
    yaw: YawMode = _YAW,
) -> None:
    """Scan -> kinematic hierarchy (Fig. 4.2): hierarchy.json, object.urdf, parts.ply,
    hierarchy.png.

    The scan: metres (or --scale), z up, its front (doors, drawers) facing
    any direction. --yaw canonical (default): its yaw is estimated from
    its vertical planes, the networks work in artic's object frame (front
    towards -x), axes and outputs are in the scan's frame. A swivelling
    office chair's front is taken as the side its scan was taken from.
    --yaw none: the scan is already in the object frame.

    Example: artic infer-hierarchy scan.ply --out scan_hierarchy
    """
    from artic.cli.infer_hierarchy import run
    from artic.hierarchy.commands import Options, run_infer_hierarchy

    opts = Options(category, scale, max_points, seed, yaw=_yaw_mode(yaw))
    run(run_infer_hierarchy, scan, segmenter, labeller, out, opts)


_FORCE_ALL = typer.Option(False, "--force", help="Recompute every stage.")
_DRY_RUN = typer.Option(False, "--dry-run", help="List the stages and exit.")


@app.command("pipeline")
@handle_errors
def pipeline(
    name: str = typer.Argument(..., help="stages/NAME.yaml, or a path to a pipeline file"),
    variables: list[str] | None = typer.Argument(
        None,
        help="pipeline variables NAME=VALUE (declared under vars: in the file); "
        "launcher=inline|local|slurm and launcher.KEY=VALUE (docs/cluster.md)",
    ),
    force: bool = _FORCE_ALL,
    dry_run: bool = _DRY_RUN,
    status: bool = typer.Option(
        False, "--status", help="Per stage: done, running, failed or missing shards."
    ),
) -> None:
    """Run a chain of stages from stages/NAME.yaml, skipping those that are up to date.

    Example: artic pipeline smoke;  artic pipeline bootstrap task=tball;
    artic pipeline ch3_paper launcher=slurm
    """
    from artic.cli.pipeline import parse_vars, run_pipeline
    from artic.config.launcher import load_launcher, split_launcher_args

    launcher_name, launcher_overrides, rest = split_launcher_args(list(variables or []))
    run_pipeline(
        name,
        force=force,
        dry_run=dry_run,
        values=parse_vars(rest),
        launcher=load_launcher(launcher_name, launcher_overrides),
        status=status,
    )


@app.command("bootstrap")
@handle_errors
def bootstrap(
    task: str = typer.Option("drawer", "--task", help="drawer, microwave or tball"),
    overrides: list[str] | None = typer.Argument(
        None,
        help="KEY=VALUE given to every stage that takes it (seeds=2 updates=10); "
        "launcher=... as for artic pipeline",
    ),
    force: bool = _FORCE_ALL,
    dry_run: bool = _DRY_RUN,
) -> None:
    """Algorithm 1 for one task: plan demos, fit the policy, policy search from it and from
    random init, evaluate (the pipeline stages/bootstrap.yaml).

    Example: artic bootstrap --task drawer;  artic bootstrap --task drawer seeds=2 updates=10
    """
    from artic.cli.pipeline import run_pipeline
    from artic.config.launcher import load_launcher, split_launcher_args

    launcher_name, launcher_overrides, rest = split_launcher_args(list(overrides or []))
    run_pipeline(
        "bootstrap",
        force=force,
        dry_run=dry_run,
        values={"task": task},
        launcher=load_launcher(launcher_name, launcher_overrides),
        extra=rest,
    )


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


#: one scan in seconds: one OpenMP thread for its small tensors, no passes of the cyclic
#: collector over what torch & co. import, nor at shutdown (docs/hierarchy.md, "Speed")
ONE_SCAN_COMMANDS = frozenset({"segment", "build-hierarchy", "infer-hierarchy"})


def main() -> None:
    # before any subcommand imports NumPy or PyTorch: the same kernels on every CPU
    from artic.reproducibility import pin_numerics

    pin_numerics()
    if next((w for w in sys.argv[1:] if not w.startswith("-")), None) in ONE_SCAN_COMMANDS:
        os.environ.setdefault("OMP_NUM_THREADS", "1")  # a value the user set is kept
        gc.disable()
        atexit.register(gc.freeze)  # registered first, run last of the exit handlers
    app()
