"""strahl for Python: ray queries and renders on numpy arrays, on any GPU or on the CPU.

``RaycastingScene`` follows Open3D's ``open3d.t.geometry.RaycastingScene`` in names, array
shapes, dtypes and miss values, so that code written for Open3D runs by changing the import::

    import numpy as np, strahl
    scene = strahl.RaycastingScene()
    scene.add_triangles(vertices, triangles)          # (N, 3) float32, (M, 3) uint32
    hits = scene.cast_rays(rays)                      # rays (..., 6): ox, oy, oz, dx, dy, dz

Beyond Open3D: spheres and cylinders, scene files (``RaycastingScene.from_file``), every hit
sorted by distance, the f64 oracle (``precision="f64"``) and ``strahl.render``.

Arrays are taken as numpy users pass them: float32 or float64, any memory layout (copied
when not contiguous). Nothing else is cast: an integer or object dtype, a wrong last
dimension, NaN or infinity in a ray, or a triangle index out of range raises ``ValueError``
naming the array and its first bad row. strahl releases the GIL while it works.
"""

from __future__ import annotations

import math
import os
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np

from . import _strahl

__all__ = ["RaycastingScene", "render", "INVALID_ID", "MAX_TRIANGLES", "__version__"]

#: The geometry and primitive id of a miss (Open3D's ``RaycastingScene.INVALID_ID``).
INVALID_ID: int = _strahl.INVALID_ID
#: Most primitives one scene holds.
MAX_TRIANGLES: int = _strahl.MAX_TRIANGLES
__version__: str = _strahl.__version__

_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


def _floats(name: str, a: Any, width: int) -> Tuple[np.ndarray, Tuple[int, ...]]:
    """``a`` as a flat contiguous float32/float64 array of rows of ``width``, and its leading
    shape. Raises ValueError for any other dtype or a last dimension other than ``width``."""
    arr = np.asarray(a)
    if arr.dtype not in _FLOATS:
        raise ValueError(f"{name}: dtype {arr.dtype}: expected float32 or float64 (strahl casts nothing else)")
    if arr.ndim == 0 or arr.shape[-1] != width:
        raise ValueError(f"{name}: shape {arr.shape}: expected (..., {width})")
    return np.ascontiguousarray(arr).reshape(-1), tuple(arr.shape[:-1])


def _rays(rays: Any) -> Tuple[np.ndarray, Tuple[int, ...]]:
    return _floats("rays", rays, 6)


def _per_row(name: str, a: Any, n: int) -> np.ndarray:
    """Radii: one per row (shape (n,)) or one for all (a scalar)."""
    arr = np.asarray(a)
    if arr.dtype not in _FLOATS:
        if arr.dtype.kind in "iu" and arr.ndim == 0:
            arr = np.asarray(float(arr))
        else:
            raise ValueError(f"{name}: dtype {arr.dtype}: expected float32 or float64 (strahl casts nothing else)")
    if arr.ndim == 0:
        arr = np.full(n, arr, dtype=arr.dtype)
    if arr.shape != (n,):
        raise ValueError(f"{name}: shape {arr.shape}: expected ({n},), one per row, or a scalar")
    return np.ascontiguousarray(arr)


def _shape(out: Dict[str, np.ndarray], lead: Tuple[int, ...], widths: Dict[str, int]) -> Dict[str, np.ndarray]:
    for key, w in widths.items():
        out[key] = out[key].reshape(lead + ((w,) if w > 1 else ()))
    return out


class RaycastingScene:
    """A scene for ray queries: triangle meshes, spheres and cylinders, or a scene file.

    ``device``: ``"auto"`` (a hardware GPU if there is one, else the CPU where it is faster,
    as on a software Vulkan driver), ``"gpu"`` (an error without one) or ``"cpu"``.
    ``precision``: ``"f32"`` (the GPU's arithmetic, and the CPU's mirror of it) or ``"f64"``
    (the CPU oracle; outputs are float64).

    Each ``add_*`` call returns a geometry id (0, 1, 2, ...); a hit reports it as
    ``geometry_ids`` and the triangle, sphere or cylinder within the call as
    ``primitive_ids``. The acceleration structure is built at the first query after a change.
    """

    INVALID_ID = INVALID_ID

    def __init__(self, device: str = "auto", precision: str = "f32") -> None:
        self._scene = _strahl.Scene(device, precision)

    @classmethod
    def from_file(cls, path: "os.PathLike[str] | str", device: str = "auto", precision: str = "f32") -> "RaycastingScene":
        """A scene read from strahl's TOML, a glTF file (``.gltf``, ``.glb``) or an OBJ mesh.
        A hit's geometry id is the object's index in the file (a glTF file's meshes as strahl
        lists them), its primitive id the triangle within it, as ``strahl trace`` reports."""
        self = cls.__new__(cls)
        self._scene = _strahl.Scene.from_file(os.fspath(path), device, precision)
        return self

    @property
    def device(self) -> str:
        """Where queries run, e.g. ``"cpu (lavapipe is a software rasteriser ...)"``."""
        return self._scene.device()

    def add_triangles(self, vertices: Any, triangles: Any = None) -> int:
        """Adds a triangle mesh: ``vertices`` (N, 3) float32 or float64, ``triangles`` (M, 3)
        of any integer dtype, indices into ``vertices``. Also takes an Open3D mesh (legacy
        ``TriangleMesh`` or ``t.geometry.TriangleMesh``) as the one argument. Returns the
        geometry id."""
        if triangles is None:
            vertices, triangles = _mesh_arrays(vertices)
        v, vlead = _floats("vertices", vertices, 3)
        t = np.asarray(triangles)
        if t.dtype.kind not in "iu":
            raise ValueError(f"triangles: dtype {t.dtype}: expected an integer dtype (strahl casts nothing else)")
        if t.ndim != 2 or t.shape[1] != 3:
            raise ValueError(f"triangles: shape {t.shape}: expected (M, 3)")
        if t.dtype == np.uint64 and t.size and int(t.max()) > np.iinfo(np.int64).max:
            k = int(np.argmax(t.max(axis=1) > np.iinfo(np.int64).max))
            raise ValueError(f"triangles[{k}]: vertex index {int(t[k].max())} is out of range: there are {len(v) // 3} vertices")
        t64 = np.ascontiguousarray(t, dtype=np.int64).reshape(-1)
        return self._scene.add_triangles(v, int(np.prod(vlead)), t64, t.shape[0])

    def add_spheres(self, centers: Any, radii: Any) -> int:
        """Adds spheres: ``centers`` (K, 3), ``radii`` (K,) or one for all. Returns the
        geometry id; primitive ids count the spheres from 0."""
        c, lead = _floats("centers", centers, 3)
        if len(lead) != 1:
            raise ValueError(f"centers: shape {np.shape(centers)}: expected (K, 3)")
        return self._scene.add_spheres(c, _per_row("radii", radii, lead[0]), lead[0])

    def add_cylinders(self, p0: Any, p1: Any, radii: Any) -> int:
        """Adds finite cylinders with end caps, axis ``p0[k]`` to ``p1[k]``: (K, 3) each,
        ``radii`` (K,) or one for all. Returns the geometry id."""
        a, lead = _floats("p0", p0, 3)
        b, lead1 = _floats("p1", p1, 3)
        if len(lead) != 1 or lead1 != lead:
            raise ValueError(f"p0, p1: shapes {np.shape(p0)}, {np.shape(p1)}: expected both (K, 3)")
        return self._scene.add_cylinders(a, b, _per_row("radii", radii, lead[0]), lead[0])

    def cast_rays(self, rays: Any, nthreads: int = 0) -> Dict[str, np.ndarray]:
        """The nearest hit of each ray (..., 6): ``t_hit`` (...) in units of the ray's
        direction, inf on a miss; ``geometry_ids``, ``primitive_ids`` (...) uint32,
        ``INVALID_ID`` on a miss; ``primitive_uvs`` (..., 2) the barycentric (u, v) of a
        triangle hit, p = (1-u-v)v0 + u v1 + v v2 (0 for spheres, cylinders and misses);
        ``primitive_normals`` (..., 3) the unit geometric normal: (v1-v0)x(v2-v0) for a
        triangle, outward for a sphere or cylinder, 0 on a miss. ``nthreads`` is accepted for
        Open3D's signature; strahl uses every core (``RAYON_NUM_THREADS`` limits it)."""
        flat, lead = _rays(rays)
        out = self._scene.cast_rays(flat, list(lead))
        return _shape(out, lead, {"t_hit": 1, "geometry_ids": 1, "primitive_ids": 1, "primitive_uvs": 2, "primitive_normals": 3})

    def test_occlusions(self, rays: Any, tnear: float = 0.0, tfar: float = math.inf, nthreads: int = 0) -> np.ndarray:
        """Whether each ray meets anything at tnear <= t <= tfar (units of its direction):
        a bool array of the rays' leading shape."""
        flat, lead = _rays(rays)
        return self._scene.test_occlusions(flat, list(lead), float(tnear), float(tfar)).reshape(lead)

    def count_intersections(self, rays: Any, nthreads: int = 0) -> np.ndarray:
        """How many times each ray meets the scene (t >= 0): an int32 array of the rays'
        leading shape. A ray through an edge or vertex shared by triangles counts it once."""
        flat, lead = _rays(rays)
        return self._scene.count_intersections(flat, list(lead)).view(np.int32).reshape(lead)

    def list_intersections(self, rays: Any, nthreads: int = 0) -> Dict[str, np.ndarray]:
        """Every hit of every ray (t >= 0), sorted by distance along each ray. The hits of
        ray ``i`` (flat index) are ``ray_splits[i]:ray_splits[i + 1]`` of ``ray_ids``,
        ``t_hit``, ``geometry_ids``, ``primitive_ids``, ``primitive_uvs`` (K, 2) and, beyond
        Open3D, ``primitive_normals`` (K, 3)."""
        flat, lead = _rays(rays)
        out = self._scene.list_intersections(flat, list(lead))
        out["primitive_uvs"] = out["primitive_uvs"].reshape(-1, 2)
        out["primitive_normals"] = out["primitive_normals"].reshape(-1, 3)
        return out

    def compute_occupancy(self, query_points: Any, nthreads: int = 0, nsamples: int = 1) -> np.ndarray:
        """1.0 where a point (..., 3) is inside the closed surfaces, else 0.0 (float32), by
        the parity of a ray's hits, voted over ``nsamples`` (odd) rays, as Open3D does it:
        the same directions, 1 + U(-0.001, 0.001) per component from mt19937(42)."""
        if not isinstance(nsamples, (int, np.integer)) or nsamples < 1 or nsamples % 2 != 1:
            raise ValueError(f"nsamples={nsamples!r}: must be an odd integer >= 1")
        q, lead = _floats("query_points", query_points, 3)
        q = q.reshape(-1, 3)
        dirs = _occupancy_directions(int(nsamples)).astype(q.dtype)
        rays = np.concatenate([np.repeat(q, nsamples, axis=0), np.tile(dirs, (len(q), 1))], axis=1)
        odd = (self.count_intersections(rays) % 2).reshape(-1, nsamples)
        inside = odd.sum(axis=1) > nsamples // 2
        return inside.astype(np.float32).reshape(lead)

    def compute_closest_points(self, query_points: Any, nthreads: int = 0) -> Dict[str, np.ndarray]:
        """The nearest surface point to each point (..., 3): ``points`` (..., 3);
        ``geometry_ids``, ``primitive_ids`` (...) uint32; ``primitive_uvs`` (..., 2), the
        barycentric (u, v) of the point on its triangle, p = (1-u-v)v0 + u v1 + v v2 (0 for
        spheres and cylinders); ``primitive_normals`` (..., 3), the triangle's unit normal
        (v1-v0)x(v2-v0), outward for a sphere or cylinder. On a scene without geometry the
        ids are ``INVALID_ID`` and the rest 0, as in Open3D."""
        q, lead = _floats("query_points", query_points, 3)
        out = self._scene.compute_closest_points(q, list(lead))
        return _shape(out, lead, {"points": 3, "geometry_ids": 1, "primitive_ids": 1, "primitive_uvs": 2, "primitive_normals": 3})

    def compute_distance(self, query_points: Any, nthreads: int = 0) -> np.ndarray:
        """The distance from each point (..., 3) to the nearest surface, of the points'
        leading shape (inf on a scene without geometry)."""
        q, lead = _floats("query_points", query_points, 3)
        return self._scene.compute_distance(q, list(lead), False).reshape(lead)

    def compute_signed_distance(self, query_points: Any, nthreads: int = 0, nsamples: int = 1, sign: str = "winding") -> np.ndarray:
        """The distance to the nearest surface, negative inside, of the points' leading shape.

        ``sign="winding"`` (the default) decides inside by the generalized winding number of
        the meshes (Jacobson et al. 2013), summed through the BVH with far-field
        approximations (Barill et al. 2018), after faces reversed against their neighbours
        are turned back: right where a mesh has a hole, flipped faces or self-intersections.
        Spheres and closed cylinders are inside by their own exact tests. ``sign="parity"``
        is Open3D's rule: the parity of a ray's hits, voted over ``nsamples`` (odd) rays, as
        ``compute_occupancy`` decides it; ``nsamples`` is used only there."""
        if sign not in ("winding", "parity"):
            raise ValueError(f"sign={sign!r}: use \"winding\" or \"parity\"")
        q, lead = _floats("query_points", query_points, 3)
        if sign == "winding":
            return self._scene.compute_distance(q, list(lead), True).reshape(lead)
        d = self._scene.compute_distance(q, list(lead), False).reshape(lead)
        inside = self.compute_occupancy(q.reshape(lead + (3,)), nsamples=nsamples) > 0
        return np.where(inside, -d, d).astype(d.dtype)

    @staticmethod
    def create_rays_pinhole(*args: Any, **kwargs: Any) -> np.ndarray:
        """Rays of a pinhole camera, (height_px, width_px, 6) float32, exactly as Open3D
        makes them; directions are not normalised (their camera-space z is 1). Either
        ``(intrinsic_matrix, extrinsic_matrix, width_px, height_px)``, with K 3x3 and the
        world-to-camera matrix 4x4, or ``(fov_deg, center, eye, up, width_px, height_px)``
        with the horizontal field of view in degrees (Open3D's camera: row 0 at the bottom,
        column 0 at the right of the view)."""
        names_k = ("intrinsic_matrix", "extrinsic_matrix", "width_px", "height_px")
        names_f = ("fov_deg", "center", "eye", "up", "width_px", "height_px")
        if "fov_deg" in kwargs or len(args) + len(kwargs) == 6:
            a = _bind(names_f, args, kwargs)
            return _pinhole_fov(*a)
        return _pinhole(*_bind(names_k, args, kwargs))


def _bind(names: Sequence[str], args: Sequence[Any], kwargs: Dict[str, Any]) -> list:
    if len(args) > len(names):
        raise ValueError(f"create_rays_pinhole takes {', '.join(names)}")
    values = list(args) + [None] * (len(names) - len(args))
    for k, v in kwargs.items():
        if k not in names:
            raise ValueError(f"create_rays_pinhole: unknown argument {k!r}; it takes {', '.join(names)}")
        values[names.index(k)] = v
    missing = [n for n, v in zip(names, values) if v is None]
    if missing:
        raise ValueError(f"create_rays_pinhole: missing {', '.join(missing)}")
    return values


def _size(name: str, v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= int(v) <= 65536:
        raise ValueError(f"{name}={v!r}: must be an integer in 1..65536")
    return int(v)


def _matrix(name: str, m: Any, shape: Tuple[int, int]) -> np.ndarray:
    a = np.asarray(m.numpy() if hasattr(m, "numpy") else m)
    if a.dtype.kind not in "fiu" or a.shape != shape:
        raise ValueError(f"{name}: expected a {shape[0]}x{shape[1]} numeric matrix, got dtype {a.dtype} shape {a.shape}")
    a = a.astype(np.float64)
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: NaN or infinity")
    return a


def _pinhole(intrinsic: Any, extrinsic: Any, width: Any, height: Any) -> np.ndarray:
    f32 = np.float32
    K = _matrix("intrinsic_matrix", intrinsic, (3, 3))
    E = _matrix("extrinsic_matrix", extrinsic, (4, 4))
    w, h = _size("width_px", width), _size("height_px", height)
    if abs(np.linalg.det(K)) == 0.0:
        raise ValueError("intrinsic_matrix is singular")
    R, t = E[:3, :3], E[:3, 3]
    # As Open3D: the centre and R^T K^-1 in f64, then every pixel's direction in f32, summed
    # in this order (a matrix product rounds differently, by an ulp).
    centre = (-R.T @ t).astype(f32)
    M = (R.T @ np.linalg.inv(K)).astype(f32)
    x, y = np.meshgrid(np.arange(w, dtype=f32) + f32(0.5), np.arange(h, dtype=f32) + f32(0.5))
    x, y = x[..., None], y[..., None]
    d = x * M[:, 0] + (y * M[:, 1] + M[:, 2])
    return np.concatenate([np.broadcast_to(centre, d.shape), d], axis=-1)


def _vector(name: str, v: Any) -> np.ndarray:
    a = np.asarray(v.numpy() if hasattr(v, "numpy") else v)
    if a.dtype.kind not in "fiu" or a.shape != (3,) or not np.isfinite(a.astype(np.float64)).all():
        raise ValueError(f"{name}: expected three finite numbers, got {v!r}")
    return a.astype(np.float64)


def _pinhole_fov(fov: Any, center: Any, eye: Any, up: Any, width: Any, height: Any) -> np.ndarray:
    fov = float(fov)
    if not 0.0 < fov < 180.0:
        raise ValueError(f"fov_deg={fov}: must be in (0, 180)")
    c, e, u = _vector("center", center), _vector("eye", eye), _vector("up", up)
    w, h = _size("width_px", width), _size("height_px", height)
    f = 0.5 * w / np.tan(0.5 * np.deg2rad(fov))
    K = np.array([[f, 0.0, 0.5 * w], [0.0, f, 0.5 * h], [0.0, 0.0, 1.0]])
    if np.linalg.norm(c - e) == 0.0 or np.linalg.norm(u) == 0.0:
        raise ValueError("center must differ from eye, and up must not be zero")
    z = (c - e) / np.linalg.norm(c - e)
    x = np.cross(u / np.linalg.norm(u), z)
    if np.linalg.norm(x) == 0.0:
        raise ValueError("up must not be parallel to the view direction (center - eye)")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    E = np.eye(4)
    E[:3, :3] = R
    E[:3, 3] = -R @ e
    return _pinhole(K, E, w, h)


def _mt19937(seed: int, n: int) -> list:
    """The first ``n`` outputs of the 32-bit Mersenne Twister (Matsumoto and Nishimura 1998)
    seeded as std::mt19937(seed) is."""
    mt = [0] * 624
    mt[0] = seed & 0xFFFFFFFF
    for i in range(1, 624):
        mt[i] = (1812433253 * (mt[i - 1] ^ (mt[i - 1] >> 30)) + i) & 0xFFFFFFFF
    out, idx = [], 624
    for _ in range(n):
        if idx >= 624:
            for i in range(624):
                y = (mt[i] & 0x80000000) | (mt[(i + 1) % 624] & 0x7FFFFFFF)
                mt[i] = mt[(i + 397) % 624] ^ (y >> 1) ^ (0x9908B0DF if y & 1 else 0)
            idx = 0
        y = mt[idx]
        idx += 1
        y ^= y >> 11
        y ^= (y << 7) & 0x9D2C5680
        y ^= (y << 15) & 0xEFC60000
        y ^= y >> 18
        out.append(y)
    return out


def _occupancy_directions(nsamples: int) -> np.ndarray:
    """Open3D's occupancy rays: direction j = 1 + U(-0.001, 0.001) per component, drawn in
    float32 from std::mt19937(42) by libstdc++'s uniform_real_distribution<float> (one 32-bit
    draw over 2^32, kept below 1), three per direction."""
    f32 = np.float32
    a, b = f32(-0.001), f32(0.001)
    values = []
    for u in _mt19937(42, 3 * nsamples):
        c = f32(u) / f32(4294967296.0)
        if c >= f32(1):
            c = np.nextafter(f32(1), f32(0))
        values.append(f32(1) + (c * (b - a) + a))
    return np.array(values, dtype=f32).reshape(nsamples, 3)


def _mesh_arrays(mesh: Any) -> Tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an Open3D mesh, legacy or tensor."""
    if hasattr(mesh, "vertex") and hasattr(mesh, "triangle"):
        return mesh.vertex.positions.numpy(), mesh.triangle.indices.numpy()
    if hasattr(mesh, "vertices") and hasattr(mesh, "triangles"):
        return np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    raise ValueError(f"add_triangles: expected (vertices, triangles) arrays or an Open3D mesh, got {type(mesh).__name__}")


def render(
    scene: RaycastingScene,
    mode: str = "whitted",
    spp: int = 1,
    width: Optional[int] = None,
    height: Optional[int] = None,
    backend: str = "auto",
    max_depth: Optional[int] = None,
    seed: int = 0,
    eye: Optional[Sequence[float]] = None,
    look_at: Optional[Sequence[float]] = None,
    up: Sequence[float] = (0.0, 1.0, 0.0),
    fov_y: float = 40.0,
    info: bool = False,
    denoise: bool = False,
) -> Any:
    """Renders ``scene``: an (height, width, 3) float32 image of linear radiance, row 0 at
    the top, as ``strahl render`` makes it. ``mode``: ``"whitted"`` or ``"path"``;
    ``backend``: ``"auto"``, ``"gpu"`` or ``"cpu"``. A scene file brings its camera, lights,
    materials and image size; a scene built by ``add_*`` is grey, lit by one directional
    light, and seen from strahl's default viewpoint over its bounds, unless ``eye`` and
    ``look_at`` (with ``up`` and ``fov_y``, the vertical field of view in degrees) are given.
    With ``info=True`` it returns ``(image, where)``, ``where`` naming the backend that
    rendered it (and, where ``auto`` chose, why). With ``denoise=True`` the image is denoised
    on that backend, as ``strahl render --denoise`` does."""
    if not isinstance(denoise, bool):
        raise ValueError(f"denoise={denoise!r}: must be True or False")
    pixels, where, w, h = _render(
        scene, mode, spp, width, height, backend, max_depth, seed, eye, look_at, up, fov_y, denoise
    )
    image = pixels.reshape(h, w, 3)
    return (image, where) if info else image


def _render(scene, mode, spp, width, height, backend, max_depth, seed, eye, look_at, up, fov_y, denoise=False):
    if not isinstance(scene, RaycastingScene):
        raise ValueError(f"render: expected a strahl.RaycastingScene, got {type(scene).__name__}")
    for name, v in (("spp", spp), ("seed", seed)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0 or v >= 2**32:
            raise ValueError(f"{name}={v!r}: must be a non-negative integer")
    camera = None
    if (eye is None) != (look_at is None):
        raise ValueError("render: give eye and look_at together")
    if eye is not None:
        camera = (tuple(map(float, eye)), tuple(map(float, look_at)), tuple(map(float, up)), float(fov_y))
    return scene._scene.render(mode, int(spp), width, height, max_depth, int(seed), backend, camera, denoise)
