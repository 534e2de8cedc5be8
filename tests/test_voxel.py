"""OccupancyGrid: voxelisation (surface + enclosed interior), point queries, ego-local sampling, files, errors."""
import numpy as np
import pytest

from model_runtime.errors import InputError
from model_runtime.voxel import OccupancyGrid

VOX = 0.05
EGO_BOUNDS = ((-0.6, 0.6), (-0.6, 0.6), (0.1, 1.2))
RES = 32

# Unit cube corners (index = 4x + 2y + z) and 12 outward-wound triangles.
CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])


def rot_x(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])


def box(lo, hi, rot=np.eye(3), centre=None):
    """Vertices, faces of an axis-aligned box [lo, hi], then rotated by `rot` about its centre."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = (lo + hi) / 2 if centre is None else np.asarray(centre, float)
    v = lo + CORNERS * (hi - lo)
    return (v - c) @ rot.T + c, BOX_FACES.copy()


def concat(*meshes):
    vs, fs, n = [], [], 0
    for v, f in meshes:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def box_margins(points, lo, hi, rot=np.eye(3)):
    """(inside depth, outside distance) of points w.r.t. a box rotated by `rot` about its centre."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c, half = (lo + hi) / 2, (hi - lo) / 2
    local = np.abs((np.asarray(points) - c) @ rot)      # rot.T applied to row vectors
    return (half - local).min(-1), np.linalg.norm(np.maximum(local - half, 0.0), axis=-1)


def grid_centres(g: OccupancyGrid) -> np.ndarray:
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in g.shape], indexing="ij"), -1)
    return g.origin + (idx + 0.5) * g.voxel_size


def ego_centres(bounds=EGO_BOUNDS, res=RES) -> np.ndarray:
    axes = [lo + (np.arange(res) + 0.5) * (hi - lo) / res for lo, hi in bounds]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1)


def ego_transform(yaw_deg: float = 0.0, position=(0.0, 0.0, 0.0)) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = rot_z(yaw_deg)
    m[:3, 3] = position
    return m


def icosphere(level: int, radius: float):
    t = (1 + 5 ** 0.5) / 2
    v = np.array([(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
                  (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)], float)
    f = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
                  (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
                  (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(level):
        a, b, c = f.T
        edges = np.sort(np.stack([np.stack([a, b], 1), np.stack([b, c], 1), np.stack([c, a], 1)], 1)
                        .reshape(-1, 2), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        mid = v[uniq[:, 0]] + v[uniq[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m = inv.reshape(-1, 3) + len(v)
        v = np.concatenate([v, mid])
        f = np.concatenate([np.stack([a, m[:, 0], m[:, 2]], 1), np.stack([b, m[:, 1], m[:, 0]], 1),
                            np.stack([c, m[:, 2], m[:, 1]], 1), m])
    return v * radius, f


def assert_matches_box(g, lo, hi, rot=np.eye(3)):
    """Cells deeper than a voxel inside are set; cells farther than a voxel outside are free."""
    inside, outside = box_margins(grid_centres(g), lo, hi, rot)
    assert g.occupancy[inside > g.voxel_size].all()
    assert not g.occupancy[outside > g.voxel_size].any()


# ---------------------------------------------------------------------- voxelisation
def test_unit_cube_is_solid_inside_and_free_outside():
    g = OccupancyGrid.from_triangles(CORNERS, BOX_FACES, voxel_size=VOX)
    assert g.num_triangles == 12 and g.occupancy.dtype == bool
    inside = [[0.5, 0.5, 0.5], [0.2, 0.8, 0.3], [0.9, 0.1, 0.95]]
    outside = [[-0.1, 0.5, 0.5], [1.1, 0.5, 0.5], [0.5, -0.1, 0.5], [0.5, 1.1, 0.5],
               [0.5, 0.5, -0.1], [0.5, 0.5, 1.1], [5.0, 5.0, 5.0], [-3.0, 0.5, 0.5]]
    assert g.occupied(inside).all()
    assert not g.occupied(outside).any()
    assert_matches_box(g, (0, 0, 0), (1, 1, 1))
    lo, hi = g.bounds
    assert np.all(lo <= -0.1 + 1e-9) and np.all(hi >= 1.1 - 1e-9)


def test_fill_interior_off_keeps_only_the_surface():
    g = OccupancyGrid.from_triangles(CORNERS, BOX_FACES, voxel_size=VOX, fill_interior=False)
    assert not g.occupied([0.5, 0.5, 0.5])
    x = np.linspace(-0.2, 1.2, 141)
    hit = x[g.occupied(np.stack([x, np.full_like(x, 0.52), np.full_like(x, 0.47)], -1))]
    near0, near1 = np.abs(hit) <= VOX, np.abs(hit - 1.0) <= VOX
    assert near0.any() and near1.any() and (near0 | near1).all()      # two thin walls, nothing between


def test_open_plane_stays_thin_and_does_not_fill_the_world():
    v = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    per_column = g.occupancy.sum(axis=2)
    assert per_column.max() <= 2                       # one layer, two where z=0 sits on a cell boundary
    assert (per_column > 0).sum() >= 40 * 40            # and no holes in it
    assert g.occupied([[0.3, -0.2, 0.0], [-0.99, 0.99, 0.0]]).all()
    assert not g.occupied([[0.3, -0.2, 0.1], [0.3, -0.2, -0.1]]).any()


def test_separate_meshes_concatenated_are_each_solid():
    floor = (np.array([[-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [2.0, 2.0, 0.0], [-2.0, 2.0, 0.0]]),
             np.array([[0, 1, 2], [0, 2, 3]]))
    table = box((-0.5, -0.5, 0.6), (0.5, 0.5, 0.8))
    crate = box((1.0, 1.0, 0.0), (1.6, 1.6, 0.6))
    v, f = concat(floor, table, crate)
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    assert g.num_triangles == 26
    assert g.occupied([[0.0, 0.0, 0.7], [1.3, 1.3, 0.3], [-1.5, 1.5, 0.0]]).all()
    # Under the table and above the floor is free: the floor is open, the space is not enclosed.
    assert not g.occupied([[0.0, 0.0, 0.3], [0.0, 0.0, 1.0], [-1.5, -1.5, 0.3]]).any()


def test_box_rotated_45_degrees():
    rot = rot_z(45.0)
    v, f = box((-0.5, -0.5, 0.0), (0.5, 0.5, 1.0), rot)
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    assert g.occupied([[0.65, 0.0, 0.5], [0.0, -0.65, 0.5]]).all()        # inside the diamond's tips
    assert not g.occupied([[0.45, 0.45, 0.5], [-0.45, 0.45, 0.5]]).any()   # the unrotated corners
    assert_matches_box(g, (-0.5, -0.5, 0.0), (0.5, 0.5, 1.0), rot)


def test_tilted_box_and_sheet_thinner_than_a_voxel_have_no_gaps():
    rot = rot_x(30.0) @ rot_z(20.0)
    v, f = box((0.0, 0.0, 0.0), (1.5, 0.7, 0.4), rot)
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    assert_matches_box(g, (0.0, 0.0, 0.0), (1.5, 0.7, 0.4), rot)
    # A 1 cm sheet, a fifth of a voxel thick and tilted, has no holes: every point of its mid-plane is in
    # a set voxel, or (where the surface only grazes a voxel) has one within a voxel along the normal.
    sheet_lo, sheet_hi = np.array([0.0, 0.0, 0.0]), np.array([1.5, 1.0, 0.01])
    v, f = box(sheet_lo, sheet_hi, rot)
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    uv = np.stack(np.meshgrid(np.linspace(0, 1.5, 121), np.linspace(0, 1.0, 81), [0.005], indexing="ij"), -1)
    c = (sheet_lo + sheet_hi) / 2
    mid = (uv.reshape(-1, 3) - c) @ rot.T + c
    assert g.occupied(mid).mean() > 0.99
    normal = rot[:, 2]
    along = mid[:, None] + np.linspace(-VOX, VOX, 9)[:, None] * normal
    assert g.occupied(along).any(axis=1).all()


def test_closed_sphere_is_filled_without_leaks():
    v, f = icosphere(3, 0.8)
    g = OccupancyGrid.from_triangles(v @ rot_x(17.0).T + [0.3, -0.2, 1.0], f, voxel_size=VOX)
    dist = np.linalg.norm(grid_centres(g) - [0.3, -0.2, 1.0], axis=-1)
    assert g.occupancy[dist < 0.8 * 0.98 - VOX].all()
    assert not g.occupancy[dist > 0.8 + VOX].any()


def test_occupied_keeps_leading_shape_and_treats_nan_as_free():
    g = OccupancyGrid.from_triangles(CORNERS, BOX_FACES, voxel_size=VOX)
    pts = np.full((2, 5, 3), 0.5)
    pts[1, 2] = np.nan
    out = g.occupied(pts)
    assert out.shape == (2, 5) and out.dtype == bool
    assert out.sum() == 9 and not out[1, 2]


# ---------------------------------------------------------------------- ego sampling
FRONT_BOX = ((-0.3, 0.3), (0.4, 1.6), (0.0, 0.9))   # ego-local: 1 m in front, its near face at y = 0.4


def world_box(yaw_deg, position, local=FRONT_BOX):
    """The world mesh of an ego-local box for an ego at (yaw, position)."""
    m = ego_transform(yaw_deg, position)
    lo, hi = np.array([b[0] for b in local]), np.array([b[1] for b in local])
    v, f = box(lo, hi)
    return v @ m[:3, :3].T + m[:3, 3], f


def assert_ego_matches(occ, local_box):
    """A sample point lies somewhere in a world cell, so allow one cell diagonal either way."""
    tol = np.sqrt(3.0) * VOX
    lo, hi = np.array([b[0] for b in local_box]), np.array([b[1] for b in local_box])
    inside, outside = box_margins(ego_centres(), lo, hi)
    assert occ.shape == (RES, RES, RES) and occ.dtype == np.float32
    assert set(np.unique(occ)) <= {0.0, 1.0}
    assert (occ[inside > tol] == 1.0).all() and (inside > tol).any()
    assert (occ[outside > tol] == 0.0).all()


@pytest.mark.parametrize("yaw, position", [(0.0, (0.0, 0.0, 0.0)), (90.0, (0.0, 0.0, 0.0)),
                                           (90.0, (5.0, -3.0, 0.0)), (-135.0, (-2.0, 7.5, 0.0))])
def test_sample_ego_sees_a_box_in_front_in_the_forward_half(yaw, position):
    v, f = world_box(yaw, position)
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    occ = g.sample_ego(ego_transform(yaw, position), bounds=EGO_BOUNDS, resolution=RES)
    assert occ[:, RES // 2:].sum() > 0                       # forward (+Y) half
    assert occ[:, :RES // 2].sum() == 0                      # nothing behind
    assert occ[:, :, -3:].sum() == 0                         # box top at 0.9 m: the top of the ego box is free
    assert_ego_matches(occ, FRONT_BOX)


def test_sample_ego_rotation_matters_box_behind_shows_in_back_half():
    v, f = world_box(0.0, (0.0, 0.0, 0.0))                   # box at world +Y
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    occ = g.sample_ego(ego_transform(180.0))                 # ego turned round: the box is behind
    assert occ[:, RES // 2:].sum() == 0 and occ[:, :RES // 2].sum() > 0
    behind = ((-0.3, 0.3), (-1.6, -0.4), (0.0, 0.9))
    assert_ego_matches(occ, behind)
    # Yaw 90: forward is world -X and right is world +Y, so the box lands in the +X (right) half.
    occ = g.sample_ego(ego_transform(90.0))
    assert occ[RES // 2:].sum() > 0 and occ[:RES // 2].sum() == 0
    assert_ego_matches(occ, ((0.4, 1.6), (-0.3, 0.3), (0.0, 0.9)))


def test_sample_ego_translation_and_bounds_and_tuple_resolution():
    v, f = world_box(0.0, (0.0, 0.0, 0.0))
    g = OccupancyGrid.from_triangles(v, f, voxel_size=VOX)
    assert g.sample_ego(ego_transform(0.0, (10.0, 0.0, 0.0))).sum() == 0      # walked away: nothing near
    occ = g.sample_ego(ego_transform(), bounds=((-1.0, 1.0), (0.0, 2.0), (0.0, 1.0)), resolution=(8, 16, 4))
    assert occ.shape == (8, 16, 4) and occ.dtype == np.float32
    assert occ[:, 4:].sum() > 0 and occ[:, :3].sum() == 0


def test_empty_grid_is_free_everywhere():
    g = OccupancyGrid.empty()
    occ = g.sample_ego(ego_transform(37.0, (1.0, 2.0, 0.0)))
    assert occ.shape == (RES, RES, RES) and occ.dtype == np.float32 and not occ.any()
    assert not g.occupied(np.random.default_rng(0).normal(size=(100, 3))).any()
    assert g.num_triangles == 0


# ---------------------------------------------------------------------- files
def test_save_load_round_trip(tmp_path):
    v, f = box((0.0, 0.0, 0.0), (0.6, 0.4, 0.5), rot_z(30.0))
    g = OccupancyGrid.from_triangles(v, f, voxel_size=0.04)
    path = tmp_path / "scene.grid"                           # no .npz suffix: written exactly here
    g.save(path)
    h = OccupancyGrid.load(path)
    assert np.array_equal(h.occupancy, g.occupancy) and np.array_equal(h.origin, g.origin)
    assert h.voxel_size == g.voxel_size and h.num_triangles == g.num_triangles
    m = ego_transform(20.0, (0.3, -0.7, 0.0))
    assert np.array_equal(h.sample_ego(m), g.sample_ego(m))
    e = tmp_path / "empty.npz"
    OccupancyGrid.empty().save(e)
    assert not OccupancyGrid.load(e).sample_ego(m).any()


def test_load_rejects_missing_and_foreign_files(tmp_path):
    with pytest.raises(InputError, match="no occupancy grid file"):
        OccupancyGrid.load(tmp_path / "nope.npz")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip at all")
    with pytest.raises(InputError, match="not an occupancy grid file"):
        OccupancyGrid.load(bad)
    other = tmp_path / "other.npz"
    np.savez(other, weights=np.zeros(3))
    with pytest.raises(InputError, match="missing"):
        OccupancyGrid.load(other)


# ---------------------------------------------------------------------- errors
@pytest.mark.parametrize("vertices, faces, kwargs, words", [
    (np.zeros((0, 3)), BOX_FACES, {}, "vertices is empty"),
    (np.zeros((8, 2)), BOX_FACES, {}, "vertices must be (N, 3)"),
    (CORNERS, np.zeros((0, 3), int), {}, "faces is empty"),
    (CORNERS, np.zeros((4, 4), int), {}, "faces must be (M, 3) integer indices into vertices, got shape (4, 4)"),
    (CORNERS, BOX_FACES[:, :2], {}, "faces must be (M, 3)"),
    (CORNERS, BOX_FACES + 0.5, {}, "integer indices"),
    (np.where(np.arange(8)[:, None] == 3, np.nan, CORNERS), BOX_FACES, {}, "NaN or infinite"),
    (np.where(np.arange(8)[:, None] == 5, np.inf, CORNERS), BOX_FACES, {}, "NaN or infinite"),
    (CORNERS, BOX_FACES + 1, {}, "faces index vertex 8 but there are 8 vertices"),
    (CORNERS, BOX_FACES - 1, {}, "faces index vertex -1"),
    (CORNERS, BOX_FACES, {"voxel_size": 0.0}, "voxel_size must be a positive number"),
    (CORNERS, BOX_FACES, {"padding": -1.0}, "padding must be"),
    (CORNERS * [40.0, 30.0, 10.0], BOX_FACES, {"padding": 0.0},
     "scene is 40 m x 30 m x 10 m; at voxel_size 0.05 that is 96,"),
    (CORNERS, BOX_FACES, {"max_cells": 1000}, "over the limit 1,000: raise voxel_size or pick fewer meshes"),
])
def test_bad_inputs_raise_one_line_input_errors(vertices, faces, kwargs, words):
    with pytest.raises(InputError) as info:
        OccupancyGrid.from_triangles(vertices, faces, **kwargs)
    assert isinstance(info.value, ValueError)
    msg = str(info.value)
    assert words in msg and "\n" not in msg


def test_quads_get_a_triangulate_hint():
    with pytest.raises(InputError, match="triangulate"):
        OccupancyGrid.from_triangles(CORNERS, np.zeros((6, 4), int))


def test_bad_query_arguments_raise():
    g = OccupancyGrid.from_triangles(CORNERS, BOX_FACES)
    with pytest.raises(InputError, match=r"\(4, 4\)"):
        g.sample_ego(np.eye(3))
    with pytest.raises(InputError, match="NaN"):
        g.sample_ego(np.full((4, 4), np.nan))
    with pytest.raises(InputError, match="bounds"):
        g.sample_ego(np.eye(4), bounds=((0.5, -0.5), (0, 1), (0, 1)))
    with pytest.raises(InputError, match="resolution"):
        g.sample_ego(np.eye(4), resolution=0)
    with pytest.raises(InputError, match=r"\(\.\.\., 3\)"):
        g.occupied(np.zeros((4, 2)))


@pytest.mark.parametrize("occupancy, words", [
    (np.full((2, 2, 2), "a"), "dtype <U1"),
    (np.full((2, 2, 2), "True"), "dtype <U4"),
    (np.full((2, 2, 2), None), "dtype object"),
    (np.full((2, 2, 2), np.nan), "NaN"),
])
def test_a_grid_of_strings_objects_or_nan_is_refused_in_one_line(occupancy, words):
    with pytest.raises(InputError) as info:
        OccupancyGrid((0.0, 0.0, 0.0), 0.1, occupancy)
    msg = str(info.value)
    assert words in msg and "booleans" in msg and "\n" not in msg


def test_a_grid_of_0_1_numbers_is_the_boolean_grid():
    occ = np.zeros((3, 3, 3), np.float32)
    occ[1, 1, 1] = 1.0
    assert np.array_equal(OccupancyGrid((0, 0, 0), 0.1, occ).occupancy, occ.astype(bool))


def test_sample_ego_upright_and_tilted_frames_match_point_queries():
    """Upright ego frames (turned about Z only) take a faster path; both paths give the occupancy of the world
    cell under each ego-local cell centre, as `occupied` does point by point."""
    rng = np.random.default_rng(3)
    occ = rng.random((40, 36, 24)) < 0.3
    g = OccupancyGrid((-1.0, -0.8, 0.0), 0.07, occ)
    bounds, res = ((-1.2, 1.2), (-0.6, 1.8), (0.1, 1.2)), (8, 12, 6)
    axes = [lo + (np.arange(r) + 0.5) * ((hi - lo) / r) for (lo, hi), r in zip(bounds, res)]
    local = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    for tilt in (0.0, 0.2):
        for _ in range(10):
            yaw = rng.uniform(-np.pi, np.pi)
            c, s = np.cos(yaw), np.sin(yaw)
            m = np.eye(4)
            m[:3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
                [[1.0, 0.0, 0.0], [0.0, np.cos(tilt), -np.sin(tilt)], [0.0, np.sin(tilt), np.cos(tilt)]])
            m[:3, 3] = (rng.uniform(-1.0, 2.0), rng.uniform(-1.0, 2.0), rng.uniform(0.0, 0.3))
            world = local @ m[:3, :3].T + m[:3, 3]
            assert np.array_equal(g.sample_ego(m, bounds=bounds, resolution=res), g.occupied(world).astype(np.float32))
