"""musclewrap.output: the ParaView collection, the CSV files, the stretch colours, the plots."""

import csv
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from musclewrap.output import (
    STRETCH_RANGE,
    plot_convergence,
    plot_penetration,
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


def _drawn(monkeypatch):
    """The figures the plot functions make, drawn and kept open instead of written."""
    from musclewrap.output import _series

    figs = []

    def keep(fig, path, *, tight=True):
        fig.canvas.draw()
        figs.append(fig)
        return path

    monkeypatch.setattr(_series, "_save_png", keep)
    return figs


def test_plots_of_many_muscles_keep_legends_off_the_data_and_muscles_apart(tmp_path, monkeypatch):
    """18 muscles (a whole thigh): the legend beside the panels, not over them; every muscle
    its own colour or marker, its squares (the paper's iteration) in its line's colour; the
    title within the figure, however long."""
    from matplotlib.colors import to_rgba

    figs = _drawn(monkeypatch)
    names = [f"muscle_{i:02d}_{'x' * 12}" for i in range(18)]
    frames = list(range(0, 211, 10))
    series = {n: (frames, [1e-15 * (i + 1)] * len(frames)) for i, n in enumerate(names)}
    plot_volume_error(
        tmp_path / "v.png", series, title="a scene's name that runs long " * 4,
        markers={n: ([0, 210], [1e-16, 2e-16]) for n in names},
        line_label="sqp", marker_label="paper, eq. 11",
    )  # fmt: skip
    depths = {n: (frames, [0.01 * i] * len(frames)) for i, n in enumerate(names)}
    plot_penetration(
        tmp_path / "p.png", depths, title="the whole leg: muscles and bones in each other " * 3,
        before=depths, bone_inside=depths, muscle_inside=depths, line_inside=depths, limit=0.5,
    )  # fmt: skip
    for fig in figs:
        r = fig.canvas.get_renderer()
        ax = fig.axes[0]
        legend = ax.get_legend().get_window_extent(r)
        assert all(not legend.overlaps(a.get_window_extent(r)) for a in fig.axes)
        assert legend.x1 <= fig.bbox.x1 and legend.y0 >= fig.bbox.y0
        title = ax.title.get_window_extent(r)
        assert fig.bbox.x0 <= title.x0 and title.x1 <= fig.bbox.x1 and title.y1 <= fig.bbox.y1
        lines = {ln.get_label(): ln for ln in ax.get_lines() if ln.get_label() in names}
        assert len(lines) == 18
        assert len({(to_rgba(ln.get_color()), ln.get_marker()) for ln in lines.values()}) == 18
    squares = [ln for ln in figs[0].axes[0].get_lines() if ln.get_marker() == "s"][:18]
    for name, sq in zip(names, squares, strict=True):
        assert to_rgba(sq.get_color()) == to_rgba(
            next(ln for ln in figs[0].axes[0].get_lines() if ln.get_label() == name).get_color()
        )


def test_convergence_plot_of_many_muscles_is_rows_of_pairs(tmp_path, monkeypatch):
    """18 muscles: three rows of six panel pairs (not one strip 6,400 pixels wide), no
    panel's title on another's labels."""
    figs = _drawn(monkeypatch)
    hist = {"exact": [(1.0, 1e-3), (1e-6, 1e-14)], "paper": [(1.0, 1e-3), (0.1, 1e-5)]}
    plot_convergence(tmp_path / "c.png", {f"m{i}": (3, hist) for i in range(18)}, title="t")
    (fig,) = figs
    assert len(fig.axes) == 36
    width, height = fig.get_size_inches()
    assert width <= 3.2 * 6 + 1 and height < 2 * width
    r = fig.canvas.get_renderer()
    boxes = [a.get_window_extent(r) for a in fig.axes]
    texts = [t.get_window_extent(r) for a in fig.axes for t in (a.title, a.xaxis.label)
             if t.get_text()]  # fmt: skip
    assert sum(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1 :]) == 0
    assert sum(a.overlaps(b) for i, a in enumerate(texts) for b in texts[i + 1 :]) == 0
    for t in texts:
        assert not any(t.overlaps(b) for b in boxes)
