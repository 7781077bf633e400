"""The package answers as ``strahl trace`` does on the same rays: bit for bit on the CPU, in
f32 (the GPU's mirror) and f64 (the oracle), for nearest hits and every hit, and within the
GPU-vs-CPU tolerance of tests/gpu_vs_cpu.rs on the GPU."""

import csv
import subprocess

import numpy as np
import pytest
from conftest import random_rays

import strahl

# Each scene with the half-size of a box around its objects that the rays are aimed into.
SCENES = {"seed.toml": 6.0, "lecture.toml": 6.0, "mesh.toml": 1.5, "cylinder.toml": 2.0}


def unit_length(d):
    """|d| as strahl computes it (query::unit_direction): scaled by the largest component."""
    m = np.abs(d).max(axis=1)
    s = d / m[:, None]
    return np.sqrt(s[:, 0] * s[:, 0] + s[:, 1] * s[:, 1] + s[:, 2] * s[:, 2]) * m


def run_trace(strahl_bin, scene, rays, tmp_path, *args):
    path = tmp_path / "rays.csv"
    with open(path, "w") as f:
        f.write("ox,oy,oz,dx,dy,dz\n")
        for r in rays:
            f.write(",".join(repr(float(x)) for x in r) + "\n")
    out = subprocess.run(
        [strahl_bin, "trace", str(scene), "--rays", str(path), "--backend", "cpu", *args],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return list(csv.DictReader(out.splitlines()))


@pytest.fixture(params=list(SCENES))
def scene_path(request, repo):
    return repo / "assets" / "scenes" / request.param


def scene_rays(path, n, seed, dtype=np.float64):
    h = SCENES[path.name]
    return random_rays(n, (-h, -h, -h), (h, h, h), seed, dtype)


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_nearest_equals_strahl_trace(strahl_bin, scene_path, precision, tmp_path):
    rays = scene_rays(scene_path, 1500, seed=5)
    rows = run_trace(strahl_bin, scene_path, rays, tmp_path, "--precision", precision)
    assert len(rows) == len(rays)
    scene = strahl.RaycastingScene.from_file(scene_path, device="cpu", precision=precision)
    got = scene.cast_rays(rays)
    real = np.float32 if precision == "f32" else np.float64
    length = unit_length(rays[:, 3:])
    hits = 0
    for i, row in enumerate(rows):
        assert int(row["ray"]) == i
        if row["object"] == "-1":
            assert got["t_hit"][i] == np.inf and got["geometry_ids"][i] == strahl.INVALID_ID, i
            assert got["primitive_ids"][i] == strahl.INVALID_ID and not got["primitive_normals"][i].any(), i
            continue
        hits += 1
        # The CLI prints the distance along the unit direction; the package divides it by |d|.
        t = real(np.float64(real(row["t"])) / length[i])
        assert got["t_hit"][i] == t, (i, row, got["t_hit"][i])
        assert got["geometry_ids"][i] == int(row["object"]) and got["primitive_ids"][i] == int(row["prim"]), i
        normal = np.array([real(row[k]) for k in ("nx", "ny", "nz")])
        assert (got["primitive_normals"][i] == normal).all(), (i, row, got["primitive_normals"][i])
    assert got["t_hit"].dtype == real and hits > len(rays) // 10, hits


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_every_hit_equals_strahl_trace_all(strahl_bin, scene_path, precision, tmp_path):
    rays = scene_rays(scene_path, 600, seed=6)
    rows = run_trace(strahl_bin, scene_path, rays, tmp_path, "--all", "--precision", precision)
    scene = strahl.RaycastingScene.from_file(scene_path, device="cpu", precision=precision)
    got = scene.list_intersections(rays)
    counts = scene.count_intersections(rays)
    real = np.float32 if precision == "f32" else np.float64
    length = unit_length(rays[:, 3:])
    assert len(got["t_hit"]) == len(rows) == got["ray_splits"][-1] == counts.sum()
    assert (np.diff(got["ray_splits"]) == counts).all()
    for k, row in enumerate(rows):
        i = int(row["ray"])
        assert got["ray_ids"][k] == i
        assert got["t_hit"][k] == real(np.float64(real(row["t"])) / length[i]), (k, row)
        assert got["geometry_ids"][k] == int(row["object"]) and got["primitive_ids"][k] == int(row["prim"])


def test_gpu_agrees_with_cpu(repo):
    """On the GPU (lavapipe here) the answers of the CPU within tests/gpu_vs_cpu.rs's
    tolerance: the same primitive, t within 1e-4 relative, the same normal, all but 0.1 % of
    the rays (those within a rounding error of an edge)."""
    for name in SCENES:
        path = repo / "assets" / "scenes" / name
        rays = scene_rays(path, 4000, seed=7, dtype=np.float32)
        cpu = strahl.RaycastingScene.from_file(path, device="cpu")
        gpu = strahl.RaycastingScene.from_file(path, device="gpu")
        assert gpu.device.startswith("gpu"), gpu.device
        want, got = cpu.cast_rays(rays), gpu.cast_rays(rays)
        same = (want["geometry_ids"] == got["geometry_ids"]) & (want["primitive_ids"] == got["primitive_ids"])
        hit = want["t_hit"] < np.inf
        with np.errstate(invalid="ignore"):
            close = np.where(hit, np.abs(want["t_hit"] - got["t_hit"]) <= 1e-4 * np.maximum(want["t_hit"], 1), True)
        normal = np.where(hit, (want["primitive_normals"] * got["primitive_normals"]).sum(-1) > 0.99999, True)
        bad = ~(same & close & normal)
        assert bad.sum() <= len(rays) // 1000, (name, bad.sum())
        assert hit.sum() > len(rays) // 10, (name, hit.sum())
        want_n, got_n = cpu.count_intersections(rays), gpu.count_intersections(rays)
        assert (want_n != got_n).sum() <= len(rays) // 1000, name
        occluded = gpu.test_occlusions(rays, tfar=2.0)
        assert (occluded != cpu.test_occlusions(rays, tfar=2.0)).sum() <= len(rays) // 1000, name
