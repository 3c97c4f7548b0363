from pathlib import Path

import pytest

from artic.artifacts.formats import write_json
from artic.artifacts.manifest import (
    InputRecord,
    Manifest,
    input_folder,
    list_outputs,
    outputs_hash,
    read_manifest,
    verify_file,
    verify_outputs,
)
from artic.errors import InputError


def _manifest(folder, stage="generate-dataset"):
    outputs = list_outputs(folder)
    m = Manifest(
        stage=stage,
        config={"a": 1},
        config_hash="x",
        seed=0,
        inputs={},
        outputs=outputs,
        content_hash=outputs_hash(outputs),
        versions={},
        started_at="",
        finished_at="",
        wall_time_s=0.0,
        stats={},
    )
    write_json(folder / "manifest.json", m.model_dump(mode="json"))
    return m


def test_manifest_lists_files_and_detects_corruption(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "x.txt").write_text("hello")
    (tmp_path / "y.bin").write_bytes(b"\x00\x01")
    m = _manifest(tmp_path)
    assert set(m.outputs) == {"a/x.txt", "y.bin"}
    back = read_manifest(tmp_path, expected_stage="generate-dataset")
    assert back == m
    verify_outputs(tmp_path, back)
    (tmp_path / "a" / "x.txt").write_text("hellO")
    with pytest.raises(InputError, match=r"x.txt: corrupted"):
        verify_outputs(tmp_path, back)
    (tmp_path / "y.bin").unlink()
    with pytest.raises(InputError, match=r"y.bin: missing"):
        verify_file(tmp_path, back, "y.bin")


def test_content_hash_ignores_manifest_timing(tmp_path):
    (tmp_path / "x").write_text("1")
    a = _manifest(tmp_path)
    b = _manifest(tmp_path)
    assert a.content_hash == b.content_hash


@pytest.mark.parametrize(
    ("setup", "message"),
    [
        (lambda p: None, "no such folder"),
        (lambda p: p.mkdir(), "not a stage output"),
        (lambda p: (p.mkdir(), (p / "manifest.json").write_text("{")), "malformed manifest"),
    ],
)
def test_not_a_stage_output(tmp_path, setup, message):
    folder = tmp_path / "d"
    setup(folder)
    with pytest.raises(InputError, match=message):
        read_manifest(folder)


def test_wrong_stage_is_refused(tmp_path):
    (tmp_path / "x").write_text("1")
    _manifest(tmp_path, stage="render-depth")
    with pytest.raises(InputError, match="expected a 'generate-dataset' output"):
        read_manifest(tmp_path, expected_stage="generate-dataset")


def _with_input(out: str, path: str) -> Manifest:
    return Manifest(
        stage="policy-search", config={"out": out}, config_hash="0", seed=0,
        inputs={"dmp": InputRecord(path=path, stage="fit-dmp", content_hash="0")},
        outputs={}, content_hash="0", versions={}, started_at="", finished_at="",
        wall_time_s=0.0, stats={},
    )  # fmt: skip


def test_a_relative_input_is_found_from_the_folder_the_run_started_in(tmp_path):
    """A run started in /x with out=artifacts/policy/a and dmp=artifacts/dmp/a is read back
    from anywhere: its dmp is /x/artifacts/dmp/a."""
    folder = tmp_path / "artifacts" / "policy" / "a"
    manifest = _with_input("artifacts/policy/a", "artifacts/dmp/a")
    assert input_folder(folder, manifest, "dmp") == tmp_path / "artifacts" / "dmp" / "a"
    # absolute paths stay; a folder moved away from its out takes the path as given
    absolute = _with_input("artifacts/policy/a", str(tmp_path / "d"))
    assert input_folder(folder, absolute, "dmp") == tmp_path / "d"
    assert input_folder(tmp_path / "moved", manifest, "dmp") == Path("artifacts/dmp/a")
    with pytest.raises(InputError, match="no input 'demos'"):
        input_folder(folder, manifest, "demos")
