import pytest

from artic.artifacts.formats import write_json
from artic.artifacts.manifest import (
    Manifest,
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
