"""Closest points, distances and signed distances: against Open3D, the f64 oracle and
analytic answers; signs on a torus with a hole and reversed faces; shapes, dtypes and bad
input."""

import math

import numpy as np
import pytest

import strahl
from conftest import torus_mesh

o3d = pytest.importorskip("open3d")

EPS32 = float(np.finfo(np.float32).eps)


def open3d_scene(v, f):
    s = o3d.t.geometry.RaycastingScene()
    s.add_triangles(o3d.core.Tensor(np.asarray(v, np.float32)), o3d.core.Tensor(np.asarray(f, np.uint32)))
    return s


def points_around(n, half, seed, surface=None):
    """Points in a cube of half-size ``half``; with ``surface`` (vertices), a third of them
    within 1e-3 of a vertex and a third within 0.1 of one: on, near and far."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(-half, half, (n, 3))
    if surface is not None:
        k = n // 3
        at = surface[rng.integers(0, len(surface), 2 * k)].astype(np.float64)
        p[:k] = at[:k] + rng.normal(0, 1e-3, (k, 3))
        p[k : 2 * k] = at[k:] + rng.normal(0, 0.1, (k, 3))
    return p.astype(np.float32)


def f32_bound(p, extent):
    """The f32 error bound strahl states: 4 eps (|p|max + the scene's extent)."""
    return 4 * EPS32 * (np.abs(p).max(axis=-1) + extent)


@pytest.mark.parametrize("nu,nv", [(48, 24), (1000, 500)], ids=["torus-2k", "torus-1M"])
def test_distances_match_open3d_and_the_f64_oracle(nu, nv):
    v, f = torus_mesh(nu, nv)
    q = points_around(30000, 3.5, 1, surface=v)
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v, f)
    d = s.compute_distance(q)
    want = open3d_scene(v, f).compute_distance(o3d.core.Tensor(q)).numpy()
    extent = 2.8
    assert np.all(np.abs(d - want) <= f32_bound(q, extent) + 1e-6), np.abs(d - want).max()
    oracle = strahl.RaycastingScene(device="cpu", precision="f64")
    oracle.add_triangles(v, f)
    d64 = oracle.compute_distance(q.astype(np.float64))
    assert d64.dtype == np.float64
    assert np.all(np.abs(d - d64) <= f32_bound(q, extent)), np.abs(d - d64).max()


def test_closest_points_are_on_their_triangles():
    v, f = torus_mesh()
    q = points_around(5000, 3.5, 2, surface=v)
    s = strahl.RaycastingScene(device="cpu")
    g = s.add_triangles(v, f)
    r = s.compute_closest_points(q)
    assert set(r) == {"points", "geometry_ids", "primitive_ids", "primitive_uvs", "primitive_normals"}
    assert np.all(r["geometry_ids"] == g)
    tri = v[f[r["primitive_ids"]]].astype(np.float64)
    u, w = r["primitive_uvs"][:, 0:1], r["primitive_uvs"][:, 1:2]
    assert np.all(u >= 0) and np.all(w >= 0) and np.all(u + w <= 1 + 1e-6)
    on = (1 - u - w) * tri[:, 0] + u * tri[:, 1] + w * tri[:, 2]
    assert np.abs(on - r["points"]).max() < 1e-5
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(n - r["primitive_normals"]).max() < 1e-5
    # The point's distance is the query's, and Open3D's nearest point is as near.
    d = np.linalg.norm(r["points"] - q, axis=1)
    assert np.abs(d - s.compute_distance(q)).max() < 1e-5
    theirs = open3d_scene(v, f).compute_closest_points(o3d.core.Tensor(q))["points"].numpy()
    assert np.abs(np.linalg.norm(theirs - q, axis=1) - d).max() < 1e-5


def test_degenerate_and_sliver_triangles():
    rng = np.random.default_rng(3)
    a = rng.uniform(-1, 1, (300, 3))
    e = rng.normal(size=(300, 3))
    v = np.concatenate([a, a + e, a + 2 * e + 1e-6 * rng.normal(size=(300, 3)), a + 0.5 * e])
    k = np.arange(300)
    f = np.concatenate([
        np.stack([k, k + 300, k + 600], 1),  # slivers
        np.stack([k, k + 300, k + 900], 1),  # collinear
        np.stack([k, k, k], 1),  # points
    ])
    q = points_around(6000, 3.0, 4)
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v.astype(np.float32), f)
    oracle = strahl.RaycastingScene(device="cpu", precision="f64")
    oracle.add_triangles(v.astype(np.float32).astype(np.float64), f)
    d, d64 = s.compute_distance(q), oracle.compute_distance(q.astype(np.float64))
    assert np.all(np.isfinite(d))
    assert np.all(np.abs(d - d64) <= f32_bound(q, 6.0)), np.abs(d - d64).max()


def test_spheres_and_cylinders_are_exact():
    s = strahl.RaycastingScene(device="cpu", precision="f64")
    s.add_spheres(np.array([[0.0, 0.0, 0.0]]), 1.0)
    s.add_cylinders(np.array([[5.0, 0.0, 0.0]]), np.array([[5.0, 0.0, 4.0]]), 0.5)
    q = np.array([[0.0, 0.0, 3.0], [0.2, 0.0, 0.0], [5.0, 2.0, 2.0], [5.1, 0.0, 0.5], [5.0, 0.0, 6.0], [7.0, 0.0, -3.0]])
    want = np.array([2.0, -0.8, 1.5, -0.4, 2.0, math.hypot(1.5, 3.0)])
    assert np.abs(s.compute_signed_distance(q) - want).max() < 1e-12
    r = s.compute_closest_points(q)
    assert list(r["geometry_ids"]) == [0, 0, 1, 1, 1, 1]
    assert np.allclose(r["points"][[0, 2, 4]], [[0, 0, 1], [5, 0.5, 2], [5, 0, 4]])
    assert np.allclose(r["primitive_normals"][[0, 2, 3, 4]], [[0, 0, 1], [0, 1, 0], [1, 0, 0], [0, 0, 1]])


def torus_with_hole_and_flips(nu=200, nv=100, seed=5):
    """conftest's torus (inward-facing as it is made), a hole cut near (2.8, 0, 0) and 5 %
    of the remaining faces reversed."""
    v, f = torus_mesh(nu, nv)
    hole = np.array([2.8, 0.0, 0.0])
    near = (np.linalg.norm(v[f] - hole, axis=-1) < 0.5).any(axis=1)
    f = f[~near].copy()
    rng = np.random.default_rng(seed)
    flip = rng.random(len(f)) < 0.05
    f[flip] = f[flip][:, ::-1]
    return v, f, hole


def torus_inside(q, major=2.0, minor=0.8):
    """Signed distance to conftest's (true, smooth) torus about the y axis."""
    rho = np.hypot(q[:, 0], q[:, 2])
    return np.hypot(rho - major, q[:, 1]) - minor


def test_winding_signs_survive_a_hole_and_flipped_faces():
    v, f, hole = torus_with_hole_and_flips()
    rng = np.random.default_rng(6)
    q = np.concatenate([points_around(20000, 3.5, 7), points_around(20000, 3.5, 8, surface=v)])
    q = q[np.linalg.norm(q - hole, axis=1) > 1.0]
    truth = torus_inside(q)
    # Off the facets: the faceted torus lies within 5e-4 of the smooth one.
    q, truth = q[np.abs(truth) > 2e-3], truth[np.abs(truth) > 2e-3]
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v, f)
    winding = s.compute_signed_distance(q)
    parity = s.compute_signed_distance(q, sign="parity")
    rate = np.mean((winding < 0) == (truth < 0))
    parity_rate = np.mean((parity < 0) == (truth < 0))
    print(f"signs right away from the hole, {len(q)} points: winding {rate:.5f}, parity {parity_rate:.5f}")
    assert rate >= 0.999
    assert np.array_equal(np.abs(winding), np.abs(parity))
    # The closed torus: the winding sign is the analytic one.
    v, f = torus_mesh(200, 100)
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v, f)
    assert np.all((s.compute_signed_distance(q) < 0) == (truth < 0))
    del rng


def test_shapes_dtypes_and_layouts():
    v, f = torus_mesh()
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v, f)
    q = points_around(60, 3.0, 9).reshape(3, 4, 5, 3)
    d = s.compute_distance(q)
    assert d.shape == (3, 4, 5) and d.dtype == np.float32
    assert np.array_equal(s.compute_distance(q.astype(np.float64)), d)
    wide = np.zeros((3, 4, 5, 6), np.float32)
    wide[..., ::2] = q
    assert np.array_equal(s.compute_distance(wide[..., ::2]), d)
    r = s.compute_closest_points(q)
    assert r["points"].shape == (3, 4, 5, 3) and r["primitive_uvs"].shape == (3, 4, 5, 2)
    assert r["geometry_ids"].shape == (3, 4, 5) and r["geometry_ids"].dtype == np.uint32
    assert s.compute_signed_distance(q[0, 0, 0]).shape == ()
    oracle = strahl.RaycastingScene(device="cpu", precision="f64")
    oracle.add_triangles(v, f)
    assert oracle.compute_closest_points(q)["points"].dtype == np.float64


def test_bad_points_and_empty_scenes():
    v, f = torus_mesh()
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v, f)
    q = np.zeros((2, 3, 3), np.float32)
    q[1, 2, 0] = np.nan
    for call in (s.compute_distance, s.compute_signed_distance, s.compute_closest_points):
        with pytest.raises(ValueError, match=r"query_points\[1, 2\]: NaN or infinity"):
            call(q)
    with pytest.raises(ValueError, match=r"query_points: shape \(4, 2\): expected \(\.\.\., 3\)"):
        s.compute_distance(np.zeros((4, 2), np.float32))
    with pytest.raises(ValueError, match="dtype int64"):
        s.compute_distance(np.zeros((4, 3), np.int64))
    with pytest.raises(ValueError, match=r"sign='inside'"):
        s.compute_signed_distance(np.zeros((4, 3), np.float32), sign="inside")
    empty = strahl.RaycastingScene(device="cpu")
    p = np.zeros((2, 3), np.float32)
    assert np.all(np.isinf(empty.compute_distance(p)))
    r = empty.compute_closest_points(p)
    assert np.all(r["geometry_ids"] == strahl.INVALID_ID) and np.all(r["points"] == 0)


def test_the_gpu_answers_as_the_cpu():
    v, f = torus_mesh()
    q = points_around(6000, 3.5, 10, surface=v)
    cpu = strahl.RaycastingScene(device="cpu")
    gpu = strahl.RaycastingScene(device="gpu")
    for s in (cpu, gpu):
        s.add_triangles(v, f)
        s.add_spheres(np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]]), np.array([0.5, 0.3]))
        s.add_cylinders(np.array([[0.0, 2.0, 0.0]]), np.array([[0.0, 3.0, 0.5]]), 0.2)
    assert gpu.device.startswith("gpu"), gpu.device
    bound = f32_bound(q, 4.0)
    d_cpu, d_gpu = cpu.compute_distance(q), gpu.compute_distance(q)
    assert np.all(np.abs(d_cpu - d_gpu) <= bound), np.abs(d_cpu - d_gpu).max()
    r_cpu, r_gpu = cpu.compute_closest_points(q), gpu.compute_closest_points(q)
    same = (r_cpu["geometry_ids"] == r_gpu["geometry_ids"]) & (r_cpu["primitive_ids"] == r_gpu["primitive_ids"])
    # A different primitive only at a tie: at the same distance.
    assert np.all(same | (np.abs(d_cpu - d_gpu) <= bound))
    assert np.mean(same) > 0.999
    assert np.abs(r_cpu["points"] - r_gpu["points"])[same].max() < 1e-5
    s_cpu, s_gpu = cpu.compute_signed_distance(q), gpu.compute_signed_distance(q)
    assert np.array_equal(np.sign(s_cpu), np.sign(s_gpu))
    empty = strahl.RaycastingScene(device="gpu")
    assert np.all(np.isinf(empty.compute_distance(q[:3])))
