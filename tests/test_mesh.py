import numpy as np
import pytest

from musclewrap.mesh import (
    MeshError,
    check_mesh,
    clean_mesh,
    cubic_root_near,
    read_mesh,
    volume,
    volume_cubic,
    volume_gradient,
    write_mesh,
)
from musclewrap.synthetic import capsule, rings_mesh

TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def test_tetrahedron_volume_analytic():
    assert volume(TET_V, TET_F) == pytest.approx(1 / 6, rel=1e-15)
    assert volume(TET_V + 1e4, TET_F) == pytest.approx(1 / 6, rel=1e-9)


def test_sphere_volume_converges():
    # a fine surface of revolution approximating a sphere of radius 10
    th = np.linspace(0, np.pi, 401)
    V, F = rings_mesh(-10 * np.cos(th), 10 * np.sin(th), 400)
    assert volume(V, F) == pytest.approx(4 / 3 * np.pi * 1000, rel=1e-3)


def test_volume_gradient_matches_finite_differences():
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    rng = np.random.default_rng(1)
    V = V + rng.normal(scale=0.5, size=V.shape)
    G = volume_gradient(V, F)
    h = 1.0  # the volume is linear in any single coordinate: central differences are exact
    for i, k in [(0, 0), (7, 1), (30, 2)]:
        Vp, Vm = V.copy(), V.copy()
        Vp[i, k] += h
        Vm[i, k] -= h
        assert G[i, k] == pytest.approx((volume(Vp, F) - volume(Vm, F)) / (2 * h), rel=1e-7)


def test_volume_cubic_is_exact():
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    B = np.random.default_rng(2).normal(size=V.shape)
    c = volume_cubic(V, B, F)
    for t in (-0.7, 0.3, 2.0):
        assert np.polyval(c[::-1], t) == pytest.approx(
            volume(V + t * B, F, center=np.zeros(3)), rel=1e-12
        )


def test_capsule_counts_and_checks():
    V, F = capsule()
    assert V.shape == (15074, 3) and F.shape == (30144, 3)
    chk = check_mesh(V, F)
    assert chk.ok and chk.closed


def test_a_sleeve_is_a_closed_outward_tube_of_the_faceted_annulus_volume():
    from musclewrap.synthetic import sleeve

    V, F = sleeve(5.0, 10.0, 60.0, n_around=64, segments=30, cap_rings=3)
    assert V.shape == (64 * 66, 3) and F.shape == (2 * 64 * 66, 3)
    chk = check_mesh(V, F)
    assert chk.ok and chk.closed and chk.components == 1
    # Euler characteristic 0: genus 1
    assert len(V) - len(F) // 2 * 3 + len(F) == 0
    want = 60.0 * 32 * np.sin(2 * np.pi / 64) * (10.0**2 - 5.0**2)  # a prism on 64-gons
    assert volume(V, F) == pytest.approx(want, rel=1e-12)
    with pytest.raises(ValueError, match="inner < outer"):
        sleeve(10.0, 5.0, 60.0)


def test_open_mesh_refused():
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    with pytest.raises(MeshError, match="boundary edge"):
        clean_mesh(V, F[1:], source="holey.stl")


def test_inward_mesh_flipped():
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    V2, F2, notes = clean_mesh(V, F[:, ::-1], source="x")
    assert volume(V2, F2) > 0 and any("inward" in n for n in notes)


@pytest.mark.parametrize("ext", [".vtp", ".vtk", ".ply", ".obj", ".stl", ".off"])
def test_roundtrip_formats(tmp_path, ext):
    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    V = V + 0.123456789012345
    p = write_mesh(tmp_path / f"m{ext}", V, F)
    V2, F2 = read_mesh(p)
    if ext == ".stl":
        from musclewrap.mesh import merge_duplicate_vertices

        V2, F2, _ = merge_duplicate_vertices(V2, F2)
        assert volume(V2, F2) == pytest.approx(volume(V, F), rel=1e-6)
    else:
        assert np.array_equal(V2, V), "float64 coordinates must survive"
        assert volume(V2, F2) == volume(V, F)
    assert not list(tmp_path.glob(".*part*")), "no temporary file may be left behind"


@pytest.mark.parametrize("ext", [".vtp", ".vtk"])
def test_vtk_lines_and_point_data_read_back_by_vtk(tmp_path, ext):
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    V, F = capsule(n_around=8, cap_rings=2, segments=2)
    seg = np.array([[0, 1], [1, 2], [5, 6]])
    data = {
        "depth": np.linspace(-1, 1, len(V)),
        "normal": np.ones((len(V), 3), np.float32),
        "label": np.arange(len(V), dtype=np.int32),
        'a "quoted" <name>': np.zeros(len(V), np.uint8),
    }
    p = write_mesh(tmp_path / f"m{ext}", V, F, point_data=data, lines=seg)
    r = vtkXMLPolyDataReader() if ext == ".vtp" else vtkPolyDataReader()
    r.SetFileName(str(p))
    r.Update()
    poly = r.GetOutput()
    assert np.array_equal(vtk_to_numpy(poly.GetPoints().GetData()), V)
    polys = vtk_to_numpy(poly.GetPolys().GetConnectivityArray())
    assert np.array_equal(polys.reshape(-1, 3), F)
    lines = vtk_to_numpy(poly.GetLines().GetConnectivityArray())
    assert np.array_equal(lines.reshape(-1, 2), seg)
    for name, values in data.items():
        got = vtk_to_numpy(poly.GetPointData().GetArray(name))
        assert np.array_equal(got.reshape(values.shape), values), name


@pytest.mark.parametrize("content", [b"", b"solid x\nfacet garbage", b"\x00\x01\x02" * 50])
@pytest.mark.parametrize("ext", [".stl", ".vtk", ".vtp", ".ply", ".obj", ".off"])
def test_bad_files_named_in_error(tmp_path, content, ext):
    p = tmp_path / f"bad{ext}"
    p.write_bytes(content)
    with pytest.raises(MeshError, match="bad"):
        read_mesh(p)


@pytest.mark.parametrize("ext", [".stl", ".vtk", ".vtp", ".ply", ".obj", ".off"])
def test_truncated_files_are_refused_naming_the_file(tmp_path, ext):
    V, F = capsule(n_around=24, cap_rings=6, segments=10)
    p = tmp_path / f"cut{ext}"
    write_mesh(p, V, F)
    data = p.read_bytes()
    for keep in (0.3, 0.6, 0.9):
        p.write_bytes(data[: int(keep * len(data))])
        # refused by the reader, or read in part and refused by the checks: never accepted
        with pytest.raises(MeshError, match="cut"):
            clean_mesh(*read_mesh(p), source=str(p))


def test_vertices_of_the_wrong_shape_refused(tmp_path):
    p = tmp_path / "flat.obj"
    p.write_text("v 1.0\nv 2.0\nv 3.0\nf 1 2 3\n")  # one coordinate per vertex
    with pytest.raises(MeshError, match="flat.obj.*wrong shape"):
        read_mesh(p)


@pytest.mark.realdata
def test_legacy_vtk_that_crashes_vtks_reader_is_refused(data_dir, tmp_path):
    import random
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from fuzz import mutate

    # the third damaged copy of the psoas from this seed made VTK's legacy reader crash
    # (SIGSEGV) when read in the process itself
    data = (data_dir / "lhdl" / "muscles" / "LHDL_R_Psoas.vtk").read_bytes()
    rng = random.Random(7)
    for _ in range(3):
        damaged = mutate(data, rng)
    p = tmp_path / "damaged.vtk"
    p.write_bytes(damaged)
    with pytest.raises(MeshError, match="damaged.vtk"):
        read_mesh(p)


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_non_finite_coordinates_refused(tmp_path, bad):
    p = tmp_path / "poisoned.obj"
    p.write_text(f"v 0 0 0\nv 1 0 0\nv 0 {bad} 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    with pytest.raises(MeshError, match="poisoned.obj: 1 vertex coordinate row.*NaN or infinite"):
        read_mesh(p)
    # arrays handed to the library directly are checked too, before any geometry
    from musclewrap.mesh import clean_mesh

    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    V[3, 1] = float(bad)
    with pytest.raises(MeshError, match="arrays.stl: 1 vertex coordinate row.*NaN or infinite"):
        clean_mesh(V, F, source="arrays.stl", repair=True)


def test_second_belly_is_refused_not_dropped():
    from musclewrap.mesh import clean_mesh

    V, F = capsule(n_around=24, cap_rings=6, segments=10)
    small = (V - V.mean(axis=0)) * 0.5 + V.mean(axis=0) + [60.0, 0, 0]
    V2, F2 = np.vstack([V, small]), np.vstack([F, F + len(V)])
    with pytest.raises(MeshError, match="bellies.stl: not a closed 2-manifold.*2 connected"):
        clean_mesh(V2, F2, source="bellies.stl")
    # automatic repair would keep only the larger belly: refused, with the reason
    with pytest.raises(MeshError, match=r"bellies.stl: .*-11.11 %.*second belly"):
        clean_mesh(V2, F2, source="bellies.stl", repair=True)


def test_self_intersecting_surface_refused():
    from scipy.spatial.transform import Rotation

    from musclewrap.mesh import clean_mesh
    from musclewrap.mesh._checks import self_intersecting_faces

    V, F = capsule(n_around=24, cap_rings=6, segments=20)
    # a clean surface has none, wherever it lies and at any scale
    for seed, scale in enumerate([1e-3, 0.02, 1.0, 50.0, 1e3]):
        R = Rotation.random(random_state=seed).as_matrix()
        assert self_intersecting_faces(scale * (V @ R.T + [300.0, -200, 500]), F) == 0
    # a band of one side pushed through the opposite wall: still closed, manifold, one piece
    c = V.mean(axis=0)
    band = (np.abs(V[:, 2] - c[2]) < 15) & (V[:, 0] > c[0] + 10)
    V[band, 0] -= 2 * (V[band, 0] - c[0]) + 10
    assert self_intersecting_faces(V, F) == self_intersecting_faces(V * 1e-3 + 7.0, F) > 20
    with pytest.raises(MeshError, match=r"folded.stl: the surface passes through itself \(\d+"):
        clean_mesh(V, F, source="folded.stl", repair=True)


def test_missing_file():
    with pytest.raises(MeshError, match="no such mesh file"):
        read_mesh("/nonexistent/muscle.stl")


def test_merge_duplicate_vertices_soup_and_signed_zero():
    from musclewrap.mesh import merge_duplicate_vertices

    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-0.0, 0, 0], [1, 0, 0], [0, 0, 1]])
    F = np.array([[0, 1, 2], [3, 4, 5]])
    V2, F2, merged = merge_duplicate_vertices(V, F)
    assert merged == 2 and len(V2) == 4
    assert np.array_equal(V2[F2], V[F])
    # in the order of first appearance
    assert np.array_equal(V2, V[[0, 1, 2, 5]])


def test_merging_keeps_the_input_order():
    # a clean mesh comes back vertex by vertex, whatever the order of its vertices; an unused
    # vertex is dropped and the others keep their order
    from musclewrap.mesh import merge_duplicate_vertices

    V, F = capsule(n_around=24, cap_rings=6, segments=10)
    perm = np.random.default_rng(2).permutation(len(V))
    Vp, Fp = V[perm], np.argsort(perm)[F]
    V2, F2, merged = merge_duplicate_vertices(Vp, Fp)
    assert merged == 0 and np.array_equal(V2, Vp) and np.array_equal(F2, Fp)
    extra = np.vstack([Vp[:5], [[99.0, 99, 99]], Vp[5:]])
    V3, F3, merged = merge_duplicate_vertices(extra, np.where(Fp >= 5, Fp + 1, Fp))
    assert merged == 1 and np.array_equal(V3, Vp) and np.array_equal(F3, Fp)


def test_vertex_origins_maps_back_to_the_first_input_vertex():
    from musclewrap.mesh import merge_duplicate_vertices, vertex_origins

    # a soup: merged duplicates go to their first appearance; -0.0 is 0.0; a new vertex is -1
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [-0.0, 0, 0], [1, 0, 0], [0, 0, 1]])
    V2, _, _ = merge_duplicate_vertices(V, np.array([[0, 1, 2], [3, 4, 5]]))
    assert vertex_origins(V, V2).tolist() == [0, 1, 2, 5]
    assert vertex_origins(V, np.vstack([V2[::-1], [[0.5, 0.5, 0]]])).tolist() == [5, 2, 1, 0, -1]
    # a permutation comes back as its inverse
    C, _ = capsule(n_around=12, cap_rings=3, segments=4)
    perm = np.random.default_rng(0).permutation(len(C))
    assert np.array_equal(vertex_origins(C, C[perm]), perm)


@pytest.mark.realdata
def test_real_muscles_keep_their_vertex_order(data_dir):
    # every real muscle file that needs no merging comes back from tidying as it was read;
    # the STL soups in the order of each vertex's first appearance
    from musclewrap.mesh import tidy_mesh

    files = sorted((data_dir / "lhdl" / "muscles").glob("*.vtk"))
    files += sorted((data_dir / "lhdl" / "muscles_ply").glob("*.ply"))
    files += sorted((data_dir / "vhf").glob("*Muscle*.stl"))
    assert len(files) >= 10
    for f in files:
        V, F = read_mesh(f)
        V2, F2, _ = tidy_mesh(V, F)
        if len(F2) == len(F):
            assert np.array_equal(V2[F2], V[F]), f
        # each kept vertex appears in the input no later than the one after it
        row = {tuple(v): i for i, v in reversed(list(enumerate(V.tolist())))}
        first = np.array([row[tuple(v)] for v in V2.tolist()])
        assert np.all(np.diff(first) > 0), f
        if len(V2) == len(V):
            assert np.array_equal(V2, V), f


# ------------------------------------------------- repairable and refused topology
def _capsule():
    return capsule(n_around=24, cap_rings=6, segments=10)


def test_inconsistently_oriented_faces_are_flipped_and_reported():
    V, F = _capsule()
    want = volume(V, F)
    bad = F.copy()
    bad[5:15] = bad[5:15, ::-1]
    assert check_mesh(V, bad).inconsistent_edges > 0
    for faces in (bad, bad[:, ::-1]):  # the same, and then the whole surface inward too
        V2, F2, notes = clean_mesh(V, faces, source="patchy.stl")
        assert "10 of 1008 faces were oriented against their neighbours: flipped" in notes[0]
        chk = check_mesh(V2, F2)
        assert chk.ok and chk.inconsistent_edges == 0
        assert volume(V2, F2) == pytest.approx(want, rel=1e-12)


def test_one_sided_surface_cannot_be_oriented():
    from musclewrap.mesh import orient_faces

    # a Moebius strip: 12 quads around a half-twisted band
    n = 12
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    F = []
    for i in range(n):
        j = (i + 1) % n
        a, b = 2 * i, 2 * i + 1
        c, d = (2 * j, 2 * j + 1) if j else (1, 0)  # the half twist joins the ends crossed
        F += [[a, c, b], [b, c, d]]
    F = np.array(F)
    assert orient_faces(F, 2 * n) is None
    # an orientable band with the same faces scrambled is oriented
    Fb = np.array([[2 * i, 2 * ((i + 1) % n), 2 * i + 1] for i in range(n)])
    Fb = np.vstack([Fb, [[2 * i + 1, 2 * ((i + 1) % n), 2 * ((i + 1) % n) + 1] for i in range(n)]])
    Fb[::3] = Fb[::3, ::-1]
    out = orient_faces(Fb, 2 * n)
    assert out is not None and out[1] == 8
    ring = np.c_[np.cos(t).repeat(2), np.sin(t).repeat(2), np.tile([0.0, 1.0], n)]
    assert check_mesh(ring, Fb).inconsistent_edges > 0
    assert check_mesh(ring, out[0]).inconsistent_edges == 0


def test_surfaces_touching_at_a_vertex_are_refused_or_split():
    V, F = _capsule()
    top, bottom = int(np.argmax(V[:, 2])), int(np.argmin(V[:, 2]))
    # a second capsule standing on the first, sharing its pole vertex
    V2 = V - V[bottom] + V[top]
    F2 = F + len(V)
    F2[F2 == len(V) + bottom] = top
    V2, F2 = np.vstack([V, V2]), np.vstack([F, F2])
    chk = check_mesh(V2, F2)
    assert chk.closed and chk.components == 1 and chk.nonmanifold_vertices == 1
    with pytest.raises(MeshError, match="touch.stl: .*1 non-manifold vertex"):
        clean_mesh(V2, F2, source="touch.stl")
    # split, the two are separate bodies: a second belly, not a repair
    with pytest.raises(MeshError, match="touch.stl: .*-50.00 %.*second belly"):
        clean_mesh(V2, F2, source="touch.stl", repair=True)
    # a sliver touching the muscle at one vertex is split off and dropped
    tet = np.array([[0.0, 0, 0], [0.3, 0, 0], [0, 0.3, 0], [0, 0, 0.3]]) + V[top]
    tf = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]) + len(V)
    tf[tf == len(V)] = top
    V3, F3 = np.vstack([V, tet]), np.vstack([F, tf])
    V4, F4, notes = clean_mesh(V3, F3, source="tag.stl", repair=True)
    assert "split 1 non-manifold vertex" in notes[-2] and "PyMeshFix" in notes[-1]
    assert check_mesh(V4, F4).ok
    assert volume(V4, F4) == pytest.approx(volume(V, F), rel=1e-9)


def test_zero_area_face_is_kept_and_the_muscle_deforms():
    from musclewrap import Muscle

    V, F = _capsule()
    a, b, c = F[0]
    m = len(V)
    # the edge a-b gets its midpoint m: face 0 becomes two, and the flat triangle (m, a, b)
    # closes the surface against the neighbour that still runs b -> a
    V2 = np.vstack([V, (V[a] + V[b]) / 2])
    F2 = np.vstack([F[1:], [[a, m, c], [m, b, c], [m, a, b]]])
    _, _, notes = clean_mesh(V2, F2, source="flat.stl")
    assert notes == ["kept 1 zero-area face(s) (they add no volume)"]
    mu = Muscle.from_mesh(V2, F2, cage_size=150)
    z0, z1 = V[:, 2].min() + 1, V[:, 2].max() - 1
    r = mu.bind({"a": [[0, 0, z0], [0, 0, z1]]}).deform({"a": [[0, 0, z0], [15, 0, z1 - 3]]})
    assert r.converged and abs(r.relative_volume_error) <= 1e-9 and np.isfinite(r.V).all()


def test_sliver_hole_and_fin_are_repaired_with_the_change_reported():
    V, F = _capsule()
    want = volume(V, F)
    tet = np.array([[0.0, 0, 0], [0.5, 0, 0], [0, 0.5, 0], [0, 0, 0.5]]) + [100.0, 0, 0]
    tf = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]) + len(V)
    a, b, c = F[100]
    n = np.cross(V[b] - V[a], V[c] - V[a])
    cases = {
        "sliver": (np.vstack([V, tet]), np.vstack([F, tf]), "2 connected components"),
        "hole": (V, F[1:], "open: 3 boundary edge"),
        "fin": (
            np.vstack([V, V[a] + 3 * n / np.linalg.norm(n)]),
            np.vstack([F, [[a, b, len(V)], [b, a, len(V)]]]),
            "1 non-manifold edge",
        ),
    }
    for name, (V2, F2, problem) in cases.items():
        with pytest.raises(MeshError, match=f"{name}.ply: not a closed 2-manifold.*{problem}"):
            clean_mesh(V2, F2, source=f"{name}.ply")
        V3, F3, notes = clean_mesh(V2, F2, source=f"{name}.ply", repair=True)
        assert check_mesh(V3, F3).ok
        assert len(notes) == 1 and f"repaired with PyMeshFix ({problem}" in notes[0]
        assert "volume " in notes[0] and "relative)" in notes[0]
        assert volume(V3, F3) == pytest.approx(want, rel=1e-3)


@pytest.mark.parametrize("ext", [".vtp", ".vtk"])
def test_poly_lines_and_cell_data_read_back_with_vtk(tmp_path, ext):
    """Fibres: one poly-line cell of K points each, with per-cell arrays, read by VTK itself."""
    import pyvista as pv

    n, k = 4, 5
    P = np.random.default_rng(1).normal(size=(n * k, 3))
    lines = np.arange(n * k).reshape(n, k)
    path = write_mesh(
        tmp_path / f"f{ext}",
        P,
        np.zeros((0, 3), int),
        lines=lines,
        cell_data={"fibre": np.arange(n), "length": np.linspace(1, 2, n)},
    )
    m = pv.read(path)
    assert m.n_cells == n and m.n_points == n * k
    np.testing.assert_array_equal(m.lines.reshape(n, k + 1)[:, 1:], lines)
    np.testing.assert_array_equal(m.cell_data["fibre"], np.arange(n))
    np.testing.assert_allclose(m.cell_data["length"], np.linspace(1, 2, n))
    np.testing.assert_allclose(m.points, P)
    with pytest.raises(ValueError, match="cell array 'x' has 3 values for 4 cells"):
        write_mesh(tmp_path / f"g{ext}", P, np.zeros((0, 3), int), lines=lines,
                   cell_data={"x": np.zeros(3)})  # fmt: skip
    with pytest.raises(ValueError, match="j >= 2"):
        write_mesh(tmp_path / f"h{ext}", P, np.zeros((0, 3), int), lines=lines[:, :1])


def _box(subdivisions: int = 2) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    b = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    for _ in range(subdivisions):
        b = b.subdivide()
    return np.asarray(b.vertices), np.asarray(b.faces)


def test_winding_numbers_sphere_and_ties():
    """Exact counts: a sphere against its radius; a box against points on its grid, whose
    rays along x run through the box's edges and vertices and along faces seen edge-on."""
    from musclewrap.mesh import winding_numbers

    th = np.linspace(0, np.pi, 201)
    V, F = rings_mesh(-10 * np.cos(th), 10 * np.sin(th), 200)
    P = np.random.default_rng(3).uniform(-15, 15, size=(20000, 3))
    r = np.linalg.norm(P, axis=1)
    keep = np.abs(r - 10) > 0.05  # the polygonal sphere lies within 0.013 of the round one
    w = winding_numbers(P[keep], V, F)
    assert set(np.unique(w)) == {0, 1}
    assert np.array_equal(w == 1, r[keep] < 10)
    # rays through the vertices and mid-edges of the sphere
    E = 0.5 * (V[F[:, 0]] + V[F[:, 1]])
    Q = np.vstack([V, E])
    Q = Q[np.abs(Q[:, 0]) > 1] * [0.3, 1.0, 1.0]  # at least 0.05 inside
    assert len(Q) > 50000 and np.all(winding_numbers(Q, V, F) == 1)
    Vb, Fb = _box()
    g = np.stack(np.meshgrid(*[np.linspace(-1.5, 1.5, 13)] * 3), -1).reshape(-1, 3)
    g = g[np.abs(np.abs(g).max(axis=1) - 1) > 1e-9]  # off the box's faces
    assert np.array_equal(winding_numbers(g, Vb, Fb), (np.abs(g).max(axis=1) < 1).astype(int))


def test_winding_numbers_count_overlaps_and_orientation():
    from musclewrap.mesh import winding_numbers

    Vb, Fb = _box()
    V = np.vstack([Vb, Vb + [1.0, 0.5, 0.25]])
    F = np.vstack([Fb, Fb + len(Vb)])
    P = np.array([[0.5, 0.5, 0.5], [-0.5, -0.5, -0.5], [1.5, 1.2, 1.0], [3.0, 0, 0]])
    assert winding_numbers(P, V, F).tolist() == [2, 1, 1, 0]
    assert winding_numbers(P, Vb, Fb[:, ::-1]).tolist() == [-1, -1, 0, 0]
    assert winding_numbers(np.zeros((0, 3)), Vb, Fb).shape == (0,)


def test_lazy_winding_grid_bins_only_where_asked_and_counts_the_same(data_dir):
    """A lazy grid bins the cells its queries need: the same winding numbers bit for bit as
    the whole grid's, on points spread over a real muscle, near its vertices, at its
    vertices and mid-edges (rays through edges), in batches that move the region along the
    surface; few points near a large surface bin a small part of it."""
    from musclewrap.mesh import WindingGrid

    V, F = read_mesh(data_dir / "lhdl" / "muscles" / "LHDL_R_GluteusMaximus.vtk")[:2]
    rng = np.random.default_rng(7)
    lo, hi = V.min(0), V.max(0)
    P = np.vstack(
        [
            rng.uniform(lo - 5, hi + 5, size=(20000, 3)),
            V + rng.normal(scale=0.3, size=V.shape),
            V,
            0.5 * (V[F[:, 0]] + V[F[:, 1]]),
        ]
    )
    whole = WindingGrid(V, F)
    ref = whole(P)
    assert 0 < (ref == 1).sum() < len(P) and set(np.unique(ref)) <= {0, 1}
    lazy = WindingGrid(V, F, lazy=True)
    assert len(lazy._bins[1]) == 0
    # batches along y: the binned cells move with every one
    for batch in np.array_split(np.argsort(P[:, 1], kind="stable"), 40):
        few = P[batch[:3]]
        assert np.array_equal(WindingGrid(V, F, lazy=True)(few), ref[batch[:3]])
        assert np.array_equal(lazy(P[batch]), ref[batch])
    lazy.bin_around(P)  # every cell: the whole grid's bins
    assert np.array_equal(lazy._bins[0], whole._bins[0])
    assert np.array_equal(lazy._bins[1], whole._bins[1])
    small = WindingGrid(V, F, lazy=True)
    small.bin_around(V[:5] + 0.01)
    assert 0 < len(small._bins[1]) < 0.05 * len(whole._bins[1])


def test_cubic_root():
    assert cubic_root_near(np.array([1.0, -3.0, 0.0, 1.0]), 0.0, 0.3) == pytest.approx(
        0.34729635533386, rel=1e-12
    )
    # Newton stalls at the guess (zero slope): all roots, two of them complex
    t = cubic_root_near(np.array([3.0, -3.0, 0.0, 1.0]), 0.0, 1.0)
    assert t**3 - 3 * t + 3 == pytest.approx(0.0, abs=1e-12) and t < -2
    # a quadratic (both roots equally near the guess), and a line
    assert abs(cubic_root_near(np.array([-4.0, 0.0, 1.0, 0.0]), 0.0, 0.0)) == pytest.approx(2.0)
    assert cubic_root_near(np.array([-4.0, 2.0, 0.0, 0.0]), 0.0, 5.0) == pytest.approx(2.0)
    assert np.isnan(cubic_root_near(np.array([1.0, 0.0, 0.0, 0.0]), 0.0, 0.0))
    assert np.isnan(cubic_root_near(np.array([1.0, np.inf, 0.0, 0.0]), 0.0, 0.0))


def test_real_roots_of_a_cubic_with_roots_orders_of_magnitude_apart():
    # closed forms (and a companion matrix) lose the small roots of such a cubic; the
    # bracketed search keeps all three to rounding
    from musclewrap.mesh._cubic import _real_roots

    roots = np.array([-2e-4, 1e-4, 1e6])
    p = np.poly(roots)[::-1]  # increasing degree
    assert np.sort(_real_roots(*p)) == pytest.approx(roots, rel=1e-10)
    # a double root where the cubic vanishes exactly: (t - 1)^2 (t - 3)
    assert np.sort(_real_roots(-3.0, 7.0, -5.0, 1.0)) == pytest.approx(
        [1.0, 3.0, np.nan], nan_ok=True
    )
    # one real root and a complex pair: t^3 + t + 10 = (t + 2)(t^2 - 2t + 5)
    r = _real_roots(10.0, 1.0, 0.0, 1.0)
    assert r[0] == pytest.approx(-2.0, rel=1e-14) and np.isnan(r[1:]).all()


def test_volume_hessian_reduced_matches_finite_differences():
    from musclewrap.mesh import volume_gradient, volume_hessian_reduced

    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    rng = np.random.default_rng(0)
    W = rng.random((len(V), 7))
    W /= W.sum(axis=1, keepdims=True)
    x = np.linalg.lstsq(W, V, rcond=None)[0]
    K = volume_hessian_reduced(W @ x, F, W)
    assert np.array_equal(K, K.T)
    w, e = rng.normal(size=x.shape), 1e-5
    fd = (W.T @ volume_gradient(W @ (x + e * w), F) - W.T @ volume_gradient(W @ (x - e * w), F)) / (
        2 * e
    )
    assert np.allclose(
        (K @ w.ravel()).reshape(x.shape), fd, rtol=1e-7, atol=1e-9 * np.abs(fd).max()
    )


def test_oriented_box_holds_every_point_and_only_points_near_it():
    from musclewrap.mesh import in_oriented_box, oriented_box

    rng = np.random.default_rng(3)
    # a long oblique cloud: its axis-aligned box is mostly empty, its own box is not
    t = rng.uniform(-1.0, 1.0, (2000, 1))
    P = t * [100.0, 80.0, 60.0] + rng.normal(scale=3.0, size=(2000, 3))
    R, lo, hi = oriented_box(P)
    assert np.allclose(R.T @ R, np.eye(3))
    assert np.array_equal(in_oriented_box(P, R, lo, hi), np.arange(len(P)))
    Q = rng.uniform(P.min(0), P.max(0), (5000, 3))
    rows = in_oriented_box(Q, R, lo, hi)
    X = Q @ R
    inside = np.flatnonzero(((X >= lo) & (X <= hi)).all(axis=1))
    assert np.array_equal(rows, inside)
    assert len(rows) < 0.2 * len(Q)  # most of the axis-aligned box is left out


def _flooded(W, A, seeds):
    """Brute force: the vertices with ``W > 0`` connected to a seed inside through others inside."""
    ip, ix = A
    seen, out, todo = set(), [], [int(s) for s in seeds if W[s] > 0]
    seen.update(todo)
    while todo:
        v = todo.pop()
        out.append(v)
        for u in ix[ip[v] : ip[v + 1]]:
            if W[u] > 0 and int(u) not in seen:
                seen.add(int(u))
                todo.append(int(u))
    return set(out)


@pytest.mark.parametrize("lazy", [False, True])
def test_winding_grid_flood_finds_a_region_inside_whole_from_one_vertex(lazy):
    """`WindingGrid.flood`: another mesh's vertices inside the surface, reached from seeds over
    that mesh's edges, are every vertex of each region inside that holds a seed, and none of a
    region inside that holds none (brute force: winding numbers of every vertex, then a search
    over the edges). The other mesh comes in its own frame with a rigid transform; a lazy grid
    binned round one seed only bins the rest as the flood reaches it."""
    from scipy.spatial.transform import Rotation

    from musclewrap.mesh import WindingGrid, vertex_adjacency, winding_numbers

    V, F = capsule(radius=10.0, length=80.0, n_around=24, cap_rings=5, segments=32)  # z 0..100
    # two rods across the capsule (along y, at z = 30 and 70, their ends out of it) in one
    # mesh, in a frame of its own: a region inside each
    R1, RF1 = capsule(radius=3.0, length=40.0, n_around=12, cap_rings=3, segments=40)
    R1 = (R1 - R1.mean(axis=0))[:, [0, 2, 1]]  # along y (a reflection: the faces turned back)
    RF1 = np.ascontiguousarray(RF1[:, ::-1])
    B = np.vstack([R1 + [0.0, 0.0, 30.0], R1 + [0.0, 0.0, 70.0]])
    RF = np.vstack([RF1, RF1 + len(R1)])
    rot = Rotation.from_euler("z", 15.0, degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rot, [2.0, 1.0, 0.0]
    placed = B @ rot.T + T[:3, 3]
    Wn = winding_numbers(placed, V, F)
    assert 0 < (Wn > 0).sum() < len(B)
    A = vertex_adjacency(RF, len(B))
    adj = (A.indptr.astype(np.int64), A.indices.astype(np.int64))
    inside = np.flatnonzero(Wn > 0)
    assert inside[0] < len(R1) <= inside[-1]  # a region in each rod
    # one seed inside the first rod, a few outside: the second rod's region is not reached
    seeds = np.concatenate([inside[:1], np.flatnonzero(Wn == 0)[:5]])
    grid = WindingGrid(V, F, lazy=lazy)
    if lazy:
        grid.bin_around(placed[inside[:1]])
    got = grid.flood(B, adj, seeds, T)
    assert len(got) == len(set(got.tolist()))
    assert set(got.tolist()) == _flooded(Wn, adj, seeds) == set(inside[inside < len(R1)].tolist())
    assert got[0] == inside[0]
    # no seed inside: nothing
    assert len(grid.flood(B, adj, np.flatnonzero(Wn == 0)[:5], T)) == 0
    assert len(grid.flood(B, adj, np.zeros(0, dtype=np.int64), T)) == 0


def test_a_lazy_winding_grid_keeps_the_cells_it_binned():
    """Asked near one place, then another, then the first again, a lazy grid bins the union
    (each binning is a pass over every face) and counts as the whole grid does."""
    from musclewrap.mesh import WindingGrid

    V, F = capsule(radius=10.0, length=80.0, n_around=24, cap_rings=5, segments=32)
    whole = WindingGrid(V, F)
    lazy = WindingGrid(V, F, lazy=True)
    a, b = V[V[:, 2] < 20], V[V[:, 2] > 80]
    lazy(a + 0.1)
    first = lazy._region
    lazy(b + 0.1)
    i0, i1, j0, j1 = lazy._region
    assert i0 <= first[0] and first[1] <= i1 and j0 <= first[2] and first[3] <= j1
    kept = lazy._region
    P = np.vstack([a, b]) + 0.1
    assert np.array_equal(lazy(P), whole(P))
    assert lazy._region == kept  # nothing binned again
    lazy.bin_around(a[:1], margin=3)
    assert lazy._region == kept  # within the cells binned, even with a margin


def test_faces_given_twice_are_kept_once_the_way_their_neighbours_run():
    from musclewrap.mesh import drop_repeated_faces

    V, F = capsule(n_around=12, cap_rings=4, segments=5)
    # face 7 again reversed (after it), face 20 reversed *before* it, face 31 again as it is
    G = np.vstack([F[:20], F[20][::-1][None], F[20:], F[7][::-1][None], F[31][None]])
    assert check_mesh(V, G).nonmanifold_edges == 9
    kept, dropped = drop_repeated_faces(G)
    assert dropped == 3
    assert np.array_equal(kept, F)  # the outward copies, in their order
    assert drop_repeated_faces(F)[1] == 0


@pytest.mark.realdata
def test_a_models_bone_with_faces_given_twice_is_read_closed_and_its_side_right(data_dir):
    """Rajagopal 2016's generic femur gives 5 faces twice (3 reversed): read, each is kept
    once and the bone is a closed 2-manifold; the side of points around it agrees with
    the winding number (a run read a muscle vertex 18.7 mm outside it as that deep in)."""
    import igl

    from musclewrap.contact import Obstacle
    from musclewrap.run._read import _read_bone
    from musclewrap.scene._config import BoneSpec

    path = data_dir / "opensim" / "Geometry" / "r_femur.vtp"
    bone = BoneSpec("femur", path, "femur_r", "femur_r", scale=(1000.0, 1000.0, 1000.0))
    V, F, said, open_edges = _read_bone(bone, None)
    check = check_mesh(V, F)
    assert open_edges == 0 and check.nonmanifold_edges == 0 and len(F) == 260
    assert said == ["5 faces given twice (the same three vertices): kept once"]
    rng = np.random.default_rng(0)
    lo, hi = V.min(axis=0) - 20, V.max(axis=0) + 20
    Q = rng.uniform(lo, hi, (20000, 3))
    far = np.sqrt(igl.point_mesh_squared_distance(Q, V, F)[0]) > 1.0
    outside = igl.winding_number(V, F, Q) < 0.5
    ob = Obstacle(V, F)
    inside = np.zeros(len(Q), dtype=bool)
    idx, phi, _, _ = ob.query(Q, np.full(len(Q), np.inf))
    inside[idx[phi < 0]] = True
    assert not np.any(inside[far] & outside[far])
    assert np.any(~outside[far])  # the test saw the inside too
    # the file as it is: the reversed copies make points outside read as inside
    raw = read_mesh(path)[1]
    bad = Obstacle(V, raw)
    wrong = np.zeros(len(Q), dtype=bool)
    idx, phi, _, _ = bad.query(Q, np.full(len(Q), np.inf))
    wrong[idx[phi < 0]] = True
    assert np.any(wrong[far] & outside[far])
