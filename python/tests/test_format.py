"""A reader written from docs/FORMAT.md alone, against assets the module bakes: the checksum, the writer's
layout, the mesh origins, the decoded boxes and cones, the source section."""

import math
import os
import struct

import numpy as np
import pytest

import clusterbake
from conftest import SCENE


M64 = 0xFFFFFFFFFFFFFFFF
A, B, C = 0x9E3779B97F4A7C15, 0xBF58476D1CE4E5B9, 0x94D049BB133111EB


def mix(x):
    x = ((x ^ (x >> 30)) * B) & M64
    x = ((x ^ (x >> 27)) * C) & M64
    return x ^ (x >> 31)


def checksum(stream):
    """The checksum of FORMAT.md over one stream of bytes."""
    lanes = [A, B, C, 0]
    padded = stream + bytes(-len(stream) % 32)
    for at in range(0, len(padded), 32):
        for j in range(4):
            x = (lanes[j] + int.from_bytes(padded[at + 8 * j : at + 8 * j + 8], "little") * B) & M64
            lanes[j] = ((((x << 31) | (x >> 33)) & M64) * A) & M64
    h = mix(len(stream))
    for j in range(4):
        h = (mix(h ^ lanes[j]) + j) & M64
    return mix(h)


def table(data):
    """[(type, element_size, offset, size, count)] in table order."""
    count = struct.unpack_from("<I", data, 20)[0]
    return [struct.unpack_from("<IIQQQ", data, 64 + 32 * i) for i in range(count)]


def section(data, kind, dtype):
    for t, _, offset, size, _ in table(data):
        if t == kind:
            return np.frombuffer(data, dtype, size // np.dtype(dtype).itemsize, offset)
    return None


MESH = np.dtype([(f, "<u4") for f in ("fv", "vc", "ft", "tc", "ff", "fc", "fcoarse", "cc", "fr", "rc")])
FINE = np.dtype([("ft", "<u4"), ("fv", "<u4"), ("fr", "<u4"), ("tc", "u1"), ("vc", "u1"), ("rc", "u1"), ("z", "u1")])
INSTANCE = np.dtype([("mesh", "<u4"), ("z1", "<u4"), ("z2", "<u8"), ("m", "<f8", 12)])
OBB = np.dtype([("c", "<f4", 3), ("h", "<f4", 3), ("r", "<i2", 3), ("largest", "<u2")])
CONE = np.dtype([("axis", "<i2", 2), ("front", "<f4"), ("back", "<f4"), ("cos", "<f4")])


@pytest.fixture(scope="module")
def scene_bytes():
    return clusterbake.bake(SCENE, bounds="all").to_bytes()


def test_checksum_and_layout(scene_bytes):
    data = scene_bytes
    assert data[:8] == b"CLBAKE\r\n" and struct.unpack_from("<III", data, 8) == (4, 0, 64)
    assert struct.unpack_from("<Q", data, 24)[0] == len(data) and len(data) % 16 == 0
    assert struct.unpack_from("<Q", data, 32)[0] == checksum(data[:32] + data[40:])
    assert data[40:64] == bytes(24)
    # The writer's layout: sections in table order, each at the next multiple of 16, zero gaps.
    at = 64 + 32 * len(table(data))
    for t, element, offset, size, count in table(data):
        assert size == element * count
        assert offset == (at + 15) // 16 * 16 and not any(data[at:offset])
        at = offset + size
    assert not any(data[at:])


def decode_obb(r):
    """The box axes (3 x 3, rows are axes) as docs/FORMAT.md decodes them."""
    d = 32767 * 1.4142135623730951
    q, s, k = [0.0] * 4, 0.0, 0
    for i in range(4):
        if i == r["largest"]:
            continue
        q[i] = float(r["r"][k]) / d
        s += q[i] * q[i]
        k += 1
    q[r["largest"]] = math.sqrt(1 - s) if s < 1 else 0.0
    length = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    x, y, z, w = (v / length for v in q)
    axes = [
        (1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)),
        (2 * (x * y - w * z), 1 - 2 * (x * x + z * z), 2 * (y * z + w * x)),
        (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)),
    ]
    return np.array(axes, dtype=np.float32).astype(np.float64)


def decode_axis(a):
    x, y = a[0] / 32767, a[1] / 32767
    z = 1 - abs(x) - abs(y)
    if z < 0:
        x, y = (1 - abs(y)) * (-1 if x < 0 else 1), (1 - abs(x)) * (-1 if y < 0 else 1)
    length = math.sqrt(x * x + y * y + z * z)
    return np.array([x / length, y / length, z / length])


def fine_cluster_triangles(data):
    """[(mesh index, fine cluster index, corners (t, 3, 3) float64 in the mesh's frame)]."""
    meshes = section(data, 1, MESH)
    positions = section(data, 2, "<f4").reshape(-1, 3).astype(np.float64)
    tris = section(data, 3, "u1").reshape(-1, 3)
    refs = section(data, 19, "<u2")
    fine = section(data, 4, FINE)
    out = []
    for mi, m in enumerate(meshes):
        for c in range(m["fc"]):
            f = fine[m["ff"] + c]
            assert f["z"] == 0
            vlist = [f["fv"] + i for i in range(f["vc"])]
            vlist += [f["fv"] - refs[m["fr"] + f["fr"] + i] for i in range(f["rc"])]
            local = tris[m["ft"] + f["ft"] : m["ft"] + f["ft"] + f["tc"]]
            corners = positions[m["fv"] + np.array(vlist)[local]]
            out.append((mi, m["ff"] + c, corners))
    return out


def test_boxes_and_cones_hold_their_clusters(scene_bytes):
    data = scene_bytes
    obbs = section(data, 7, OBB)
    cones = section(data, 13, CONE)
    spheres = section(data, 9, "<f4").reshape(-1, 4).astype(np.float64)
    checked_cones = 0
    for _, c, corners in fine_cluster_triangles(data):
        p = corners.reshape(-1, 3)
        box = obbs[c]
        axes = decode_obb(box)
        local = np.abs((p - box["c"].astype(np.float64)) @ axes.T)
        assert (local <= box["h"].astype(np.float64)).all()
        assert (np.linalg.norm(p - spheres[c, :3], axis=1) <= spheres[c, 3]).all()
        cone = cones[c]
        if cone["cos"] == 2:
            continue
        assert 0 < cone["cos"] <= 1
        a = decode_axis(cone["axis"])
        apex = np.array([np.float32(float(box["c"][k]) + float(cone["front"]) * a[k]) for k in range(3)], np.float64)
        axis = a.astype(np.float32).astype(np.float64)
        # A light just past the front apex along the axis sees every triangle with an area from the front.
        light = apex + axis * (1e-3 + np.abs(apex).max() * 1e-5)
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        facing = np.einsum("ij,ij->i", n, light - corners[:, 0])
        assert (facing[np.linalg.norm(n, axis=1) > 0] > 0).all()
        checked_cones += 1
    assert checked_cones > 1000


def test_mesh_origins_as_documented(tmp_path):
    # float32 arrays: stored + origin is the input exactly; the origin per axis as the float rule says.
    rng = np.random.default_rng(5)
    p32 = (rng.random((50, 3)) * [1, 2, 3] + [1000, -0.5, -4000]).astype(np.float32)
    idx = rng.integers(0, 50, (40, 3))
    data = clusterbake.bake((p32, idx)).to_bytes()
    inst = section(data, 6, INSTANCE)[0]
    origin = inst["m"][9:]
    lo, hi = p32.min(0).astype(np.float64), p32.max(0).astype(np.float64)
    side = (hi - lo).max()
    for k in range(3):
        c = float(np.float32(0.5 * (lo[k] + hi[k])))
        ok = (lo[k] > 0 and c / 2 <= lo[k] and hi[k] <= 2 * c) or (hi[k] < 0 and c / 2 >= hi[k] and lo[k] >= 2 * c)
        assert origin[k] == (c if ok and abs(c) > side else 0.0)
    assert origin[0] != 0 and origin[1] == 0 and origin[2] != 0
    stored = section(data, 2, "<f4").reshape(-1, 3).astype(np.float64)
    world = {tuple(v) for v in stored + origin}
    assert world <= {tuple(v) for v in p32.astype(np.float64)}
    # float64 arrays: the box centre rounded to a step of 2^(ilogb(side) - 8).
    p64 = p32.astype(np.float64) + 0.123456789
    data = clusterbake.bake((p64, idx)).to_bytes()
    origin = section(data, 6, INSTANCE)[0]["m"][9:]
    lo, hi = p64.min(0), p64.max(0)
    step = 2.0 ** (math.frexp((hi - lo).max())[1] - 1 - 8)
    assert list(origin) == [round(0.5 * (lo[k] + hi[k]) / step) * step for k in range(3)]
    stored = section(data, 2, "<f4").reshape(-1, 3)
    used = np.unique(idx)
    assert {tuple(v) for v in stored} <= {tuple(v) for v in (p64[used] - origin).astype(np.float32)}


def test_source_section_grammar(scene_bytes):
    text = bytes(section(scene_bytes, 20, "u1")).decode()
    lines = text.split("\n")
    assert lines[-1] == ""  # every line ends in \n
    assert lines[0] == f"clusterbake {clusterbake.__version__}, asset format 4, build {clusterbake.build_id}"
    words = lines[2].split(" ")
    assert words[:2] == ["input", "xxh3-128"] and len(words[2]) == 33 and words[2].endswith(",")
    assert int(words[3]) == os.path.getsize(SCENE) and words[4] == "bytes"
    assert lines[3:-1] == ["file " + os.path.basename(SCENE)]
