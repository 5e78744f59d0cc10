"""musclewrap.output: the ParaView collection, the CSV files, the stretch colours, the plots."""

import csv
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from musclewrap.output import (
    STRETCH_RANGE,
    plot_volume_error,
    stretch_colours,
    stretch_table,
    write_csv,
    write_pvd,
)


def test_pvd_lists_each_time_with_its_parts_in_order(tmp_path):
    entries = [(0.0, "a_0.vtp"), (0.0, "b & c_0.vtp"), (0.5, "a_1.vtp"), (0.1 + 0.2, "a_2.vtp")]
    p = write_pvd(tmp_path / "scene.pvd", entries)
    root = ET.parse(p).getroot()
    assert root.get("type") == "Collection"
    got = [(d.get("timestep"), d.get("part"), d.get("file")) for d in root.iter("DataSet")]
    # a time written to the last bit (repr), files quoted, parts counted per time step
    assert got == [
        ("0.0", "0", "a_0.vtp"),
        ("0.0", "1", "b & c_0.vtp"),
        ("0.5", "0", "a_1.vtp"),
        (repr(0.1 + 0.2), "0", "a_2.vtp"),
    ]
    assert float(got[3][0]) == 0.1 + 0.2
    assert sorted(x.name for x in tmp_path.iterdir()) == ["scene.pvd"]  # no temporary left


def test_csv_keeps_the_column_order_and_leaves_out_other_keys(tmp_path):
    rows = [{"b": 2, "a": 1, "extra": "x"}, {"a": 3.5, "b": "y,z"}]
    p = write_csv(tmp_path / "r.csv", rows, ["a", "b"])
    with open(p, newline="") as fh:
        got = list(csv.reader(fh))
    assert got == [["a", "b"], ["1", "2"], ["3.5", "y,z"]]


def test_a_csv_that_cannot_be_written_leaves_the_old_file_whole(tmp_path):
    p = write_csv(tmp_path / "r.csv", [{"a": 1}], ["a"])
    before = p.read_bytes()

    class Bad:
        def __str__(self):
            raise RuntimeError("no text")

    with pytest.raises(RuntimeError):
        write_csv(p, [{"a": Bad()}], ["a"])
    assert p.read_bytes() == before
    assert sorted(x.name for x in tmp_path.iterdir()) == ["r.csv"]


def test_stretch_colours_white_at_one_and_equal_ratios_alike():
    table = stretch_table()
    mid = table[len(table) // 2 - 1 : len(table) // 2 + 1]
    assert np.all(mid > 0.95)  # near-white at a stretch of 1
    lo, hi = STRETCH_RANGE
    assert lo == pytest.approx(1 / hi)
    c = stretch_colours(np.array([1.0, np.nan, hi, hi * 10, lo, lo / 10, 1.2, 1 / 1.2]))
    assert c.dtype == np.uint8 and c.shape == (8, 3)
    np.testing.assert_array_equal(c[0], c[1])  # NaN drawn as 1
    np.testing.assert_array_equal(c[2], c[3])  # beyond the range: its end's colour
    np.testing.assert_array_equal(c[4], c[5])
    assert c[2, 0] > c[2, 2] and c[4, 2] > c[4, 0]  # stretched red, compressed blue
    # equal ratios either side of 1 take entries equally far either side of the middle
    rgb = np.rint(255 * table).astype(np.uint8)
    i, j = (int(np.flatnonzero((rgb == x).all(axis=1))[0]) for x in (c[6], c[7]))
    assert i > len(table) // 2 > j and i + j == len(table) - 1


def test_volume_error_plot_draws_exact_volumes_too(tmp_path):
    # a run's volumes are often exact to the last bit: an error of 0 on the log axis
    series = {"a": ([0, 1, 2, 3], [1e-12, -3e-13, 0.0, 2e-15]), "b": ([0, 1], [0.0, 0.0])}
    p = plot_volume_error(tmp_path / "v.png", series, title="t", markers={"a": ([1], [1e-9])})
    assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["v.png"]
