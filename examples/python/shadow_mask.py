"""Bakes a scene and writes the shadow mask of a height field of points as a PNG.

    PYTHONPATH=build/python python3 examples/python/shadow_mask.py data/default_scene.glb OUTDIR

The points cover the default scene's middle, 24 x 24 metres, one per pixel, on gentle hills just above its
ground; each is asked whether the light sees it. Lit points are light grey, shadowed ones dark, so the
mask is the scene's shadows seen from above. Needs only numpy and the standard library (the PNG is
written with zlib).
"""

import os
import struct
import sys
import zlib

import numpy as np

import clusterbake

SIZE = 512  # pixels a side
EXTENT = 12.0  # metres from the centre to each edge
LIGHT = (-14.0, 6.0, 3.0)  # low in the west: long shadows of the blobs, fence posts and pillars


def height_field(size, extent):
    """(size * size, 3) points, row by row from the far (-z) edge, x growing along a row."""
    xs = np.linspace(-extent, extent, size)
    x, z = np.meshgrid(xs, xs)
    y = 0.02 + 0.08 * (1 + np.sin(x / 2.5) * np.cos(z / 3.5))  # hills under 17 cm: above the flat ground
    return np.stack([x, y, z], axis=-1).reshape(-1, 3)


def write_png(path, pixels):
    """An 8-bit grey PNG of a (height, width) uint8 array."""
    height, width = pixels.shape

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    rows = b"".join(b"\x00" + pixels[r].tobytes() for r in range(height))  # filter 0 on every row
    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(rows, 9)))
        f.write(chunk(b"IEND", b""))


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: shadow_mask.py SCENE OUTDIR")
    scene, outdir = sys.argv[1], sys.argv[2]
    os.makedirs(outdir, exist_ok=True)
    asset = clusterbake.bake(scene)
    points = height_field(SIZE, EXTENT)
    shadowed = asset.occluded(points, LIGHT).reshape(SIZE, SIZE)
    pixels = np.where(shadowed, 60, 225).astype(np.uint8)
    path = os.path.join(outdir, "shadow_mask.png")
    write_png(path, pixels)
    print(f"{path}: {SIZE} x {SIZE} points, {shadowed.mean():.1%} in shadow of the light at {LIGHT}")


if __name__ == "__main__":
    main()
