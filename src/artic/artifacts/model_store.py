"""The model store: trained networks by kind and category, shipped or trained here.

Two places hold models of a kind (`mdn`, `segmenter`, `hierarchy`) and a category:
- **local**: `artifacts/models/<kind>/<category>/`, a training stage's output folder
  (`model.pt`, `model_card.md`, `manifest.json`), where `artic pipeline ch3` / `ch4` put
  them;
- **shipped**: `models/<kind>/<category>/` of the package (`artic.config.compose.models_dir`,
  `$ARTIC_MODELS` overrides), written by `ship_model` from such a folder: `model.pt`,
  `model_card.md` (with the evaluation figures appended) and `card.json` (`ModelCard`),
  and an MDN's `refined_intervals.csv` when its evaluation wrote one.

`choose_model` is the one rule every command follows: the file the user gave; else the
local model, unless it was trained with a debug preset (a smoke model, never used by
default); else the shipped one; else an error naming the pipeline that makes one. The
choice says where the model came from, so commands can print it. `list_models` is what
`artic models` shows.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, ValidationError

from artic.artifacts.formats import read_json, write_json
from artic.artifacts.hashing import sha256_file
from artic.artifacts.manifest import MANIFEST, InputRecord, Manifest, read_manifest
from artic.config.compose import models_dir
from artic.errors import InputError

MODEL_FILE = "model.pt"
CARD_JSON = "card.json"
CARD_MD = "model_card.md"
#: an `evaluate mdn` output's scales of the refined estimate's intervals
#: (kinematics/intervals.py), shipped beside the model it evaluated
REFINED_INTERVALS = "refined_intervals.csv"
#: where training stages put a category's model by default, and evaluations their reports
LOCAL_ROOT = Path("artifacts/models")
REPORTS_ROOT = Path("artifacts/reports")
CARD_FORMAT = 1

Source = Literal["given", "local", "shipped"]


@dataclass(frozen=True)
class ModelKind:
    """A kind of trained network: the stage that trains it, what uses it, and the
    pipeline (with its cost on this project's 2-core reference machine) that makes one."""

    name: str
    stage: str
    chapter: int
    used_by: str
    make: str
    headline: str  # the evaluation figures to show first: those whose name has this

    def headline_figures(
        self, figures: dict[str, float | int | str]
    ) -> dict[str, float | int | str]:
        """`figures` with the headline ones first (for a table of models)."""
        first = {k: v for k, v in figures.items() if self.headline in k}
        return {**first, **{k: v for k, v in figures.items() if k not in first}}


KINDS: dict[str, ModelKind] = {
    k.name: k
    for k in (
        ModelKind(
            "mdn",
            "train-mdn",
            3,
            "artic predict",
            "`artic pipeline ch3` (generate, render, train, evaluate; about 26 minutes per "
            "category on 2 CPU cores, all six categories)",
            "Ours pos/rot/config",
        ),
        ModelKind(
            "segmenter",
            "train-segmenter",
            4,
            "artic segment, artic infer-hierarchy",
            "`artic pipeline ch4` (generate, scan, train segmenter and graph network, "
            "evaluate; about 1.5 hours per category on 2 CPU cores, three categories)",
            "mAP",
        ),
        ModelKind(
            "hierarchy",
            "train-hierarchy",
            4,
            "artic build-hierarchy, artic infer-hierarchy",
            "`artic pipeline ch4` (generate, scan, train segmenter and graph network, "
            "evaluate; about 1.5 hours per category on 2 CPU cores, three categories)",
            "Tree F1",
        ),
    )
}


class ModelCard(BaseModel):
    """`card.json` of a shipped model: where it came from and how well it does."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    format: int = CARD_FORMAT
    kind: str
    category: str
    stage: str
    preset: str  # the config-group options it was trained with, "experiment=ch3_cpu"
    config_hash: str
    data_path: str
    data_hash: str
    commit: str
    trained_at: str
    training_wall_time_s: float
    model_sha256: str
    size: int
    #: how the weights are stored: float32 (as trained) or float16 (`halve_shipped`)
    weights: str = "float32"
    #: a segmenter's inference settings changed after training (`set_inference_shipped`)
    inference: dict[str, Any] = {}
    #: what else was done to the weights after training, in order (`transform_shipped`)
    changes: tuple[str, ...] = ()
    evaluation_stage: str | None
    evaluation_hash: str | None
    figures: dict[str, float | int | str]
    config: dict[str, Any]


@dataclass(frozen=True)
class StoredModel:
    """One model of the store, as `artic models` lists it."""

    kind: str
    category: str
    source: Source
    path: Path  # the model.pt
    size: int
    preset: str
    config_hash: str
    data_hash: str
    commit: str
    figures: dict[str, float | int | str]

    @property
    def debug(self) -> bool:
        """Trained with a debug preset (`debug=tiny`): a smoke model, meaningless."""
        return any(p.startswith("debug=") for p in self.preset.split())


@dataclass(frozen=True)
class ModelChoice:
    """The model a command uses and why: `source` given / local / shipped; `warning`: one
    line to show the user (a debug model given explicitly, a local debug model skipped)."""

    kind: str
    path: Path
    source: Source
    model: StoredModel | None
    warning: str = ""

    def describe(self) -> str:
        """`shipped model models/mdn/microwave/model.pt`, as the commands print it."""
        return f"{self.source} model {self.path}"


def _kind(kind: str) -> ModelKind:
    if kind not in KINDS:
        raise InputError(f"model kind '{kind}' (available: {', '.join(KINDS)})")
    return KINDS[kind]


def preset_of(choices: dict[str, str]) -> str:
    """`experiment=ch3_cpu debug=tiny`: the options of the groups that change a run's
    scale (category and task are columns of their own)."""
    groups = ("experiment", "debug", "dataset", "render")
    return " ".join(f"{g}={choices[g]}" for g in groups if g in choices) or "defaults"


def _figures(stats: dict[str, float | int | str]) -> dict[str, float | int | str]:
    return {k: v for k, v in stats.items() if k not in ("category", "scans")}


def evaluation_of(content_hash: str, reports: Path = REPORTS_ROOT) -> Manifest | None:
    """The newest evaluation manifest under `reports` with an input of `content_hash`."""
    found: list[Manifest] = []
    for path in sorted(reports.rglob(MANIFEST)) if reports.is_dir() else []:
        try:
            manifest = read_manifest(path.parent)
        except InputError:
            continue
        if manifest.stage.startswith("evaluate") and any(
            r.content_hash == content_hash for r in manifest.inputs.values()
        ):
            found.append(manifest)
    return max(found, key=lambda m: m.finished_at) if found else None


def _local(folder: Path, kind: ModelKind, category: str, reports: Path | None) -> StoredModel:
    manifest = read_manifest(folder, expected_stage=kind.stage)
    model = folder / MODEL_FILE
    if not model.is_file():
        raise InputError(f"{folder}: no {MODEL_FILE}")
    data = next(iter(manifest.inputs.values()), None)
    # the figures: only for a listing (a command choosing its model need not search reports)
    evaluation = None if reports is None else evaluation_of(manifest.content_hash, reports)
    return StoredModel(
        kind=kind.name,
        category=category,
        source="local",
        path=model,
        size=model.stat().st_size,
        preset=preset_of(manifest.choices),
        config_hash=manifest.config_hash,
        data_hash="" if data is None else data.content_hash,
        commit=manifest.versions.get("artic_commit", ""),
        figures={} if evaluation is None else _figures(evaluation.stats),
    )


def read_card(folder: Path) -> ModelCard:
    """`card.json` of a shipped model folder; InputError naming it when malformed."""
    path = folder / CARD_JSON
    try:
        return ModelCard.model_validate(read_json(path))
    except ValidationError as err:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"])
        raise InputError(f"{path}: field {field}: {first['msg']}") from None


def _check_bytes(model: Path, card: ModelCard) -> None:
    """InputError unless the shipped `model` file is the one its card describes."""
    if not model.is_file() or sha256_file(model) != card.model_sha256:
        raise InputError(f"{model}: does not match its {CARD_JSON} (edited or broken)")


def shipped_input(folder: Path, stage: str) -> InputRecord | None:
    """A shipped model's folder given where a stage reads the output of `stage` (a
    training stage: `evaluate mdn model=models/mdn/drawer`): its input record, with the
    model file's sha256 (checked against its card; the first 16 hex digits) as its content
    hash; None when `folder` is not a shipped model's (no card.json, or a manifest)."""
    if not (folder / CARD_JSON).is_file() or (folder / MANIFEST).is_file():
        return None
    card = read_card(folder)
    if card.stage != stage:
        raise InputError(f"{folder}: a shipped {card.stage} model, not a {stage} one")
    _check_bytes(folder / MODEL_FILE, card)
    return InputRecord(path=str(folder), stage=card.stage, content_hash=card.model_sha256[:16])


def _shipped(folder: Path, card: ModelCard) -> StoredModel:
    return StoredModel(
        kind=card.kind,
        category=card.category,
        source="shipped",
        path=folder / MODEL_FILE,
        size=card.size,
        preset=card.preset,
        config_hash=card.config_hash,
        data_hash=card.data_hash,
        commit=card.commit,
        figures=dict(card.figures),
    )


def local_model(
    kind: str, category: str, root: Path = LOCAL_ROOT, reports: Path | None = REPORTS_ROOT
) -> StoredModel | None:
    """The model trained here for `category` (None when there is none); its figures from
    the evaluations under `reports` (None: no figures, no search)."""
    folder = root / kind / category
    if not (folder / MODEL_FILE).is_file():
        return None
    return _local(folder, _kind(kind), category, reports)


def _shipped_card(kind: str, category: str, store: Path | None) -> tuple[Path, ModelCard] | None:
    """The folder and card of the shipped model of `kind` for `category`, if one ships."""
    folder = (store or models_dir()) / _kind(kind).name / category
    return (folder, read_card(folder)) if (folder / CARD_JSON).is_file() else None


def shipped_model(kind: str, category: str, store: Path | None = None) -> StoredModel | None:
    """The shipped model of `kind` for `category` (None when none ships)."""
    found = _shipped_card(kind, category, store)
    return None if found is None else _shipped(*found)


def list_models(
    root: Path = LOCAL_ROOT, reports: Path = REPORTS_ROOT, store: Path | None = None
) -> list[StoredModel]:
    """Every shipped and local model, by kind and category (the local one first)."""
    out: list[StoredModel] = []
    shipped_root = store or models_dir()
    for kind in KINDS:
        categories = {p.name for base in (root, shipped_root) for p in _folders(base / kind)}
        for category in sorted(categories):
            local = local_model(kind, category, root, reports)
            shipped = shipped_model(kind, category, shipped_root)
            out += [m for m in (local, shipped) if m is not None]
    return out


def _folders(path: Path) -> list[Path]:
    return sorted(p for p in path.iterdir() if p.is_dir()) if path.is_dir() else []


def debug_preset_of(model: Path) -> str:
    """The debug preset (`debug=tiny`) a model file beside its training manifest was
    trained with, or "" (none, or no manifest to tell)."""
    try:
        manifest = Manifest.model_validate_json((model.parent / MANIFEST).read_text())
    except (OSError, ValueError):
        return ""
    debug = manifest.choices.get("debug")
    return f"debug={debug}" if debug else ""


def choose_model(
    kind: str,
    category: str,
    given: Path | None,
    option: str,
    root: Path = LOCAL_ROOT,
    store: Path | None = None,
) -> ModelChoice:
    """The model file a command uses: `given`; else the local model unless it is a debug
    model; else the shipped one (its bytes checked against its card); else InputError
    naming the pipeline that makes one, or `option` to give one."""
    spec = _kind(kind)
    if given is not None:
        if not given.is_file():
            raise InputError(f"{option} {given}: no such file")
        debug = debug_preset_of(given)
        warning = f"{given} was trained with {debug}: a smoke model, its answers mean nothing"
        return ModelChoice(kind, given, "given", None, warning if debug else "")
    skipped = ""
    local = local_model(kind, category, root, reports=None)
    if local is not None and not local.debug:
        return ModelChoice(kind, local.path, "local", local)
    if local is not None:
        skipped = f"{local.path} was trained with {local.preset} and is not used by default"
    found = _shipped_card(kind, category, store)
    if found is not None:
        shipped, card = _shipped(*found), found[1]
        _check_bytes(shipped.path, card)
        return ModelChoice(kind, shipped.path, "shipped", shipped, skipped)
    have = sorted(p.name for p in _folders((store or models_dir()) / kind))
    ships = f"shipped: {', '.join(have)}" if have else "none shipped"
    raise InputError(
        f"{root / kind / category / MODEL_FILE}: no {kind} model for {category} ({ships}); "
        f"make one with {spec.make}, or give one with {option} PATH"
    )


def ship_model(
    folder: Path, evaluation: Path | None, store: Path, commit: str, preset: str = ""
) -> Path:
    """Copy the training output `folder` into the store as `<kind>/<category>/` with its
    `card.json` (figures from the evaluation output `evaluation`, which must have
    evaluated this very model) and its model card with those figures appended, and the
    evaluation's `refined_intervals.csv` when it has one. `commit`:
    the commit the model was trained at; `preset`: the config-group options, when the
    manifest predates recording them. Replaces an earlier shipped model of the same kind
    and category. Returns the new folder."""
    manifest = read_manifest(folder)
    kinds = {k.stage: k for k in KINDS.values()}
    if manifest.stage not in kinds:
        raise InputError(f"{folder}: a '{manifest.stage}' output, not a trained model")
    kind = kinds[manifest.stage]
    preset = preset or preset_of(manifest.choices)
    if "debug=" in preset:
        raise InputError(f"{folder}: trained with {preset}; a debug model is never shipped")
    category = str(manifest.stats.get("category") or manifest.config["category"]["name"])
    model = folder / MODEL_FILE
    figures: dict[str, float | int | str] = {}
    evaluated: Manifest | None = None
    if evaluation is not None:
        evaluated = read_manifest(evaluation)
        if not any(r.content_hash == manifest.content_hash for r in evaluated.inputs.values()):
            raise InputError(f"{evaluation}: did not evaluate the model of {folder}")
        figures = _figures(evaluated.stats)
    data_key, data = next(iter(manifest.inputs.items()))
    card = ModelCard(
        kind=kind.name,
        category=category,
        stage=manifest.stage,
        preset=preset,
        config_hash=manifest.config_hash,
        data_path=f"{data_key}: {data.path}",
        data_hash=data.content_hash,
        commit=commit,
        trained_at=manifest.finished_at,
        training_wall_time_s=manifest.wall_time_s,
        model_sha256=sha256_file(model),
        size=model.stat().st_size,
        evaluation_stage=None if evaluated is None else evaluated.stage,
        evaluation_hash=None if evaluated is None else evaluated.content_hash,
        figures=figures,
        config=manifest.config,
    )
    target = store / kind.name / category
    tmp = target.with_name(target.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    shutil.copyfile(model, tmp / MODEL_FILE)
    if evaluation is not None and (evaluation / REFINED_INTERVALS).is_file():
        # the refined estimate's interval scales, which `artic predict` reads beside the model
        shutil.copyfile(evaluation / REFINED_INTERVALS, tmp / REFINED_INTERVALS)
    card_md = (folder / CARD_MD).read_text() if (folder / CARD_MD).is_file() else ""
    (tmp / CARD_MD).write_text(card_md.rstrip("\n") + "\n\n" + _shipped_section(card))
    write_json(tmp / CARD_JSON, card.model_dump(mode="json"))
    shutil.rmtree(target, ignore_errors=True)
    tmp.rename(target)
    return target


def recard_shipped(folder: Path, evaluation: Path) -> Path:
    """A shipped model's `card.json` and model card with the figures of a new evaluation
    of it (`artic evaluate mdn model=models/mdn/<category>`, whose input record is the
    model file's sha256), and that evaluation's `refined_intervals.csv` beside the model
    (or none, when it wrote none); the model file and the training facts stay. Written
    beside and renamed over, file by file. Returns `folder`."""
    card = read_card(folder)
    _check_bytes(folder / MODEL_FILE, card)
    evaluated = read_manifest(evaluation)
    if not any(r.content_hash == card.model_sha256[:16] for r in evaluated.inputs.values()):
        raise InputError(f"{evaluation}: did not evaluate the model of {folder}")
    new = card.model_copy(update={
        "evaluation_stage": evaluated.stage,
        "evaluation_hash": evaluated.content_hash,
        "figures": _figures(evaluated.stats),
    })  # fmt: skip
    intervals = evaluation / REFINED_INTERVALS
    _replace_card(folder, new, intervals if intervals.is_file() else None)
    return folder


def _replace_card(folder: Path, new: ModelCard, intervals: Path | None) -> None:
    """A shipped folder's `card.json` and model card (its training part kept) written for
    `new`, and its `refined_intervals.csv` a copy of `intervals` (None: removed); a
    `.model.pt.partial` beside them replaces the model file first. Each file is written
    beside and renamed over."""
    training = (folder / CARD_MD).read_text().split("## Shipped with artic")[0]
    partial = {
        name: folder / f".{name}.partial"
        for name in (MODEL_FILE, CARD_MD, CARD_JSON, REFINED_INTERVALS)
    }
    partial[CARD_MD].write_text(training.rstrip("\n") + "\n\n" + _shipped_section(new))
    write_json(partial[CARD_JSON], new.model_dump(mode="json"))
    if intervals is not None:
        shutil.copyfile(intervals, partial[REFINED_INTERVALS])
    else:
        (folder / REFINED_INTERVALS).unlink(missing_ok=True)
    for name, path in partial.items():
        if path.is_file():
            path.replace(folder / name)


def halve_shipped(folder: Path) -> Path:
    """A shipped model's weights stored in half precision (`model_file.half_precision`:
    half the bytes; loading computes in float32 on the rounded weights). Its card gets
    the new file's sha256 and size, and loses the figures and `refined_intervals.csv`
    measured on the old bytes: evaluate the halved model and re-card it
    (`recard_shipped`) before shipping it. Returns `folder`."""
    from artic.artifacts.model_file import half_precision, load_torch_file

    card = read_card(folder)
    model = folder / MODEL_FILE
    _check_bytes(model, card)
    if card.weights == "float16":
        return folder
    payload = load_torch_file(model)
    try:
        payload["state_dict"] = half_precision(payload["state_dict"])
    except ValueError as err:
        raise InputError(f"{model}: cannot be stored in half precision: {err}") from None
    return _rewrite_shipped(folder, card, payload, {"weights": "float16"})


def set_inference_shipped(
    folder: Path,
    updates: dict[str, Any],
    validate: Callable[[dict[str, Any]], dict[str, Any]],
) -> Path:
    """A shipped segmenter's saved inference settings changed by `updates` (e.g. `passes`;
    `validate` checks the merged settings and returns them as saved: the segmenter's
    `InferenceConfig`, which this floor does not import); the weights stay. Its card
    records the change and gets the new file's sha256 and size, and loses the figures
    measured with the old settings: evaluate it and re-card it (`recard_shipped`).
    InputError for another kind of model or settings `validate` refuses. Returns `folder`."""
    from artic.artifacts.model_file import load_torch_file

    card = read_card(folder)
    model = folder / MODEL_FILE
    _check_bytes(model, card)
    payload = load_torch_file(model)
    if card.kind != "segmenter" or "inference" not in payload.get("hparams", {}):
        raise InputError(f"{model}: a {card.kind} model has no inference settings to change")
    try:
        settings = validate({**payload["hparams"]["inference"], **updates})
    except ValidationError as err:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"])
        raise InputError(f"{model}: inference.{field}: {first['msg']}") from None
    payload["hparams"]["inference"] = settings
    return _rewrite_shipped(folder, card, payload, {"inference": {**card.inference, **updates}})


def transform_shipped(
    folder: Path, transform: Callable[[dict[str, Any]], dict[str, Any]], change: str
) -> Path:
    """A shipped model's file replaced by `transform` of its saved dict (e.g. a head
    fitted onto its weights: `scripts/ship_model.py --axis-head`); its card records
    `change` after the changes before, gets the new file's sha256 and size, and loses the
    figures measured on the old file: evaluate it and re-card it (`recard_shipped`).
    `transform` raises InputError for a model it does not take. Returns `folder`."""
    from artic.artifacts.model_file import load_torch_file

    card = read_card(folder)
    model = folder / MODEL_FILE
    _check_bytes(model, card)
    payload = transform(load_torch_file(model))
    return _rewrite_shipped(folder, card, payload, {"changes": (*card.changes, change)})


def _rewrite_shipped(
    folder: Path, card: ModelCard, payload: dict[str, Any], update: dict[str, Any]
) -> Path:
    """`payload` written as the shipped `folder`'s model file, its `card` changed by
    `update`, given the new file's sha256 and size, and cleared of the figures measured on
    the old file (`_replace_card`; `halve_shipped`, `set_inference_shipped`,
    `transform_shipped`). Returns `folder`."""
    from artic.artifacts.model_file import save_torch_file

    partial = folder / f".{MODEL_FILE}.partial"
    save_torch_file(partial, payload)
    new = card.model_copy(update={
        "model_sha256": sha256_file(partial), "size": partial.stat().st_size, **update,
        "evaluation_stage": None, "evaluation_hash": None, "figures": {},
    })  # fmt: skip
    _replace_card(folder, new, None)
    return folder


def _shipped_section(card: ModelCard) -> str:
    lines = [
        "## Shipped with artic",
        "",
        f"- trained with `{card.preset}` at commit `{card.commit}` ({card.trained_at}, "
        f"{card.training_wall_time_s / 60:.1f} min)",
        f"- data: `{card.data_path}` (content hash `{card.data_hash[:16]}`)",
        f"- config hash `{card.config_hash[:16]}`; model.pt sha256 `{card.model_sha256[:16]}`",
    ]
    if card.weights != "float32":
        lines.append(f"- weights stored as {card.weights} (computed in float32 when loaded)")
    if card.inference:
        settings = ", ".join(f"{k}={v}" for k, v in card.inference.items())
        lines.append(f"- inference settings changed after training: {settings}")
    lines += [f"- after training: {change}" for change in card.changes]
    if card.evaluation_stage:
        lines += [
            "",
            f"### Evaluation (`artic {card.evaluation_stage.replace('-', ' ', 1)}`, "
            "withheld objects)",
            "",
            "| figure | value |",
            "|---|---|",
            *(f"| {k} | {v} |" for k, v in card.figures.items()),
        ]
    return "\n".join(lines) + "\n"
