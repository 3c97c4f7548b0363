import numpy as np

from artic.artifacts.formats import read_npz, write_csv, write_npz


def test_npz_round_trip_and_same_bytes(tmp_path):
    arrays = {
        "depth": np.arange(2 * 4 * 5, dtype=np.uint16).reshape(2, 4, 5),
        "labels": np.linspace(0, 1, 6).reshape(2, 3),
        "names": np.array(["a", "bc"]),
    }
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    write_npz(a, arrays)
    write_npz(b, arrays)
    assert a.read_bytes() == b.read_bytes()
    back = read_npz(a)
    assert list(back) == list(arrays)
    for k, v in arrays.items():
        assert back[k].dtype == v.dtype
        np.testing.assert_array_equal(back[k], v)


def test_csv_floats_round_trip_exactly(tmp_path):
    value = 0.1 + 0.2
    path = tmp_path / "x.csv"
    write_csv(path, ["a", "b"], [[np.float64(value), np.int32(3)]])
    header, row = path.read_text().splitlines()
    assert header == "a,b"
    a, b = row.split(",")
    assert float(a) == value and b == "3"
