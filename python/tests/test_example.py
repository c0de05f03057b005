"""examples/python/shadow_mask.py: its PNG decodes to the answers of the module for its points."""

import importlib.util
import os
import struct
import subprocess
import sys
import zlib

import numpy as np

import clusterbake
from conftest import SCENE

EXAMPLE = os.path.join(os.path.dirname(__file__), "..", "..", "examples", "python", "shadow_mask.py")


def read_grey_png(path):
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    at, idat, size = 8, b"", None
    while at < len(data):
        length, kind = struct.unpack_from(">I4s", data, at)
        body = data[at + 8 : at + 8 + length]
        assert struct.unpack_from(">I", data, at + 8 + length)[0] == zlib.crc32(kind + body) & 0xFFFFFFFF
        if kind == b"IHDR":
            size = struct.unpack_from(">II", body)
            assert body[8:10] == b"\x08\x00"  # 8-bit grey
        elif kind == b"IDAT":
            idat += body
        at += 12 + length
    width, height = size
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(height, width + 1)
    assert not rows[:, 0].any()  # filter 0 on every row
    return rows[:, 1:]


def test_example_writes_the_shadow_mask(tmp_path):
    env = dict(os.environ)
    r = subprocess.run([sys.executable, EXAMPLE, SCENE, str(tmp_path)], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    pixels = read_grey_png(tmp_path / "shadow_mask.png")
    spec = importlib.util.spec_from_file_location("shadow_mask", EXAMPLE)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    assert pixels.shape == (example.SIZE, example.SIZE)
    points = example.height_field(example.SIZE, example.EXTENT)
    shadowed = clusterbake.bake(SCENE).occluded(points, example.LIGHT).reshape(pixels.shape)
    assert np.array_equal(pixels == 60, shadowed) and np.array_equal(pixels == 225, ~shadowed)
    assert 0.02 < shadowed.mean() < 0.5  # shadows fall on the field, and most of it is lit
