"""``strahl.render`` makes the image ``strahl render`` makes: the same pixels, Whitted and
path traced, on the CPU; on the GPU within the GPU-vs-CPU image tolerance."""

import struct
import subprocess
import zlib

import numpy as np
import pytest
from conftest import torus_mesh

import strahl


def read_png(path):
    """An 8-bit RGB or RGBA, non-interlaced PNG (what strahl writes) as (H, W, 3) uint8."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, (w, h, channels) = 8, b"", (0, 0, 0)
    while pos < len(data):
        (n,), kind = struct.unpack(">I", data[pos : pos + 4]), data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and colour in (2, 6) and interlace == 0
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * channels)
    out = np.zeros((h, w * channels), np.int32)
    for y in range(h):
        f, line = raw[y, 0], raw[y, 1:].astype(np.int32)
        prev = out[y - 1] if y else np.zeros_like(line)
        row = np.zeros_like(line)
        for x in range(len(line)):
            a = row[x - channels] if x >= channels else 0
            b = prev[x]
            c = prev[x - channels] if x >= channels else 0
            if f == 0:
                pred = 0
            elif f == 1:
                pred = a
            elif f == 2:
                pred = b
            elif f == 3:
                pred = (a + b) // 2
            else:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            row[x] = (line[x] + pred) & 0xFF
        out[y] = row
    return out.reshape(h, w, channels)[..., :3].astype(np.uint8)


def srgb8(linear):
    v = np.clip(linear, 0.0, 1.0)
    s = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    return (s * 255.0 + 0.5).astype(np.uint8)


@pytest.mark.parametrize("mode,spp", [("whitted", 1), ("path", 4)])
def test_render_equals_strahl_render(strahl_bin, repo, tmp_path, mode, spp):
    path = repo / "assets" / "scenes" / "seed.toml"
    png = tmp_path / "seed.png"
    subprocess.run(
        [strahl_bin, "render", str(path), "-o", str(png), "--backend", "cpu", "--width", "48", "--height", "36",
         "--mode", mode, "--spp", str(spp), "--seed", "3"],
        check=True,
        capture_output=True,
    )
    scene = strahl.RaycastingScene.from_file(path)
    image, where = strahl.render(scene, mode=mode, spp=spp, width=48, height=36, backend="cpu", seed=3, info=True)
    assert image.shape == (36, 48, 3) and image.dtype == np.float32 and where.startswith("cpu")
    assert np.isfinite(image).all() and image.max() > 0.1
    # The same linear pixels, encoded as strahl encodes them (powf may differ by an ulp: at
    # most one code).
    diff = np.abs(srgb8(image).astype(int) - read_png(png).astype(int))
    assert diff.max() <= 1 and (diff > 0).mean() < 0.01, diff.max()


def test_gpu_render_agrees_with_cpu(repo):
    scene = strahl.RaycastingScene.from_file(repo / "assets" / "scenes" / "seed.toml")
    cpu = strahl.render(scene, width=40, height=30, backend="cpu")
    gpu, where = strahl.render(scene, width=40, height=30, backend="gpu", info=True)
    assert where.startswith("gpu"), where
    # tests/gpu_vs_cpu.rs's image criterion: nearly every pixel within 1e-3 (edges differ).
    close = np.abs(gpu - cpu).max(axis=-1) <= 1e-3
    assert close.mean() >= 0.99, close.mean()


def test_a_built_scene_renders_with_a_camera():
    v, t = torus_mesh()
    scene = strahl.RaycastingScene(device="cpu")
    scene.add_triangles(v, t)
    default = strahl.render(scene, width=32, height=24, backend="cpu")
    # Seen from above, the torus's hole is in the middle of the image, its body around it.
    above = strahl.render(scene, width=32, height=24, backend="cpu", eye=(0, 8, 0), look_at=(0, 0, 0),
                          up=(0, 0, 1), fov_y=40)
    background = above[0, 0]
    assert (np.abs(above[12, 16] - background) < 1e-6).all(), "the hole shows the background"
    assert np.abs(above[12, 16 + 7] - background).max() > 0.01, "the body is lit"
    assert np.abs(default - background).max(axis=-1).mean() > 0.05
    with pytest.raises(ValueError, match=r"mode=\"ambient\""):
        strahl.render(scene, mode="ambient")
    with pytest.raises(ValueError, match=r"width=0"):
        strahl.render(scene, width=0)
    with pytest.raises(ValueError, match=r"give eye and look_at together"):
        strahl.render(scene, eye=(0, 1, 0))


def test_denoise_brings_a_noisy_render_nearer_many_samples(repo):
    scene = strahl.RaycastingScene.from_file(repo / "assets" / "scenes" / "seed.toml")
    size = dict(mode="path", width=80, height=60)
    reference = strahl.render(scene, spp=256, backend="cpu", **size)
    raw = strahl.render(scene, spp=4, backend="cpu", **size)
    denoised = strahl.render(scene, spp=4, backend="cpu", denoise=True, **size)

    def error(image):
        return np.sqrt(np.mean((np.clip(image, 0, 1) - np.clip(reference, 0, 1)) ** 2))

    assert error(denoised) < error(raw) / 1.5, (error(denoised), error(raw))
    # The GPU denoises the GPU's image as the CPU does the CPU's (to rounding).
    gpu, where = strahl.render(scene, spp=4, backend="gpu", denoise=True, info=True, **size)
    assert where.startswith("gpu"), where
    diff = np.abs(srgb8(gpu).astype(int) - srgb8(denoised).astype(int)).max(axis=-1)
    assert (diff <= 2).mean() >= 0.98, (diff <= 2).mean()
    with pytest.raises(ValueError, match=r"denoise='yes'"):
        strahl.render(scene, denoise="yes")
