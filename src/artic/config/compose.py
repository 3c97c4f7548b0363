"""Compose a stage's config with Hydra's Compose API and validate it with pydantic.

Each stage has its own config root `conf/<stage>/` (primary `config.yaml` plus groups
only that stage has, such as `debug/` and `experiment/`); groups shared by stages
X
search path. Separate roots let one stage take `dataset=PATH` as a value while another
has a `dataset` config group.
"""

from __future__ import annotations

import difflib
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from artic.errors import InputError

M = TypeVar("M", bound=BaseModel)

_RESOLVERS_REGISTERED = False


def _data_root() -> Path:
    """Where the shipped `conf/`, `stages/` and `models/` are: inside the installed package
    (a wheel copies them to `artic/conf/`, ... at build time), else the top level of the
    repository (an editable install or a checkout)."""
    from importlib import resources

    package = resources.files("artic")
    if isinstance(package, Path) and (package / "conf" / "common").is_dir():
        return package
    return Path(__file__).resolve().parents[3]


def conf_dir() -> Path:
    """The `conf/` folder: `$ARTIC_CONF` if set, else the shipped `conf/`."""
    env = os.environ.get("ARTIC_CONF")
    path = Path(env) if env else _data_root() / "conf"
    if not (path / "common").is_dir():
        raise InputError(f"{path}: not an artic conf/ folder (set ARTIC_CONF)")
    return path


def stages_dir() -> Path:
    """The `stages/` folder of pipeline files: the one beside `$ARTIC_CONF` if that
    folder has one, else the shipped `stages/`."""
    env = os.environ.get("ARTIC_CONF")
    if env and (Path(env).parent / "stages").is_dir():
        return Path(env).parent / "stages"
    return _data_root() / "stages"


def models_dir() -> Path:
    """The shipped model store (`models/`, packaged like `conf/`), or `$ARTIC_MODELS`."""
    env = os.environ.get("ARTIC_MODELS")
    return Path(env) if env else _data_root() / "models"


def _register_resolvers() -> None:
    global _RESOLVERS_REGISTERED
    if _RESOLVERS_REGISTERED:
        return
    from omegaconf import OmegaConf

    # ${basename:artifacts/objects/microwave} -> microwave
    OmegaConf.register_new_resolver(
        "basename", lambda p: Path(str(p).rstrip("/")).name, replace=True
    )
    _RESOLVERS_REGISTERED = True


@dataclass(frozen=True)
class Composed:
    """A resolved config and the config-group options it was composed from
    (`{"category": "microwave", "debug": "tiny"}`: Hydra's `runtime.choices`, groups left
    unset and Hydra's own groups left out)."""

    config: dict[str, Any]
    choices: dict[str, str]


def compose(stage: str, overrides: list[str]) -> dict[str, Any]:
    """The resolved config of `stage` (a folder name under conf/) with Hydra overrides."""
    return compose_with_choices(stage, overrides).config


def compose_with_choices(stage: str, overrides: list[str]) -> Composed:
    """`compose`, and which option of each config group it used."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.errors import HydraException
    from omegaconf import OmegaConf, open_dict
    from omegaconf.errors import OmegaConfBaseException

    _register_resolvers()
    root = conf_dir()
    search = f"hydra.searchpath=[file://{root / 'common'}]"
    try:
        with initialize_config_dir(config_dir=str(root / stage), version_base=None):
            cfg = hydra_compose("config", overrides=[*overrides, search], return_hydra_config=True)
        runtime = OmegaConf.to_container(cfg.hydra.runtime.choices)
        with open_dict(cfg):
            del cfg["hydra"]
        container = OmegaConf.to_container(cfg, resolve=True)
    except (HydraException, OmegaConfBaseException, ValueError) as err:
        unknown = _UNKNOWN_KEY.search(str(err))
        if unknown:
            raise InputError(_unknown_key(stage, unknown.group(1))) from None
        raise InputError(f"config: {_one_line(err)}") from None
    assert isinstance(container, dict) and isinstance(runtime, dict)
    choices = {
        str(k): str(v)
        for k, v in runtime.items()
        if v is not None and not str(k).startswith("hydra/")
    }
    return Composed({str(k): v for k, v in container.items()}, choices)


#: Hydra's "Could not override 'train.epoch'. To append to your config use +train.epoch=3"
_UNKNOWN_KEY = re.compile(r"Could not override '([^']+)'")


def config_keys(tree: Any, prefix: str = "") -> list[str]:
    """Every dotted key of a config tree (`train`, `train.epochs`, ...)."""
    if not isinstance(tree, dict):
        return []
    keys: list[str] = []
    for k, v in tree.items():
        key = f"{prefix}{k}"
        keys += [key, *config_keys(v, key + ".")]
    return keys


def _unknown_key(stage: str, key: str) -> str:
    """One line for an override of a key the stage's config does not have, with the
    closest existing keys (instead of Hydra's hint to add it with `+`, which the stage's
    schema would refuse anyway)."""
    try:
        keys = config_keys(compose(stage, []))
    except InputError:
        keys = []
    close = difflib.get_close_matches(key, keys, n=3, cutoff=0.6)
    hint = f"; did you mean {' or '.join(close)}?" if close else ""
    return f"config: no key '{key}' in the {stage.replace('_', '-')} config{hint}"


def validate(schema: type[M], config: dict[str, Any]) -> M:
    """`schema.model_validate(config)`, or InputError naming the first bad field."""
    try:
        return schema.model_validate(config)
    except ValidationError as err:
        first = err.errors()[0]
        field = ".".join(str(p) for p in first["loc"]) or "config"
        got = first.get("input")
        shown = "" if isinstance(got, dict | list) else f" (got {got!r})"
        raise InputError(f"config field {field}: {first['msg']}{shown}") from None


def _one_line(err: Exception) -> str:
    """Hydra's multi-line messages as one line: the problem, then the options, if listed
    ("Could not find 'category/sofa'; available: cabinet, drawer, ...")."""
    lines = [ln.strip() for ln in str(err).strip().splitlines() if ln.strip()]
    if "Config search path:" in lines:
        lines = lines[: lines.index("Config search path:")]
    if not lines:
        return type(err).__name__
    head = lines[0].removeprefix("In 'config': ")
    listed = [i for i, ln in enumerate(lines) if ln.startswith("Available options")]
    if listed:
        return f"{head}; available: {', '.join(lines[listed[0] + 1 :])}"
    return " ".join([head, *lines[1:]])
