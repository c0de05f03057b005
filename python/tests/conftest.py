"""What the module's tests share: the command line they compare with, the shipped data, and a small
reader of the asset's section table (docs/FORMAT.md) for comparing assets section by section."""

import os
import struct
import subprocess

import numpy as np
import pytest

import clusterbake

DATA = os.environ.get("CLUSTERBAKE_DATA", os.path.join(os.path.dirname(__file__), "..", "..", "data"))
SCENE = os.path.join(DATA, "default_scene.glb")


def cli_path():
    path = os.environ.get("CLUSTERBAKE_CLI")
    if not path or not os.path.exists(path):
        pytest.skip("CLUSTERBAKE_CLI is not set to the built clusterbake (ctest sets it)")
    return path


def run_cli(*args, check=True):
    """The command line's run: (exit code, stdout, stderr)."""
    r = subprocess.run([cli_path(), *map(str, args)], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"clusterbake {' '.join(map(str, args))} failed: {r.stderr}")
    return r.returncode, r.stdout, r.stderr


def sections(data):
    """{type: bytes} of every section of an asset's bytes, read as docs/FORMAT.md lays them out."""
    assert data[:8] == b"CLBAKE\r\n"
    count = struct.unpack_from("<I", data, 20)[0]
    out = {}
    for i in range(count):
        kind, size_of, offset, size, n = struct.unpack_from("<IIQQQ", data, 64 + 32 * i)
        assert size == n * size_of
        out[kind] = data[offset : offset + size]
    return out


SOURCE_SECTION = 20


@pytest.fixture(scope="session")
def scene_asset():
    """The default scene baked with the default options."""
    return clusterbake.bake(SCENE)


@pytest.fixture(scope="session")
def scene_asset_file(tmp_path_factory, scene_asset):
    path = tmp_path_factory.mktemp("asset") / "default_scene.cbk"
    scene_asset.save(path)
    return path


def scene_points(count, seed):
    """Points over the default scene: near the ground, among the objects and above them."""
    rng = np.random.default_rng(seed)
    pts = np.empty((count, 3))
    pts[:, 0] = rng.uniform(-12, 12, count)
    pts[:, 1] = rng.choice([0.02, 0.3, 1.0, 2.5], count) + rng.uniform(0, 0.1, count)
    pts[:, 2] = rng.uniform(-12, 12, count)
    return pts


def write_points(path, pts):
    """Text points for `clusterbake query`, every double written so that it reads back exactly."""
    with open(path, "w") as f:
        for p in pts:
            f.write(f"{p[0]!r} {p[1]!r} {p[2]!r}\n")
