"""Against Open3D's RaycastingScene (PyPI ``open3d``, CPU, on Embree) on the same meshes
and rays: the same hit or miss except at ties (a ray within a rounding error of an edge,
where either side may take it), ``t_hit`` equal within f32 rounding, ``list_intersections``
at least as complete as Open3D's and equal to a brute-force f64 intersection, and the
helpers (``create_rays_pinhole``, ``compute_occupancy``) identical."""

import numpy as np
import pytest
from conftest import random_rays, torus_mesh

import strahl

o3d = pytest.importorskip("open3d")

# Embree's t and strahl's each carry the f32 rounding of the ray's origin and of the hit point,
# some ulps of the coordinates (of magnitude 1 to 3 here), not of t: 2^-18 of max(t, 1) covers
# both with room (measured: at most 2^-19.1 apart), while a wrong distance (another surface, a
# scale error) is off by far more.
T_REL = 2.0**-18


def soup(n=1500, seed=3):
    """Random triangles in a unit box: crossing, overlapping, some slivers."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-1, 1, (n, 1, 3))
    verts = (centres + rng.normal(0, 0.15, (n, 3, 3))).reshape(-1, 3).astype(np.float32)
    return verts, np.arange(3 * n, dtype=np.uint32).reshape(-1, 3)


MESHES = {"torus": torus_mesh, "soup": soup}


def both(name):
    v, t = MESHES[name]()
    ours = strahl.RaycastingScene(device="cpu")
    theirs = o3d.t.geometry.RaycastingScene()
    assert ours.add_triangles(v, t) == theirs.add_triangles(v, t) == 0
    return v, t, ours, theirs


def o3d_np(d):
    return {k: v.numpy() for k, v in d.items()}


def moller_trumbore(v, t, rays):
    """Every ray against every triangle in f64 (Möller and Trumbore 1997): the barycentric
    (u, w), the distance in units of |d| and the determinant, each (rays, triangles)."""
    o, d = rays[:, None, :3].astype(np.float64), rays[:, None, 3:].astype(np.float64)
    v0, v1, v2 = (v[t[:, k]].astype(np.float64)[None] for k in range(3))
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(d, e2)
    det = (e1 * p).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = o - v0
        u = (s * p).sum(-1) / det
        q = np.cross(s, e1)
        w = (d * q).sum(-1) / det
        tt = (e2 * q).sum(-1) / det
    return u, w, tt, det


def ties(v, t, rays, eps=1e-5):
    """Rays that pass within ``eps`` (barycentric) of some triangle's edge: where two
    intersectors may rightly disagree on which triangle, or whether one, is hit."""
    u, w, tt, det = moller_trumbore(v, t, rays)
    with np.errstate(invalid="ignore"):
        b = np.stack([u, w, 1 - u - w], -1)
        near = (np.abs(b) < eps).any(-1) & (b > -eps).all(-1) & (tt > -1e-6)
    return near.any(1) | (np.abs(det) < 1e-12).any(1)


def brute_force(v, t, rays):
    """Every hit of each ray by testing every triangle: per ray the sorted list of (t in
    units of |d|, triangle)."""
    u, w, tt, _ = moller_trumbore(v, t, rays)
    with np.errstate(invalid="ignore"):
        hit = (u >= 0) & (w >= 0) & (u + w <= 1) & (tt >= 0) & np.isfinite(tt)
    return [sorted(zip(tt[i][hit[i]], np.nonzero(hit[i])[0])) for i in range(len(rays))]


@pytest.mark.parametrize("name", list(MESHES))
def test_cast_rays_matches_open3d(name):
    v, t, ours, theirs = both(name)
    rays = random_rays(20000, (-2.8, -1, -2.8) if name == "torus" else (-1, -1, -1),
                       (2.8, 1, 2.8) if name == "torus" else (1, 1, 1), seed=11, dtype=np.float32)
    a, b = ours.cast_rays(rays), o3d_np(theirs.cast_rays(o3d.core.Tensor(rays)))
    for k in b:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
    tie = ties(v, t, rays)
    hit_a, hit_b = a["t_hit"] < np.inf, b["t_hit"] < np.inf
    assert (hit_a == hit_b)[~tie].all(), np.nonzero((hit_a != hit_b) & ~tie)
    assert hit_a.sum() > len(rays) // 5
    same = hit_a & hit_b & ~tie
    # Where two triangles are hit at the same distance (overlapping soup triangles), either
    # is right: compare the distance; the triangle and its normal where the distances differ.
    with np.errstate(invalid="ignore"):
        close = np.abs(a["t_hit"] - b["t_hit"]) <= T_REL * np.maximum(b["t_hit"], 1)
    assert close[same].all()
    prim = same & (a["primitive_ids"] == b["primitive_ids"])
    assert prim.sum() >= 0.999 * same.sum()
    assert np.abs(a["primitive_normals"] - b["primitive_normals"])[prim].max() < 1e-5
    assert np.abs(a["primitive_uvs"] - b["primitive_uvs"])[prim].max() < 1e-3
    miss = ~hit_a
    assert (a["geometry_ids"][miss] == o3d.t.geometry.RaycastingScene.INVALID_ID).all()
    assert (a["primitive_uvs"][miss] == 0).all() and (a["primitive_normals"][miss] == 0).all()


def test_shapes_follow_the_rays():
    _, _, ours, theirs = both("torus")
    rays = random_rays(24, (-3, -1, -3), (3, 1, 3), seed=2, dtype=np.float32).reshape(2, 3, 4, 6)
    a, b = ours.cast_rays(rays), o3d_np(theirs.cast_rays(o3d.core.Tensor(rays)))
    assert {k: v.shape for k, v in a.items()} == {k: v.shape for k, v in b.items()}
    assert ours.count_intersections(rays).shape == (2, 3, 4) == ours.test_occlusions(rays).shape
    assert ours.count_intersections(rays).dtype == theirs.count_intersections(o3d.core.Tensor(rays)).numpy().dtype
    assert ours.test_occlusions(rays).dtype == theirs.test_occlusions(o3d.core.Tensor(rays)).numpy().dtype


@pytest.mark.parametrize("name", list(MESHES))
def test_every_hit_is_complete(name):
    v, t, ours, theirs = both(name)
    rays = random_rays(300, (-2.8, -1, -2.8) if name == "torus" else (-1, -1, -1),
                       (2.8, 1, 2.8) if name == "torus" else (1, 1, 1), seed=12, dtype=np.float32)
    a = ours.list_intersections(rays)
    b = o3d_np(theirs.list_intersections(o3d.core.Tensor(rays)))
    counts = ours.count_intersections(rays)
    theirs_counts = theirs.count_intersections(o3d.core.Tensor(rays)).numpy()
    tie = ties(v, t, rays)
    exact = brute_force(v, t, rays)
    total = 0
    for i in range(len(rays)):
        s = slice(a["ray_splits"][i], a["ray_splits"][i + 1])
        mine = list(zip(a["t_hit"][s], a["primitive_ids"][s]))
        assert counts[i] == len(mine)
        assert (np.diff(a["t_hit"][s]) >= 0).all(), "sorted by distance"
        if tie[i]:
            continue
        total += len(mine)
        # Open3D's hits (in Embree's traversal order) are a subset of strahl's...
        o = slice(b["ray_splits"][i], b["ray_splits"][i + 1])
        assert set(b["primitive_ids"][o]) <= {p for _, p in mine}, i
        assert theirs_counts[i] <= counts[i]
        # ...and strahl's are exactly those of the brute force, at its distances.
        want = exact[i]
        assert [p for _, p in mine] == [p for _, p in want] or sorted(p for _, p in mine) == sorted(p for _, p in want), i
        for (tm, _), (tw, _) in zip(sorted(mine), sorted(want)):
            assert abs(tm - tw) <= T_REL * max(tw, 1), (i, tm, tw)
    assert total > len(rays)


def test_occlusions_and_counts_match_open3d():
    v, t, ours, theirs = both("torus")
    rays = random_rays(5000, (-2.8, -1, -2.8), (2.8, 1, 2.8), seed=13, dtype=np.float32)
    tie = ties(v, t, rays)
    near = theirs.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    for tnear, tfar in [(0.0, np.inf), (0.0, 0.5), (0.3, 1.2)]:
        a = ours.test_occlusions(rays, tnear=tnear, tfar=tfar)
        b = theirs.test_occlusions(o3d.core.Tensor(rays), tnear=tnear, tfar=tfar).numpy()
        # Where the nearest hit lies within rounding of tfar, either answer is right.
        with np.errstate(invalid="ignore"):
            edge = np.abs(near - tfar) <= T_REL * np.maximum(near, 1)
        assert (a == b)[~tie & ~edge].all(), (tnear, tfar)
    a = ours.count_intersections(rays)
    b = theirs.count_intersections(o3d.core.Tensor(rays)).numpy()
    assert (a == b)[~tie].all() and a.max() >= 4


def test_occupancy_matches_open3d():
    v, t, ours, theirs = both("torus")
    rng = np.random.default_rng(4)
    points = rng.uniform((-3, -1, -3), (3, 1, 3), (4000, 3)).astype(np.float32)
    for nsamples in (1, 3):
        a = ours.compute_occupancy(points, nsamples=nsamples)
        b = theirs.compute_occupancy(o3d.core.Tensor(points), nsamples=nsamples).numpy()
        assert a.dtype == b.dtype and a.shape == b.shape
        # Occupancy agrees with the torus's own inside test, away from its surface.
        r = np.hypot(np.hypot(points[:, 0], points[:, 2]) - 2.0, points[:, 1])
        away = np.abs(r - 0.8) > 0.05
        assert (a == b)[away].all() and (a[away] == (r[away] < 0.8)).all()
        assert (a != b).sum() <= len(points) // 200


def test_pinhole_rays_are_open3d_s():
    Rc = o3d.t.geometry.RaycastingScene
    for w, h, fov, eye in [(8, 4, 60.0, (0, 0, 5)), (33, 17, 35.0, (1.5, -2.0, 4.0))]:
        a = strahl.RaycastingScene.create_rays_pinhole(fov, [0, 0, 0], list(eye), [0, 1, 0], w, h)
        b = Rc.create_rays_pinhole(fov_deg=fov, center=[0, 0, 0], eye=list(eye), up=[0, 1, 0], width_px=w, height_px=h)
        assert a.dtype == np.float32 and (a == b.numpy()).all()
    K = np.array([[500.0, 0, 320], [0, 480, 240], [0, 0, 1]])
    E = np.eye(4)
    E[:3, :3] = o3d.geometry.get_rotation_matrix_from_xyz((0.1, -0.4, 0.2))
    E[:3, 3] = (0.3, -0.2, 2.0)
    a = strahl.RaycastingScene.create_rays_pinhole(K, E, 64, 48)
    b = Rc.create_rays_pinhole(o3d.core.Tensor(K), o3d.core.Tensor(E), 64, 48)
    assert (a == b.numpy()).all()


def test_open3d_meshes_are_accepted():
    legacy = o3d.geometry.TriangleMesh.create_box()
    ours = strahl.RaycastingScene(device="cpu")
    ours.add_triangles(legacy)
    ours.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(legacy))
    hits = ours.list_intersections(np.array([[0.5, 0.5, -1, 0, 0, 1]], np.float32))
    assert list(hits["geometry_ids"]) == [0, 1, 0, 1] and np.allclose(hits["t_hit"], [1, 1, 2, 2])
