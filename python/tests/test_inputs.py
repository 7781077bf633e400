"""Every bad input raises ValueError naming what is wrong and where (the first bad row), and
changes nothing; good inputs in any float dtype and memory layout give the same answers."""

import threading

import numpy as np
import pytest
from conftest import random_rays, torus_mesh

import strahl

QUAD_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
QUAD_T = np.array([[0, 1, 2], [1, 3, 2]], np.uint32)
RAYS = np.array([[0.2, 0.3, 1, 0, 0, -2], [0.7, 0.6, 1, 0, 0, -1], [5, 5, 5, 0, 0, 1]], np.float32)


@pytest.fixture
def quad():
    s = strahl.RaycastingScene(device="cpu")
    assert s.add_triangles(QUAD_V, QUAD_T) == 0
    return s


def raises(match, f, *args, **kwargs):
    with pytest.raises(ValueError, match=match):
        f(*args, **kwargs)


def test_bad_rays_name_the_first_bad_row(quad):
    raises(r"rays: shape \(3, 5\): expected \(\.\.\., 6\)", quad.cast_rays, RAYS[:, :5])
    raises(r"rays: dtype int64: expected float32 or float64", quad.cast_rays, RAYS.astype(np.int64))
    raises(r"rays: dtype object", quad.cast_rays, RAYS.astype(object))
    raises(r"rays: dtype float16", quad.count_intersections, RAYS.astype(np.float16))
    grid = np.tile(RAYS[0], (2, 3, 1))
    for bad, what in [(np.nan, "NaN or infinity"), (np.inf, "NaN or infinity")]:
        g = grid.copy()
        g[1, 2, 4] = bad
        g[1, 1, 0] = bad  # the first bad row in C order is [1, 1]
        for query in (quad.cast_rays, quad.test_occlusions, quad.count_intersections, quad.list_intersections):
            raises(rf"rays\[1, 1\]: {what}", query, g)
    z = RAYS.copy()
    z[2, 3:] = 0
    raises(r"rays\[2\]: the direction \(dx, dy, dz\) is zero", quad.cast_rays, z)
    raises(r"tnear=2.0, tfar=1.0", quad.test_occlusions, RAYS, tnear=2.0, tfar=1.0)
    raises(r"tnear=NaN", quad.test_occlusions, RAYS, tnear=np.nan)


def test_bad_meshes_and_shapes(quad):
    raises(r"triangles\[1\]: vertex index 4 is out of range: there are 4 vertices",
           quad.add_triangles, QUAD_V, np.array([[0, 1, 2], [1, 4, 2]]))
    raises(r"triangles\[0\]: vertex index -1 is out of range", quad.add_triangles, QUAD_V, np.array([[0, -1, 2]]))
    raises(r"triangles\[0\]: vertex index 18446744073709551615 is out of range",
           quad.add_triangles, QUAD_V, np.array([[0, 2**64 - 1, 2]], np.uint64))
    raises(r"triangles: dtype float32: expected an integer dtype", quad.add_triangles, QUAD_V, QUAD_T.astype(np.float32))
    raises(r"triangles: shape \(2, 4\)", quad.add_triangles, QUAD_V, np.zeros((2, 4), np.uint32))
    raises(r"vertices: dtype int32", quad.add_triangles, QUAD_V.astype(np.int32), QUAD_T)
    v = QUAD_V.copy()
    v[3, 1] = np.nan
    raises(r"vertices\[3\]: NaN or infinity", quad.add_triangles, v, QUAD_T)
    raises(r"radii\[1\]: a radius must be finite and positive, got -1", quad.add_spheres, np.zeros((2, 3)), [1.0, -1.0])
    raises(r"radii: shape \(3,\): expected \(2,\)", quad.add_spheres, np.zeros((2, 3)), np.ones(3))
    raises(r"centers\[0\]: NaN", quad.add_spheres, np.full((1, 3), np.inf), 1.0)
    raises(r"p0\[1\] and p1\[1\]: the axis has zero length", quad.add_cylinders, np.zeros((2, 3)),
           np.array([[0, 0, 1.0], [0, 0, 0]]), 0.5)
    raises(r"nsamples=2: must be an odd integer", quad.compute_occupancy, np.zeros((1, 3), np.float32), nsamples=2)
    raises(r"query_points: shape \(4,\)", quad.compute_occupancy, np.zeros(4, np.float32))
    # Nothing was added by the failed calls: the next geometry is 1, and the answers are the quad's.
    assert quad.add_spheres(np.array([[0.0, 0.0, 10.0]]), 1.0) == 1
    assert list(quad.cast_rays(RAYS)["geometry_ids"][:2]) == [0, 0]


def test_bad_options():
    raises(r"device=\"tpu\": use \"auto\", \"gpu\" or \"cpu\"", strahl.RaycastingScene, device="tpu")
    raises(r"precision=\"f16\"", strahl.RaycastingScene, precision="f16")
    raises(r"precision=\"f64\" runs on the CPU", strahl.RaycastingScene, device="gpu", precision="f64")
    raises(r"fov_deg=0.0", strahl.RaycastingScene.create_rays_pinhole, 0.0, [0, 0, 0], [0, 0, 1], [0, 1, 0], 4, 4)
    raises(r"up must not be parallel", strahl.RaycastingScene.create_rays_pinhole, 60.0, [0, 0, 0], [0, 1, 0],
           [0, 1, 0], 4, 4)
    raises(r"width_px=0", strahl.RaycastingScene.create_rays_pinhole, np.eye(3), np.eye(4), 0, 4)
    raises(r"intrinsic_matrix: expected a 3x3", strahl.RaycastingScene.create_rays_pinhole, np.eye(4), np.eye(4), 4, 4)


def test_bad_files(tmp_path):
    with pytest.raises(OSError, match="nope.toml"):
        strahl.RaycastingScene.from_file(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\neye = [0, 0]\n")
    raises(r"bad.toml:\d+:\d+: camera", strahl.RaycastingScene.from_file, bad)
    obj = tmp_path / "bad.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nf 1 2 9\n")
    raises(r"bad.obj", strahl.RaycastingScene.from_file, obj)


def test_layouts_and_dtypes_give_the_same_answers(quad):
    want = quad.cast_rays(RAYS)
    wide = np.zeros((3, 12), np.float32)
    wide[:, ::2] = RAYS  # every other column: not contiguous
    for rays in (RAYS.astype(np.float64), np.asfortranarray(RAYS), wide[:, ::2], RAYS[::-1][::-1]):
        got = quad.cast_rays(rays)
        for k in want:
            assert (got[k] == want[k]).all(), k
    assert quad.cast_rays(np.zeros((0, 6), np.float32))["t_hit"].shape == (0,)
    assert quad.list_intersections(np.zeros((0, 6), np.float32))["ray_splits"].tolist() == [0]
    one = quad.cast_rays(RAYS[0])
    assert one["t_hit"].shape == () and one["t_hit"] == want["t_hit"][0]


def test_an_empty_scene_misses():
    s = strahl.RaycastingScene(device="cpu")
    out = s.cast_rays(RAYS)
    assert (out["t_hit"] == np.inf).all() and (out["geometry_ids"] == strahl.INVALID_ID).all()
    assert (s.count_intersections(RAYS) == 0).all() and not s.test_occlusions(RAYS).any()
    raises(r"rays\[0\]: NaN", s.cast_rays, np.full((1, 6), np.nan, np.float32))


def test_spheres_and_cylinders_answer_analytically():
    s = strahl.RaycastingScene(device="cpu", precision="f64")
    s.add_spheres(np.array([[0.0, 0, 0], [0, 0, 10]]), np.array([1.0, 2.0]))
    s.add_cylinders(np.array([[5.0, -1, 0]]), np.array([[5.0, 1, 0]]), 0.5)
    rays = np.array([[0, 0, -5, 0, 0, 2], [0, 0, 20, 0, 0, -1], [5, -3, 0, 0, 1, 0], [5, 0, -3, 0, 0, 1]], np.float64)
    out = s.cast_rays(rays)
    assert out["t_hit"].dtype == np.float64
    assert out["t_hit"].tolist() == [2.0, 8.0, 2.0, 2.5]
    assert out["geometry_ids"].tolist() == [0, 0, 1, 1] and out["primitive_ids"].tolist() == [0, 1, 0, 0]
    assert out["primitive_normals"].tolist() == [[0, 0, -1], [0, 0, 1], [0, -1, 0], [0, 0, -1]]
    every = s.list_intersections(rays)
    assert every["ray_splits"].tolist() == [0, 4, 8, 10, 12]
    assert every["t_hit"].tolist() == [2.0, 3.0, 6.5, 8.5, 8.0, 12.0, 19.0, 21.0, 2.0, 4.0, 2.5, 3.5]


def test_threads_share_a_scene():
    """Queries release the GIL and may run from several threads at once on one scene."""
    v, t = torus_mesh()
    s = strahl.RaycastingScene(device="cpu")
    s.add_triangles(v, t)
    rays = random_rays(20000, (-3, -1, -3), (3, 1, 3), seed=8, dtype=np.float32)
    want = s.cast_rays(rays)["t_hit"]
    results = [None] * 4

    def work(k):
        results[k] = s.cast_rays(rays)["t_hit"]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert all((r == want).all() for r in results)
