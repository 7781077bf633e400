"""A spinning LiDAR's scan of a glTF model, written as a point cloud (binary PLY).

    python3 python/examples/lidar.py [MODEL.glb] [--sensor X Y Z] [-o lidar.ply]

The sensor has 64 beams from -25 to +15 degrees elevation and takes 1024 azimuth steps per
turn (65,536 rays), about the y axis (glTF's up). Without --sensor it stands beside a glTF
model, at mid-height, in front of it (+z) by half the model's size, as its bounds say (from
the file's accessors). MODEL may be any file strahl reads (.glb, .gltf, .toml, .obj); the
default is the first glTF under assets/, or assets/scenes/seed.toml while the repository
ships none (then the sensor defaults to the origin). Needs numpy and strahl only.
"""

import argparse, json, struct, sys, time
from pathlib import Path

import numpy as np
import strahl

ASSETS = Path(__file__).resolve().parents[2] / "assets"


def gltf_bounds(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """World-space bounds of a glTF's meshes: each POSITION accessor's min/max corners (which
    the format requires) moved by its node's world matrix."""
    data = path.read_bytes()
    if data[:4] == b"glTF":  # .glb: a 12-byte header, then the JSON chunk (length, type, data)
        doc = json.loads(data[20:20 + struct.unpack_from("<I", data, 12)[0]])
    else:
        doc = json.loads(data)
    corners = []

    def visit(i: int, parent: np.ndarray) -> None:
        node = doc["nodes"][i]
        if "matrix" in node:
            m = np.array(node["matrix"], float).reshape(4, 4).T  # column-major in the file
        else:  # translation * rotation (a unit quaternion x, y, z, w) * scale
            x, y, z, w = node.get("rotation", [0, 0, 0, 1])
            m = np.eye(4)
            m[:3, :3] = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
            m[:3, :3] *= node.get("scale", [1, 1, 1])
            m[:3, 3] = node.get("translation", [0, 0, 0])
        world = parent @ m
        for prim in doc["meshes"][node["mesh"]]["primitives"] if "mesh" in node else []:
            acc = doc["accessors"][prim["attributes"]["POSITION"]]
            lo, hi = acc["min"], acc["max"]  # the 8 corners of the box, moved to world space
            box = np.array([[a, b, c, 1] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])])
            corners.append((box @ world.T)[:, :3])
        for child in node.get("children", []):
            visit(child, world)

    scene = doc.get("scenes", [{"nodes": range(len(doc.get("nodes", [])))}])[doc.get("scene", 0)]
    for i in scene["nodes"]:
        visit(i, np.eye(4))
    pts = np.concatenate(corners)
    return pts.min(axis=0), pts.max(axis=0)


def main() -> None:
    gltfs = sorted(p for p in ASSETS.rglob("*") if p.suffix.lower() in (".glb", ".gltf"))
    default = gltfs[0] if gltfs else ASSETS / "scenes" / "seed.toml"
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", nargs="?", type=Path, default=default, help=f"default: {default}")
    ap.add_argument("--sensor", nargs=3, type=float, metavar=("X", "Y", "Z"), help="sensor position")
    ap.add_argument("--beams", type=int, default=64)
    ap.add_argument("--steps", type=int, default=1024, help="azimuth steps per turn")
    ap.add_argument("-o", "--output", type=Path, default=Path("lidar.ply"))
    args = ap.parse_args()

    scene = strahl.RaycastingScene.from_file(args.model)
    is_gltf = args.model.suffix.lower() in (".glb", ".gltf")
    if args.sensor:
        sensor = np.array(args.sensor)
    elif is_gltf:
        lo, hi = gltf_bounds(args.model)
        sensor = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2] + 0.5 * np.max(hi - lo)])
    else:
        sensor = np.zeros(3)

    # One ray per (beam, azimuth step): unit directions, so t_hit is the range.
    el = np.deg2rad(np.linspace(-25.0, 15.0, args.beams))[:, None]
    az = np.linspace(0.0, 2 * np.pi, args.steps, endpoint=False)[None, :]
    dirs = np.stack(np.broadcast_arrays(np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)), axis=-1)
    rays = np.concatenate([np.broadcast_to(sensor, dirs.shape), dirs], axis=-1).astype(np.float32)

    # strahl reads a glTF file mirrored into its own left-handed space, z -> -z (docs/src/gltf.md,
    # "Handedness"): cast the mirrored rays, so that the points are in the file's coordinates.
    mirror = np.array([1, 1, -1] * 2 if is_gltf else [1] * 6, np.float32)
    t0 = time.perf_counter()
    scene.cast_rays(rays[:1, :1])  # the first query builds the BVH: time it apart from the scan
    t1 = time.perf_counter()
    hits = scene.cast_rays(rays * mirror)  # each output has the rays' leading shape (beams, steps)
    seconds = time.perf_counter() - t1
    t = hits["t_hit"]
    keep = np.isfinite(t)  # a miss has t_hit = inf
    origin, d = rays[keep][:, :3], rays[keep][:, 3:]
    points = origin + t[keep][:, None] * d
    # A stand-in for the return's intensity: the cosine of the angle of incidence (the
    # normal is the triangle's geometric one, on either side: hence the absolute value).
    intensity = np.abs(np.sum(hits["primitive_normals"][keep] * d * mirror[3:], axis=-1))
    ring = np.broadcast_to(np.arange(args.beams, dtype=np.uint16)[:, None], t.shape)[keep]

    # Binary PLY: a text header, then one packed little-endian record per point.
    record = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("ring", "<u2")])
    cloud = np.empty(len(points), record)
    cloud["x"], cloud["y"], cloud["z"] = points.T
    cloud["intensity"], cloud["ring"] = intensity, ring
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(cloud)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              "property float intensity\nproperty ushort ring\nend_header\n")
    with open(args.output, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(cloud.tobytes())

    print(f"model: {args.model}\nsensor at {np.round(sensor, 3).tolist()}, {args.beams} beams x {args.steps} steps = {t.size:,} rays")
    print(f"device: {scene.device}")
    print(f"BVH built in {(t1 - t0) * 1e3:.0f} ms; the scan's cast_rays took {seconds * 1e3:.1f} ms ({t.size / seconds / 1e6:.2f} Mrays/s)")
    print(f"{len(cloud):,} points ({100 * keep.mean():.1f}% of the rays hit), range {t[keep].min():.2f} to {t[keep].max():.2f}"
          if len(cloud) else "no ray hit anything: try --sensor")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    sys.exit(main())
