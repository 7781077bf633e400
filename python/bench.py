"""Benchmark of strahl's Python package against Open3D and Embree (embreex), in one process.

What it measures: ray-query throughput (million rays per second) on the anchors' 1M-triangle
bumpy torus, from a numpy rays array to numpy results (the conversions on both sides are
inside the timing, as a user sees them):

- ``cast_rays`` (nearest hit) for strahl on the CPU, strahl on the GPU, Open3D's
  ``o3d.t.geometry.RaycastingScene`` and embreex (Embree 4 via ``EmbreeScene.run``);
- ``count_intersections`` and ``list_intersections`` for strahl on the CPU and Open3D
  (embreex has neither);
- ``compute_distance`` and ``compute_signed_distance`` (points, not rays) for strahl on the
  CPU and Open3D: ``--points`` points, half uniform in the mesh's bounding box enlarged 1.2x
  about its centre, half within 1 % of its diagonal of a random vertex (on strahl's GPU the
  signed distances' winding numbers are summed on the CPU);

on four ray sets, all float32 (N, 6):

- ``camera``: the anchors' pinhole camera (``*_camera.json``: eye, look_at, up, horizontal
  fov), one ray through each pixel centre, coherent;
- ``random``: the anchors' random rays (``embree_bench.py``'s ``random_rays``, which ``strahl
  bench rays --rays random`` casts too): from points on a sphere of 1.5 times the box's
  diagonal around its centre to uniform points of the box, incoherent;
- ``inside``: origins uniform in the mesh's bounding box enlarged 1.5x about its centre,
  directions uniform on the sphere (fixed seed): incoherent, and most of them start inside
  the tree's root box and leave it without a hit;
- ``miss``: rays from outside the bounding box pointing away from it, so that almost no
  traversal happens: what is left is each library's per-ray cost of reading rays and
  writing results.

Every scene is built (and its acceleration structure committed, by a one-ray query) outside
the timing. Each measurement is one warm-up call, then ``--repeat`` timed calls; the
contenders take turns call by call, so that a CPU that speeds up or slows down during the
run (shared machines do) affects them alike. The table reports the best and the median
time; throughput is from the best. It also checks the answers while it is at it: how often
each contender agrees with Open3D on hit or miss, on the hit triangle, and on t.

Compare the ratios, not the absolute times: they depend on the machine, its cores and what
else runs on it. strahl uses every core (``RAYON_NUM_THREADS`` limits it), Open3D too
(``nthreads=0``), and embreex is driven from a thread pool of ``os.cpu_count()`` threads
(``run`` releases the GIL; one call uses one thread).

Run::

    pip install ./python open3d embreex          # open3d and embreex are optional
    python3 shared/anchors/embree_bench.py --export-obj /tmp/obj --tris 1000000
    python3 python/bench.py --obj /tmp/obj/bumpy_torus_1000000.obj [--csv bench.csv]

``--skip-gpu`` or ``--only strahl-cpu,open3d`` choose contenders. The GPU contender uses
``device="gpu"``: on a software Vulkan driver (lavapipe) that is a test device, not a GPU.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import sys
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Callable, Dict, List, Optional

import numpy as np

# Python puts this script's folder first on sys.path, and that folder holds strahl's source
# package (python/strahl) without its compiled extension: drop it, so that `import strahl`
# finds the installed package.
if sys.path and Path(sys.path[0] or ".").resolve() == Path(__file__).resolve().parent:
    del sys.path[0]
try:
    import strahl
except ImportError as e:
    sys.exit(f"bench.py: cannot import strahl ({e}); install it first: pip install ./python")

EXPORT_HINT = (
    "export it with: python3 shared/anchors/embree_bench.py --export-obj DIR --tris 1000000 "
    "(needs numpy and embreex), which writes DIR/bumpy_torus_1000000.obj and "
    "DIR/bumpy_torus_1000000_camera.json"
)
CONTENDERS = ("strahl-cpu", "strahl-gpu", "open3d", "embreex")
# OBJ statements that carry nothing this benchmark needs; anything else but v and f is an error.
OBJ_IGNORED = {"vt", "vn", "vp", "o", "g", "s", "usemtl", "mtllib"}


# --------------------------------------------------------------------------------------------
# OBJ reading

def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (N, 3) float32 and triangles (M, 3) int64 (0-based) of an OBJ file with
    ``v x y z`` and ``f a b c`` lines (1-based indices, ``a/t/n`` forms allowed). Raises
    ValueError naming the line of anything else. The fast path joins all v (f) lines and
    parses them at once; only when it sees a problem does it scan line by line to name it."""
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    v_lines = [l for l in lines if l.startswith("v ")]
    f_lines = [l for l in lines if l.startswith("f ")]
    others = [l for l in lines if not l.startswith(("v ", "f "))]
    for l in others:
        words = l.split(None, 1)
        if words and words[0] in ("v", "f"):
            # Indented or tab-separated statements: normalise every line (order matters: the
            # vertices' order defines the indices) and classify again.
            lines = [" ".join(l.split()) for l in lines]
            v_lines = [l for l in lines if l.startswith("v ")]
            f_lines = [l for l in lines if l.startswith("f ")]
            others = [l for l in lines if not l.startswith(("v ", "f "))]
            break
    for l in others:
        words = l.split(None, 1)
        if words and not words[0].startswith("#") and words[0] not in OBJ_IGNORED:
            _diagnose_obj(path, lines)
    try:
        vertices = _parse_rows(v_lines, "v", float).astype(np.float32)
        faces = _parse_rows(f_lines, "f", int)
    except ValueError:
        _diagnose_obj(path, lines)
        raise  # _diagnose_obj raises first; this only keeps the original error if it did not
    if not np.isfinite(vertices).all() or (len(faces) and (faces.min() < 1 or faces.max() > len(vertices))):
        _diagnose_obj(path, lines)
    if len(faces) == 0:
        raise ValueError(f"{path}: no triangles (no 'f a b c' lines)")
    return vertices, faces - 1


def _parse_rows(rows: List[str], keyword: str, number: type) -> np.ndarray:
    """Parses lines ``keyword n1 n2 n3`` into an (len(rows), 3) array, or raises ValueError.
    All tokens are split at once; when there are 4 per line and every 4th is the keyword, every
    line had exactly 3 numbers (a line with fewer or more would shift a keyword off the grid)."""
    tokens = " ".join(rows).split()
    if len(tokens) != 4 * len(rows) or tokens[0::4].count(keyword) != len(rows):
        raise ValueError("not 3 numbers per line")
    del tokens[0::4]
    if keyword == "f" and any("/" in t for t in tokens):
        tokens = [t.split("/", 1)[0] for t in tokens]  # a/t/n: keep the vertex index
    if number is float:
        values = np.fromiter(map(float, tokens), dtype=np.float64, count=len(tokens))
    else:
        # numpy's own text parser is ~3x faster than int(); it stops at the first token that is
        # not an integer (with a DeprecationWarning), which the count below catches.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            values = np.fromstring(" ".join(tokens), dtype=np.int64, sep=" ")
        if values.size != len(tokens):
            raise ValueError("not all indices are integers")
    return values.reshape(-1, 3)


def _diagnose_obj(path: Path, lines: List[str]) -> None:
    """Scans line by line and raises ValueError at the first malformed line."""
    nv = 0
    for no, line in enumerate(lines, 1):
        words = line.split()
        if not words or words[0].startswith("#") or words[0] in OBJ_IGNORED:
            continue
        where = f"{path}:{no}: {line.strip()[:80]!r}"
        if words[0] == "v":
            try:
                xyz = [float(w) for w in words[1:]]
            except ValueError:
                raise ValueError(f"{where}: a vertex coordinate is not a number") from None
            if len(xyz) != 3:
                raise ValueError(f"{where}: expected 'v x y z' (3 coordinates), got {len(xyz)}")
            if not all(np.isfinite(xyz)):
                raise ValueError(f"{where}: a vertex coordinate is not finite")
            nv += 1
        elif words[0] == "f":
            if len(words) != 4:
                raise ValueError(f"{where}: expected a triangle 'f a b c', got {len(words) - 1} vertices")
            try:
                idx = [int(w.split("/", 1)[0]) for w in words[1:]]
            except ValueError:
                raise ValueError(f"{where}: a vertex index is not an integer") from None
            for i in idx:
                if i < 1:
                    raise ValueError(f"{where}: vertex index {i}: only positive (1-based) indices are supported")
                if i > nv:
                    raise ValueError(f"{where}: vertex index {i}: only {nv} vertices are defined before this line")
        else:
            raise ValueError(f"{where}: unsupported statement {words[0]!r} (this reader takes v and f lines)")
    raise ValueError(f"{path}: malformed, but no single line could be blamed")


# --------------------------------------------------------------------------------------------
# Rays

def camera_rays(camera: dict, width: int, height: int) -> np.ndarray:
    """One ray per pixel centre of the anchors' camera, flat (W*H, 6) float32. Open3D's fov
    overload takes the horizontal fov, as the camera file gives it; directions are not
    normalised (camera-space z = 1), which changes no hit, only the units of t."""
    rays = strahl.RaycastingScene.create_rays_pinhole(
        camera["fov_x_deg"], camera["look_at"], camera["eye"], camera["up"], width, height)
    return rays.reshape(-1, 6)


def random_rays(n: int, vertices: np.ndarray, seed: int) -> np.ndarray:
    """The anchors' random rays (shared/anchors/embree_bench.py, random_rays): origins on the
    sphere of radius 1.5 |hi - lo| around the box's centre, aimed at uniform points of the box."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64)
    c = 0.5 * (lo + hi)
    rad = 1.5 * np.linalg.norm(hi - lo)
    d = rng.normal(size=(n, 3))
    org = c + rad * d / np.linalg.norm(d, axis=1, keepdims=True)
    dirs = lo + (hi - lo) * rng.random((n, 3)) - org
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    return np.concatenate([org, dirs], axis=1).astype(np.float32)


def inside_rays(n: int, vertices: np.ndarray, seed: int) -> np.ndarray:
    """Origins uniform in the box enlarged 1.5x, directions uniform on the sphere."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64)
    centre, half = 0.5 * (lo + hi), 0.75 * (hi - lo)  # the box enlarged 1.5x about its centre
    origins = centre + half * rng.uniform(-1.0, 1.0, (n, 3))
    d = rng.normal(size=(n, 3))  # an isotropic Gaussian, normalised: uniform on the sphere
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.concatenate([origins, d], axis=1).astype(np.float32)


def query_points(n: int, vertices: np.ndarray, seed: int) -> np.ndarray:
    """Half uniform in the bounding box enlarged 1.2x about its centre, half within 1 % of
    its diagonal of a random vertex: float32 (n, 3)."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64)
    c, h = (lo + hi) / 2, (hi - lo) / 2 * 1.2
    far = c + rng.uniform(-1, 1, (n - n // 2, 3)) * h
    near = vertices[rng.integers(0, len(vertices), n // 2)] + rng.normal(0, 0.01 * np.linalg.norm(hi - lo), (n // 2, 3))
    return np.concatenate([far, near]).astype(np.float32)


def miss_rays(n: int, vertices: np.ndarray, seed: int) -> np.ndarray:
    """Rays that start on a sphere around the bounding box and point outwards (at most 60
    degrees off the radial direction, so away from the centre): none can reach the mesh."""
    rng = np.random.default_rng(seed + 1)
    lo, hi = vertices.min(axis=0).astype(np.float64), vertices.max(axis=0).astype(np.float64)
    centre, radius = 0.5 * (lo + hi), 0.9 * np.linalg.norm(hi - lo)  # 1.8x the box's enclosing sphere
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    d = u + 0.5 * rng.uniform(-1.0, 1.0, (n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.concatenate([centre + radius * u, d], axis=1).astype(np.float32)


# --------------------------------------------------------------------------------------------
# Contenders: each builds its scene, then answers queries on numpy rays with numpy arrays.

class Contender:
    """A library under test. ``cast`` returns the library's own result; ``t_hit`` and
    ``prim`` read it in one convention (inf and -1 on a miss) for the agreement checks."""

    name: str
    device: str = ""
    build_s: float = 0.0

    def cast(self, rays: np.ndarray):
        raise NotImplementedError

    count: Optional[Callable] = None
    list: Optional[Callable] = None

    @staticmethod
    def t_hit(out) -> np.ndarray:
        return out["t_hit"]

    @staticmethod
    def prim(out) -> np.ndarray:
        return np.where(np.isfinite(out["t_hit"]), out["primitive_ids"].astype(np.int64), -1)


class Strahl(Contender):
    def __init__(self, device: str, V: np.ndarray, F: np.ndarray) -> None:
        self.name = f"strahl-{device}"
        t0 = time.perf_counter()
        self.scene = strahl.RaycastingScene(device=device)
        self.scene.add_triangles(V, F)
        self.scene.cast_rays(np.array([[0, 0, 0, 0, 0, 1]], np.float32))  # builds the BVH (and GPU pipeline)
        self.build_s = time.perf_counter() - t0
        self.device = self.scene.device
        self.count = self.scene.count_intersections
        self.list = self.scene.list_intersections
        self.distance = self.scene.compute_distance
        self.signed = self.scene.compute_signed_distance

    def cast(self, rays):
        return self.scene.cast_rays(rays)


class Open3D(Contender):
    name = "open3d"

    def __init__(self, V: np.ndarray, F: np.ndarray) -> None:
        import open3d as o3d  # optional: an ImportError here skips the contender

        t0 = time.perf_counter()
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(V.astype(np.float32), F.astype(np.uint32))
        self.scene.cast_rays(np.array([[0, 0, 0, 0, 0, 1]], np.float32))  # commits the Embree scene
        self.build_s = time.perf_counter() - t0
        self.device = f"Open3D {o3d.__version__}, CPU, nthreads=0 (all)"

    # .numpy() shares the tensors' memory: no copy, but the user has numpy arrays.
    def cast(self, rays):
        return {k: v.numpy() for k, v in self.scene.cast_rays(rays).items()}

    def count(self, rays):
        return self.scene.count_intersections(rays).numpy()

    def list(self, rays):
        return {k: v.numpy() for k, v in self.scene.list_intersections(rays).items()}

    def distance(self, points):
        return self.scene.compute_distance(points).numpy()

    def signed(self, points):
        return self.scene.compute_signed_distance(points).numpy()


class Embreex(Contender):
    name = "embreex"

    def __init__(self, V: np.ndarray, F: np.ndarray) -> None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        t0 = time.perf_counter()
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, np.ascontiguousarray(V[F], dtype=np.float32))  # (M, 3, 3) soup
        self.scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))  # commits
        self.build_s = time.perf_counter() - t0
        self.threads = os.cpu_count() or 1
        self.pool = ThreadPoolExecutor(self.threads)
        self.device = f"embreex (Embree 4), {self.threads} threads of run() calls"

    def cast(self, rays):
        # Contiguous origins and directions (numpy in), then one run() per thread's share;
        # the parts' dicts are joined into one (numpy out).
        org, dirs = np.ascontiguousarray(rays[:, :3]), np.ascontiguousarray(rays[:, 3:])
        step = -(-len(rays) // self.threads)
        parts = list(self.pool.map(lambda s: self.scene.run(org[s:s + step], dirs[s:s + step], output=1),
                                   range(0, len(rays), step)))
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}

    @staticmethod
    def t_hit(out):
        return np.where(out["geomID"] >= 0, out["tfar"], np.float32(np.inf))  # a miss has tfar 1e37

    @staticmethod
    def prim(out):
        return np.where(out["geomID"] >= 0, out["primID"].astype(np.int64), -1)


# --------------------------------------------------------------------------------------------
# Timing and checks

def timed(calls: Dict[str, Callable[[], object]], repeat: int) -> Dict[str, tuple]:
    """One warm-up call each, then ``repeat`` rounds in which every contender is timed once.
    Returns name -> (warm-up result, [times])."""
    results = {name: (f(), []) for name, f in calls.items()}
    for _ in range(repeat):
        for name, f in calls.items():
            t0 = time.perf_counter()
            f()
            results[name][1].append(time.perf_counter() - t0)
    return results


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Largest |a - b| / max(|b|, 1e-6 * median |b|) (t near 0, a ray starting at a surface,
    would otherwise make any rounding look huge); 0 for no pairs."""
    if a.size == 0:
        return 0.0
    a, b = a.astype(np.float64), b.astype(np.float64)
    floor = 1e-6 * float(np.median(np.abs(b))) or 1e-30
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), floor)))


def cast_agreement(c: Contender, out, ref: Contender, ref_out) -> str:
    t, tr = c.t_hit(out), ref.t_hit(ref_out)
    hit, hit_r = np.isfinite(t), np.isfinite(tr)
    both = hit & hit_r
    same_prim = np.mean(c.prim(out) == ref.prim(ref_out))
    return (f"hit/miss {100 * np.mean(hit == hit_r):.4f}%, triangle {100 * same_prim:.4f}%, "
            f"max rel |dt| {rel_diff(t[both], tr[both]):.2e} ({100 * np.mean(hit):.1f}% hit)")


def list_agreement(out, ref_out) -> str:
    splits, splits_r = out["ray_splits"].astype(np.int64), ref_out["ray_splits"].astype(np.int64)
    same = np.mean(np.diff(splits) == np.diff(splits_r))
    text = f"hits per ray {100 * same:.4f}%, {len(out['t_hit']):,} vs {len(ref_out['t_hit']):,} hits"
    if np.array_equal(splits, splits_r):
        # Open3D lists a ray's hits in traversal order, strahl sorted by t: compare them sorted.
        order = np.lexsort((out["t_hit"], out["ray_ids"]))
        order_r = np.lexsort((ref_out["t_hit"], ref_out["ray_ids"]))
        text += f", max rel |dt| {rel_diff(out['t_hit'][order], ref_out['t_hit'][order_r]):.2e}"
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--obj", type=Path, required=True, help="the bumpy torus OBJ; " + EXPORT_HINT)
    ap.add_argument("--camera", type=Path, help="camera JSON (default: the OBJ's name + _camera.json)")
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per measurement (default 3)")
    ap.add_argument("--rays", type=int, default=1_000_000, help="random (and miss) rays (default 1,000,000)")
    ap.add_argument("--width", type=int, default=1024, help="camera image width (default 1024)")
    ap.add_argument("--height", type=int, default=768, help="camera image height (default 768)")
    ap.add_argument("--query-rays", type=int, default=200_000,
                    help="rays of each set for count/list_intersections, the first N (default 200,000)")
    ap.add_argument("--points", type=int, default=200_000,
                    help="points of compute_distance and compute_signed_distance (default 200,000)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the random rays (default 1)")
    ap.add_argument("--skip-gpu", action="store_true", help="leave out strahl on device='gpu'")
    ap.add_argument("--only", help="comma-separated contenders among " + ", ".join(CONTENDERS))
    ap.add_argument("--csv", type=Path, help="also write the table as CSV")
    args = ap.parse_args()

    if not args.obj.is_file():
        ap.error(f"--obj {args.obj}: no such file; " + EXPORT_HINT)
    camera_path = args.camera or args.obj.with_name(args.obj.stem + "_camera.json")
    if not camera_path.is_file():
        ap.error(f"camera file {camera_path}: no such file (give --camera); " + EXPORT_HINT)
    wanted = set(CONTENDERS)
    if args.only:
        wanted = {w.strip() for w in args.only.split(",")}
        if wanted - set(CONTENDERS):
            ap.error(f"--only: unknown {', '.join(sorted(wanted - set(CONTENDERS)))}; choose among {', '.join(CONTENDERS)}")
    if args.skip_gpu:
        wanted.discard("strahl-gpu")
    if args.repeat < 1 or args.rays < 1 or args.query_rays < 1 or args.points < 1:
        ap.error("--repeat, --rays, --query-rays and --points must be positive")

    t0 = time.perf_counter()
    V, F = read_obj(args.obj)
    print(f"mesh: {args.obj} ({len(F):,} triangles, {len(V):,} vertices; read in {time.perf_counter() - t0:.2f} s)")
    camera = json.loads(camera_path.read_text())
    ray_sets = {
        "camera": camera_rays(camera, args.width, args.height),
        "random": random_rays(args.rays, V, args.seed),
        "inside": inside_rays(args.rays, V, args.seed),
        "miss": miss_rays(args.rays, V, args.seed),
    }
    print(f"rays: camera {args.width}x{args.height} = {len(ray_sets['camera']):,}, random {args.rays:,}, "
          f"inside {args.rays:,}, miss {args.rays:,}; float32 (N, 6)")
    print(f"machine: {os.cpu_count()} logical CPUs; strahl {strahl.__version__}, numpy {np.__version__}\n")

    contenders: List[Contender] = []
    makers = {
        "strahl-cpu": lambda: Strahl("cpu", V, F),
        "strahl-gpu": lambda: Strahl("gpu", V, F),
        "open3d": lambda: Open3D(V, F),
        "embreex": lambda: Embreex(V, F),
    }
    for name in CONTENDERS:
        if name not in wanted:
            continue
        try:
            c = makers[name]()
        except ImportError as e:
            print(f"{name}: skipped, not installed ({e})")
            continue
        except Exception as e:  # noqa: BLE001 (a missing GPU, a failed build: report, go on)
            print(f"{name}: skipped, {type(e).__name__}: {e}")
            continue
        print(f"{name}: scene built in {c.build_s:.2f} s (incl. acceleration structure); {c.device}")
        contenders.append(c)
    if not contenders:
        print("nothing to measure")
        return 1
    by_name = {c.name: c for c in contenders}
    ref = by_name.get("open3d") or contenders[0]  # the answers are checked against Open3D's
    print()

    rows, checks = [], []

    def record(query, set_name, n, results, note=""):
        for name, (_, times) in results.items():
            best = min(times)
            rows.append({"query": query, "rays": set_name, "n_rays": n, "contender": name,
                         "best_s": best, "median_s": statistics.median(times),
                         "mrays_per_s": n / best / 1e6, "note": note})

    for set_name, rays in ray_sets.items():
        # The GPU call is warmed up (pipeline compiled) by the one-ray build query already.
        res = timed({c.name: (lambda c=c: c.cast(rays)) for c in contenders}, args.repeat)
        record("cast_rays", set_name, len(rays), res)
        for c in contenders:
            if c is not ref:
                checks.append(f"cast_rays  {set_name:6s} {c.name:10s} vs {ref.name}: "
                              + cast_agreement(c, res[c.name][0], ref, res[ref.name][0]))

    queriers = [c for c in contenders if c.name in ("strahl-cpu", "open3d")]
    subset_note = ""
    for query in ("count_intersections", "list_intersections"):
        for set_name, rays in ray_sets.items():
            sub = rays[: args.query_rays]
            if len(sub) < len(rays):
                subset_note = f"the first {len(sub):,} rays of each set"
            res = timed({c.name: (lambda c=c: getattr(c, query.split("_")[0])(sub)) for c in queriers}, args.repeat)
            record(query, set_name, len(sub), res, subset_note if len(sub) < len(rays) else "")
            if "strahl-cpu" in res and "open3d" in res:
                s, o = res["strahl-cpu"][0], res["open3d"][0]
                if query == "count_intersections":
                    text = f"count equal {100 * np.mean(s == o):.4f}%, mean count {np.mean(o):.3f}"
                else:
                    text = list_agreement(s, o)
                checks.append(f"{query.split('_')[0]:10s} {set_name:6s} strahl-cpu vs open3d: {text}")

    points = query_points(args.points, V, args.seed)
    pointers = [c for c in contenders if hasattr(c, "distance")]
    for query, method in (("compute_distance", "distance"), ("compute_signed_distance", "signed")):
        res = timed({c.name: (lambda c=c: getattr(c, method)(points)) for c in pointers}, args.repeat)
        record(query, "points", len(points), res, "points, not rays")
        if "strahl-cpu" in res and "open3d" in res:
            s, o = res["strahl-cpu"][0], res["open3d"][0]
            text = f"max |difference| {np.abs(s - o).max():.3g}"
            if method == "signed":
                text += f", signs equal {100 * np.mean((s < 0) == (o < 0)):.4f}%"
            checks.append(f"{method:10s} points strahl-cpu vs open3d: {text}")

    # The table.
    print(f"throughput (M/s: million rays, or points, per second), best of {args.repeat} (after one warm-up call), numpy in -> numpy out:")
    header = f"{'query':24s} {'rays':7s} {'n':>9s}  {'contender':10s} {'best s':>8s} {'median s':>9s} {'M/s':>9s}"
    print(header)
    print("-" * len(header))
    last = None
    for r in rows:
        if last is not None and (r["query"], r["rays"]) != last:
            print()
        last = (r["query"], r["rays"])
        print(f"{r['query']:24s} {r['rays']:7s} {r['n_rays']:9,d}  {r['contender']:10s} "
              f"{r['best_s']:8.4f} {r['median_s']:9.4f} {r['mrays_per_s']:9.2f}")
    if subset_note:
        print(f"\ncount_intersections and list_intersections use {subset_note} (--query-rays).")

    # Ratios of throughputs: above 1 means the first is faster.
    speed = {(r["query"], r["rays"], r["contender"]): r["mrays_per_s"] for r in rows}
    print("\nratios of throughput (> 1: the first is faster):")
    pairs = [("strahl-cpu", "open3d"), ("strahl-cpu", "embreex"), ("strahl-gpu", "open3d"), ("strahl-gpu", "strahl-cpu")]
    for query in ("cast_rays", "count_intersections", "list_intersections", "compute_distance",
                  "compute_signed_distance"):
        for a, b in pairs:
            cells = [f"{s} {speed[(query, s, a)] / speed[(query, s, b)]:6.2f}"
                     for s in list(ray_sets) + ["points"] if (query, s, a) in speed and (query, s, b) in speed]
            if cells:
                print(f"  {query:24s} {a + ' / ' + b:25s} " + "   ".join(cells))

    slower = [s for s in ("camera", "random") if speed.get(("cast_rays", s, "strahl-cpu"), np.inf) < speed.get(("cast_rays", s, "open3d"), 0)]
    if slower:
        print(f"  -> strahl-cpu's cast_rays is slower than Open3D's on the {' and '.join(slower)} rays; the miss rays "
              "(almost no traversal) show how much of it is per-ray overhead")

    print("\nagreement (the warm-up calls' answers):")
    for line in checks:
        print("  " + line)

    if args.csv:
        with open(args.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
        print(f"\nwrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
