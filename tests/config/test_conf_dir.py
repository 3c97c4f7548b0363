"""Where conf/ and stages/ come from: the repository in a checkout, `$ARTIC_CONF` when set
(an installed wheel's copy inside the package is checked by `make wheel-check`)."""

import shutil
from pathlib import Path

import pytest

from artic.config.compose import conf_dir, stages_dir
from artic.config.pipeline_file import pipeline_path
from artic.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


def test_checkout_reads_the_top_level_folders(monkeypatch):
    monkeypatch.delenv("ARTIC_CONF", raising=False)
    assert conf_dir() == ROOT / "conf"
    assert stages_dir() == ROOT / "stages"
    assert pipeline_path("smoke") == ROOT / "stages" / "smoke.yaml"


def test_artic_conf_overrides_and_stages_fall_back_to_the_shipped(tmp_path, monkeypatch):
    own = tmp_path / "mine" / "conf"
    shutil.copytree(ROOT / "conf" / "common", own / "common")
    monkeypatch.setenv("ARTIC_CONF", str(own))
    assert conf_dir() == own
    assert stages_dir() == ROOT / "stages"  # no stages/ beside it
    (tmp_path / "mine" / "stages").mkdir()
    (tmp_path / "mine" / "stages" / "x.yaml").write_text("steps: []\n")
    assert stages_dir() == tmp_path / "mine" / "stages"
    assert pipeline_path("x") == tmp_path / "mine" / "stages" / "x.yaml"


def test_a_folder_without_common_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("ARTIC_CONF", str(tmp_path))
    with pytest.raises(InputError, match="not an artic conf/ folder"):
        conf_dir()
