"""PLY point clouds (parsed and written by plyfile): exact binary round trip, the bytes
artic has always written, foreign files, and every bad-input path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import trimesh
from plyfile import PlyData

from artic.artifacts.ply import encode_ply, read_ply, read_ply_header, write_ply
from artic.errors import InputError


def cloud(n: int = 50, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.5, 0.5, (n, 3)).astype(np.float32)
    part = rng.integers(0, 5, n)
    motion = rng.integers(0, 4, n)
    confidence = rng.random(n).astype(np.float32)
    return points, part, motion, confidence


def write_text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_binary_round_trip_is_exact_and_deterministic(tmp_path):
    points, part, motion, confidence = cloud()
    path = tmp_path / "scan.ply"
    write_ply(path, points, part, motion, confidence, comments=["object_id 3", "kind noisy"])
    got = read_ply(path)
    assert got.points.dtype == np.float32 and np.array_equal(got.points, points)
    assert got.part_id is not None and np.array_equal(got.part_id, part)
    assert got.motion_type is not None and np.array_equal(got.motion_type, motion)
    assert got.confidence is not None and np.array_equal(got.confidence, confidence)
    assert got.comments == ("object_id 3", "kind noisy") and got.extra == {}
    assert not got.likely_millimetres and not got.too_many_points and got.warnings == []
    assert path.read_bytes() == encode_ply(
        points, part, motion, confidence, ["object_id 3", "kind noisy"]
    )
    header = read_ply_header(path)
    assert header.format == "binary_little_endian"
    vertex = header.element("vertex")
    assert vertex is not None and vertex.count == 50
    assert vertex.properties == (
        ("x", "float"),
        ("y", "float"),
        ("z", "float"),
        ("part_id", "int"),
        ("motion_type", "uchar"),
        ("confidence", "float"),
    )
    # the layout artic wrote before plyfile: this header, then 4 floats + int32 + uint8 a
    # point, little-endian (outputs are hashed in manifests: the bytes must not change)
    expected_header = (
        b"ply\nformat binary_little_endian 1.0\ncomment object_id 3\ncomment kind noisy\n"
        b"element vertex 50\nproperty float x\nproperty float y\nproperty float z\n"
        b"property int part_id\nproperty uchar motion_type\nproperty float confidence\n"
        b"end_header\n"
    )
    rows = np.empty(50, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("part_id", "<i4"),
                         ("motion_type", "u1"), ("confidence", "<f4")])  # fmt: skip
    for i, a in enumerate("xyz"):
        rows[a] = points[:, i]
    rows["part_id"], rows["motion_type"], rows["confidence"] = part, motion, confidence
    assert path.read_bytes() == expected_header + rows.tobytes()


def test_comments_are_ascii_without_trailing_blanks(tmp_path):
    path = tmp_path / "c.ply"
    write_ply(path, cloud(3)[0], comments=["source scän.ply", "frame input  "])
    assert b"comment source sc\\xe4n.ply\ncomment frame input\nelement" in path.read_bytes()
    assert read_ply(path).comments == ("source sc\\xe4n.ply", "frame input")


def test_plyfile_reads_what_artic_writes(tmp_path):
    points, part, motion, confidence = cloud(30, seed=4)
    path = tmp_path / "scan.ply"
    write_ply(path, points, part, motion, confidence, comments=["kind clean"])
    vertex = PlyData.read(str(path))["vertex"].data
    assert np.array_equal(np.stack([vertex[a] for a in "xyz"], axis=1), points)
    assert np.array_equal(vertex["part_id"], part) and vertex["part_id"].dtype == np.int32
    assert np.array_equal(vertex["motion_type"], motion) and vertex["motion_type"].dtype == np.uint8
    assert np.array_equal(vertex["confidence"], confidence)


def test_points_only_file_and_other_readers_agree(tmp_path):
    points = cloud()[0]
    path = tmp_path / "xyz.ply"
    write_ply(path, points)
    got = read_ply(path)
    assert got.part_id is None and got.motion_type is None and got.confidence is None
    o3d_cloud = o3d.io.read_point_cloud(str(path))  # a standard reader sees the same points
    assert np.allclose(np.asarray(o3d_cloud.points), points)
    labelled = tmp_path / "labelled.ply"
    write_ply(labelled, *cloud())
    tm_cloud = trimesh.load(labelled)  # docs/formats.md names trimesh as a reader too
    assert np.array_equal(np.asarray(tm_cloud.vertices, dtype=np.float32), points)


def test_ascii_file_with_extra_properties_and_faces(tmp_path):
    text = """ply
format ascii 1.0
comment made by hand
element vertex 3
property double x
property double y
property double z
property uchar red
property int part_id
element face 1
property list uchar int vertex_indices
end_header
0.0 0.0 0.0 255 0
1.0 0.0 0.0 0 1
0.0 1.0 0.5 10 1
3 0 1 2
"""
    got = read_ply(write_text(tmp_path / "a.ply", text))
    assert np.allclose(got.points, [[0, 0, 0], [1, 0, 0], [0, 1, 0.5]])
    assert got.part_id is not None and got.part_id.tolist() == [0, 1, 1]
    assert got.extra["red"].tolist() == [255, 0, 10]
    assert got.comments == ("made by hand",)


def test_open3d_ascii_output_and_big_endian_binary_read(tmp_path):
    points = cloud(20)[0].astype(np.float64)
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    path = tmp_path / "o3d.ply"
    assert o3d.io.write_point_cloud(str(path), pcd, write_ascii=True)
    assert np.allclose(read_ply(path).points, points, atol=1e-6)
    # big-endian binary, with a fixed-size element before the vertices
    header = (
        "ply\nformat binary_big_endian 1.0\nelement camera 1\nproperty float fx\n"
        "element vertex 20\nproperty float x\nproperty float y\nproperty float z\n"
        "property ushort part_id\nend_header\n"
    )
    rows = np.zeros(20, dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("part_id", ">u2")])
    for i, a in enumerate("xyz"):
        rows[a] = points[:, i]
    rows["part_id"] = np.arange(20)
    big = tmp_path / "big.ply"
    big.write_bytes(header.encode() + np.array([525.0], ">f4").tobytes() + rows.tobytes())
    got = read_ply(big)
    assert np.array_equal(got.points, points.astype(np.float32))
    assert got.part_id is not None and got.part_id.tolist() == list(range(20))


def test_flags_for_millimetres_and_large_clouds(tmp_path):
    points = cloud(200)[0] * 1000.0  # a cloud of about 1 m written in millimetres
    path = tmp_path / "mm.ply"
    write_ply(path, points)
    got = read_ply(path, max_points=100)
    assert got.likely_millimetres and got.diagonal > 20
    assert got.too_many_points
    assert any("divide by 1000" in w for w in got.warnings)
    assert any("downsampled" in w for w in got.warnings)
    assert not read_ply(path, max_points=200).too_many_points


GOOD_HEADER = (
    "ply\nformat ascii 1.0\nelement vertex 2\n"
    "property float x\nproperty float y\nproperty float z\n"
)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("text.ply", "hello\n", "not a PLY file"),
        ("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n", "no end_header"),
        ("noformat.ply", "ply\nelement vertex 1\nproperty float x\nend_header\n", "format"),
        ("badline.ply", "ply\nformat ascii 1.0\nbogus line\nend_header\n", "line 3"),
        ("faces.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n", "no vertex element"),
        (
            "empty.ply",
            "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n",
            "no vertices",
        ),
        (
            "noz.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
            "end_header\n0 0\n",
            "no z property",
        ),
        (
            "short.ply",
            GOOD_HEADER + "end_header\n0 0 0\n",
            r"truncated \(its header declares 2 rows of element 'vertex'\)",
        ),
        ("words.ply", GOOD_HEADER + "end_header\n0 0 0\n0 zero 0\n", "row 2, property 'y'"),
        ("long.ply", GOOD_HEADER + "end_header\n0 0 0\n0 0 0 0\n", "row 2: expected end-of-line"),
        (
            "type.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty real x\nend_header\n",
            "line 4 not understood",
        ),
        ("binary.ply", b"ply\nformat ascii 1.0\ncomment \xff\nend_header\n", "not ASCII"),
        ("nan.ply", GOOD_HEADER + "end_header\n0 0 0\nnan 0 0\n", "1 of 2 points have NaN"),
        ("inf.ply", GOOD_HEADER + "end_header\ninf 0 0\n0 0 0\n", "NaN or infinite"),
        (
            "motion.ply",
            GOOD_HEADER.replace("vertex 2", "vertex 1")
            + "property uchar motion_type\nend_header\n0 0 0 7\n",
            "motion_type values must be 0..3",
        ),
        (
            "list.ply",
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
            "property float z\nproperty list uchar int n\nend_header\n0 0 0 1 1\n",
            "list properties",
        ),
    ],
)
def test_bad_files_raise_one_line_input_errors(tmp_path, name, content, message):
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        write_text(path, content)
    with pytest.raises(InputError, match=message) as info:
        read_ply(path)
    assert "\n" not in str(info.value) and name in str(info.value)


def test_missing_truncated_binary_and_too_few_points(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_ply(tmp_path / "absent.ply")
    with pytest.raises(InputError, match="no such file"):
        read_ply(tmp_path)  # a folder is not a PLY file
    points = cloud(10)[0]
    data = encode_ply(points)
    cut = tmp_path / "cut.ply"
    cut.write_bytes(data[:-5])
    with pytest.raises(InputError, match="truncated"):
        read_ply(cut)
    whole = tmp_path / "ten.ply"
    whole.write_bytes(data)
    with pytest.raises(InputError, match="10 points; at least 100 needed"):
        read_ply(whole, min_points=100)


def test_encoder_rejects_malformed_arrays():
    points = cloud(5)[0]
    with pytest.raises(ValueError, match="points must be"):
        encode_ply(points[:, :2])
    with pytest.raises(ValueError, match="part_id"):
        encode_ply(points, part_id=np.zeros(4, dtype=np.int64))
    with pytest.raises(ValueError, match="single lines"):
        encode_ply(points, comments=["two\nlines"])


def test_binary_file_with_a_list_element_before_the_vertices(tmp_path):
    # plyfile parses elements with lists wherever they are (the hand-written reader refused)
    header = (
        "ply\nformat binary_little_endian 1.0\nelement face 1\n"
        "property list uchar int vertex_indices\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nend_header\n"
    )
    face = np.array([3], "u1").tobytes() + np.array([0, 1, 2], "<i4").tobytes()
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4")
    path = tmp_path / "mesh.ply"
    path.write_bytes(header.encode() + face + points.tobytes())
    assert np.array_equal(read_ply(path).points, points)
    header_read = read_ply_header(path)
    face_element = header_read.element("face")
    assert face_element is not None and face_element.has_lists
    assert face_element.properties == (("vertex_indices", "list uchar int"),)
