"""A depth image from a pinhole camera: depth.npy, a 16-bit depth.png and depth_preview.png.

    python3 python/examples/depth.py [SCENE] [--eye X Y Z] [--look-at X Y Z] [--fov 56] [-o depth]

SCENE is any file strahl reads (default: assets/scenes/seed.toml, seen from its own camera).
The camera's rays come from ``RaycastingScene.create_rays_pinhole`` (Open3D's): their
directions have camera-space z = 1, so ``t_hit`` is the depth along the view axis itself (the
z-buffer value), not the distance along the ray. depth.png holds it in thousandths of a scene
unit (millimetres for metres, as depth cameras and Open3D store depth), 0 where nothing is
hit; the preview maps near to white and far to dark grey, misses black. The camera is in the
scene's coordinates (for a glTF file, strahl's: z mirrored, see docs/src/gltf.md). Needs only
numpy and strahl.
"""

import argparse, struct, sys, time, zlib
from pathlib import Path

import numpy as np
import strahl

SEED = Path(__file__).resolve().parents[2] / "assets" / "scenes" / "seed.toml"


def write_png(path: str, image: np.ndarray) -> None:
    """A greyscale PNG of a (H, W) uint8 or uint16 array: signature, IHDR, one zlib IDAT of
    rows each led by filter byte 0, IEND. PNG stores 16-bit samples big-endian."""
    h, w = image.shape
    rows = image.astype(">u2" if image.dtype == np.uint16 else np.uint8).reshape(h, -1).view(np.uint8)
    raw = np.hstack([np.zeros((h, 1), np.uint8), rows]).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", w, h, 8 * image.dtype.itemsize, 0, 0, 0, 0)  # depth, grey, ...
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", nargs="?", type=Path, default=SEED, help=f"default: {SEED}")
    # The defaults are seed.toml's camera; its vertical fov of 43.48 degrees is 56 horizontally.
    ap.add_argument("--eye", nargs=3, type=float, default=[0.0, 0.0, -10.0])
    ap.add_argument("--look-at", nargs=3, type=float, default=[0.0, 0.0, 0.0])
    ap.add_argument("--up", nargs=3, type=float, default=[0.0, 1.0, 0.0])
    ap.add_argument("--fov", type=float, default=56.0, help="horizontal field of view, degrees")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("-o", "--output", default="depth", help="prefix of the three files")
    args = ap.parse_args()

    scene = strahl.RaycastingScene.from_file(args.scene)
    rays = strahl.RaycastingScene.create_rays_pinhole(
        args.fov, args.look_at, args.eye, args.up, args.width, args.height)  # (H, W, 6)
    t0 = time.perf_counter()
    depth = scene.cast_rays(rays)["t_hit"]  # (H, W) float32, inf where nothing is hit
    seconds = time.perf_counter() - t0
    # Row 0 of Open3D's camera is the bottom of the view (its y is up): flip the rows for the
    # usual top row first. Its columns run along up x forward, which is the viewer's left in
    # Open3D's right-handed world but the right in strahl's scene space (left-handed: +x to
    # the right looking along +z), so the columns stay as they are: the image matches
    # strahl.render's from the same camera.
    depth = depth[::-1]
    hit = np.isfinite(depth)

    np.save(f"{args.output}.npy", depth)
    write_png(f"{args.output}.png", np.where(hit, np.clip(np.round(depth * 1000), 1, 65535), 0).astype(np.uint16))
    preview = np.zeros(depth.shape, np.uint8)
    if hit.any():
        near, far = depth[hit].min(), depth[hit].max()
        preview[hit] = np.round(255 - 215 * (depth[hit] - near) / max(far - near, 1e-12)).astype(np.uint8)
    write_png(f"{args.output}_preview.png", preview)

    print(f"scene: {args.scene}; device: {scene.device}")
    print(f"{args.width}x{args.height} rays in {seconds * 1e3:.0f} ms (with building the BVH); "
          f"{100 * hit.mean():.1f}% of the pixels hit")
    if hit.any():
        print(f"depth: min {depth[hit].min():.3f}, max {depth[hit].max():.3f}")
    print(f"wrote {args.output}.npy, {args.output}.png (16-bit, depth x 1000), {args.output}_preview.png")


if __name__ == "__main__":
    sys.exit(main())
