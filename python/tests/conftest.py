"""Shared fixtures for the Python package's tests.

Every skipped test is recorded in the file ``STRAHL_SKIP_LOG`` names (as the Rust tests
record theirs, tests/common), so that ``.ci/run``, which expects every test to run, fails on
it and names it.
"""

import os
import pathlib
import shutil

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


def pytest_runtest_logreport(report):
    if report.skipped and os.environ.get("STRAHL_SKIP_LOG"):
        why = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        with open(os.environ["STRAHL_SKIP_LOG"], "a") as log:
            log.write(f"SKIPPED python/tests {report.nodeid}: {why}\n")


@pytest.fixture(scope="session")
def strahl_bin():
    """The command line, built by cargo (STRAHL_BIN, else target/release/strahl)."""
    path = os.environ.get("STRAHL_BIN") or str(REPO / "target" / "release" / "strahl")
    if not os.access(path, os.X_OK):
        found = shutil.which("strahl")
        if not found:
            pytest.skip(f"no strahl command line at {path} (cargo build --release) or on the PATH")
        path = found
    return path


@pytest.fixture(scope="session")
def repo():
    return REPO


def random_rays(n, lo, hi, seed, dtype=np.float64):
    """``n`` rays from points in the box ``lo``-``hi`` enlarged by half towards points in the
    box itself, so that most of them cross the scene; directions of random lengths."""
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    o = c + rng.uniform(-1.5, 1.5, (n, 3)) * h
    target = c + rng.uniform(-1, 1, (n, 3)) * h
    d = (target - o) * rng.uniform(0.25, 4.0, (n, 1))
    return np.concatenate([o, d], axis=1).astype(dtype)


def torus_mesh(nu=48, nv=24, major=2.0, minor=0.8):
    """A closed torus: vertices (nu·nv, 3) float32 and triangles (2·nu·nv, 3) uint32."""
    u = np.arange(nu) * 2 * np.pi / nu
    v = np.arange(nv) * 2 * np.pi / nv
    uu, vv = np.meshgrid(u, v, indexing="ij")
    x = (major + minor * np.cos(vv)) * np.cos(uu)
    z = (major + minor * np.cos(vv)) * np.sin(uu)
    y = minor * np.sin(vv)
    verts = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return verts, tris.astype(np.uint32)
