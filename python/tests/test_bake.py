"""Bakes through the module against `clusterbake bake`: the same bytes, the same refusals."""

import os
import struct
import warnings

import numpy as np
import pytest

import clusterbake
from conftest import SCENE, SOURCE_SECTION, run_cli, sections


@pytest.mark.parametrize(
    "options, flags",
    [
        ({}, []),
        ({"fine": 8, "bounds": "all"}, ["--fine", "8", "--bounds", "all"]),
        ({"method": "vco", "cache": 16, "obb": "pca"}, ["--method", "vco", "--cache", "16", "--obb", "pca"]),
        ({"coarse_morton": True, "bounds": ["obb", "sphere"]}, ["--coarse-morton", "--bounds", "obb,sphere"]),
        ({"capsule_ratio": 1.5, "bounds": "capsule", "threads": 1}, ["--capsule-ratio", "1.5", "--bounds", "capsule"]),
    ],
)
def test_bake_equals_command_line(tmp_path, options, flags):
    out = tmp_path / "cli.cbk"
    run_cli("bake", SCENE, "-o", out, "-q", *flags)
    asset = clusterbake.bake(SCENE, **options)
    assert asset.to_bytes() == out.read_bytes()


def test_cluster_equals_command_line(tmp_path):
    out = tmp_path / "cli.cbk"
    run_cli("cluster", SCENE, "-o", out, "-q", "--fine", "12")
    assert clusterbake.cluster(SCENE, fine=12).to_bytes() == out.read_bytes()
    with pytest.raises(ValueError, match="--bounds is not a cluster option"):
        clusterbake.cluster(SCENE, bounds="all")


def test_save_open_and_facts(tmp_path, scene_asset):
    path = tmp_path / "a.cbk"
    scene_asset.save(path)
    assert path.read_bytes() == scene_asset.to_bytes()
    again = clusterbake.Asset.open(str(path))
    assert clusterbake.Asset.open(os.fsencode(path)).to_bytes() == scene_asset.to_bytes()
    assert again.to_bytes() == scene_asset.to_bytes()
    assert clusterbake.Asset.from_bytes(path.read_bytes()).info == scene_asset.info
    info = scene_asset.info
    assert info["format"] == clusterbake.asset_format == 4
    assert info["bytes"] == len(scene_asset.to_bytes())
    assert info["triangles"] == 33952 and info["instances"] == 12
    assert info["fine_bounds"] == ["obb", "cone"] and info["coarse_bounds"] == ["obb", "cone"]
    # The same facts `validate --json` prints.
    import json

    _, out, _ = run_cli("validate", path, "--json")
    printed = json.loads(out)
    for key, value in info.items():
        assert printed[key] == value, key
    lines = scene_asset.source.splitlines()
    assert lines == printed["source"]
    assert lines[0] == f"clusterbake {clusterbake.__version__}, asset format 4, build {clusterbake.build_id}"
    # One source tree, one build id: the command line's --version names the module's.
    _, version, _ = run_cli("--version")
    assert f"(asset format 4, build {clusterbake.build_id}, " in version
    assert len(clusterbake.build_id) == 16 and int(clusterbake.build_id, 16) >= 0
    assert lines[1].startswith("bake --method kmeans --coarse 2048 --fine 16")
    assert lines[3] == "file " + os.path.basename(SCENE)


def test_save_is_atomic_and_refuses(tmp_path, scene_asset):
    path = tmp_path / "a.cbk"
    path.write_bytes(b"old")
    scene_asset.save(path)
    assert path.read_bytes() == scene_asset.to_bytes()
    with pytest.raises(OSError):
        scene_asset.save(tmp_path / "no such folder" / "a.cbk")
    (tmp_path / "folder.cbk").mkdir()
    with pytest.raises(OSError):
        scene_asset.save(tmp_path / "folder.cbk")
    assert (tmp_path / "folder.cbk").is_dir()
    assert sorted(os.listdir(tmp_path)) == ["a.cbk", "folder.cbk"]  # no temporary left


def test_open_refuses_bad_files(tmp_path, scene_asset):
    with pytest.raises(OSError, match="cannot open"):
        clusterbake.Asset.open(tmp_path / "missing.cbk")
    data = bytearray(scene_asset.to_bytes())
    data[200] ^= 1
    bad = tmp_path / "bad.cbk"
    bad.write_bytes(bytes(data))
    _, _, err = run_cli("validate", bad, check=False)
    with pytest.raises(ValueError) as e:
        clusterbake.Asset.open(str(bad))
    assert str(e.value) == err.strip()
    with pytest.raises(ValueError):
        clusterbake.Asset.from_bytes(b"CLBAKE\r\n" + bytes(100))


def test_bad_scene_file(tmp_path):
    bad = tmp_path / "broken.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    _, _, err = run_cli("bake", bad, "-o", tmp_path / "x.cbk", check=False)
    with pytest.raises(ValueError) as e:
        clusterbake.bake(bad)
    assert str(e.value) == err.strip()
    with pytest.raises(OSError):
        clusterbake.bake(tmp_path / "missing.glb")


# Each option the command line refuses, refused with its line (without its "clusterbake: " prefix).
BAD_OPTIONS = [
    ({"fine": 0}, ["--fine", "0"]),
    ({"fine": 86}, ["--fine", "86"]),
    ({"fine": 16, "coarse": 8}, ["--fine", "16", "--coarse", "8"]),
    ({"k0": 1}, ["--k0", "1"]),
    ({"method": "vco", "cache": 2}, ["--method", "vco", "--cache", "2"]),
    ({"capsule_ratio": 0.5}, ["--capsule-ratio", "0.5"]),
    ({"method": "spectral"}, ["--method", "spectral"]),
    ({"bounds": "boxes"}, ["--bounds", "boxes"]),
    ({"obb": "exact"}, ["--obb", "exact"]),
    ({"seed": -1}, ["--seed", "-1"]),
    ({"fine": "eight"}, ["--fine", "eight"]),
    ({"cache": 32}, ["--cache", "32"]),
    ({"method": "morton", "seed": 3}, ["--method", "morton", "--seed", "3"]),
    ({"coarse_morton": True, "presplit": 4096}, ["--coarse-morton", "--presplit", "4096"]),
]


@pytest.mark.parametrize("options, flags", BAD_OPTIONS)
def test_bad_options_raise_the_command_lines_line(tmp_path, options, flags):
    code, _, err = run_cli("bake", SCENE, "-o", tmp_path / "x.cbk", *flags, check=False)
    assert code == 2
    assert err.startswith("clusterbake: ")
    with pytest.raises(ValueError) as e:
        clusterbake.bake(SCENE, **options)
    assert "clusterbake: " + str(e.value) == err.strip()
    assert not (tmp_path / "x.cbk").exists()


def test_options_come_from_the_table():
    names = [o["name"] for o in clusterbake.bake_options()]
    assert names[:3] == ["method", "coarse", "fine"] and "capsule_ratio" in names and "threads" in names
    with pytest.raises(ValueError, match="--fine-size is not a bake option"):
        clusterbake.bake(SCENE, fine_size=8)
    with pytest.raises(ValueError, match="--coarse-morton takes True or False"):
        clusterbake.bake(SCENE, coarse_morton=1)


def cube_arrays():
    """A unit cube, outward-wound, off the world origin so that its mesh gets an origin of its own."""
    p = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float32) + [1000, 3, -7]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    t = [(a, b, c) for a, b, c, d in faces] + [(a, c, d) for a, b, c, d in faces]
    return p.astype(np.float32), np.array(t, dtype=np.int64)


def binary_ply(path, positions, indices):
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(positions)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(indices)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = positions.astype("<f4").tobytes()
    body += b"".join(struct.pack("<B3i", 3, *map(int, t)) for t in indices)
    path.write_bytes(header.encode() + body)


def test_arrays_bake_as_their_file(tmp_path):
    positions, indices = cube_arrays()
    ply = tmp_path / "cube.ply"
    binary_ply(ply, positions, indices)
    run_cli("bake", ply, "-o", tmp_path / "cube.cbk", "-q", "--fine", "4")
    from_file = sections((tmp_path / "cube.cbk").read_bytes())
    asset = clusterbake.bake((positions, indices), fine=4)
    from_arrays = sections(asset.to_bytes())
    assert from_arrays.keys() == from_file.keys()
    for kind in from_file:
        if kind != SOURCE_SECTION:
            assert from_arrays[kind] == from_file[kind], kind
    lines = asset.source.splitlines()
    assert len(lines) == 3 and lines[2].startswith("input xxh3-128 ")  # no file lines: arrays are no files
    assert asset.info["closed_meshes"] == 1
    # int32 indices and a non-contiguous view of the same values bake the same asset.
    same = clusterbake.bake((np.asfortranarray(positions), indices.astype(np.int32)), fine=4)
    assert same.to_bytes() == asset.to_bytes()


def test_float64_arrays_bake_as_text(tmp_path):
    positions, indices = cube_arrays()
    p64 = positions.astype(np.float64) + 0.1
    obj = tmp_path / "cube.obj"
    with open(obj, "w") as f:
        f.writelines(f"v {x!r} {y!r} {z!r}\n" for x, y, z in p64)
        f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in indices)
    run_cli("bake", obj, "-o", tmp_path / "cube.cbk", "-q")
    from_file = sections((tmp_path / "cube.cbk").read_bytes())
    from_arrays = sections(clusterbake.bake((p64, indices)).to_bytes())
    for kind in from_file:
        if kind != SOURCE_SECTION:
            assert from_arrays[kind] == from_file[kind], kind


BAD_ARRAYS = [
    (np.zeros((4, 2), np.float32), np.zeros((1, 3), np.int32), ValueError, "positions must have shape"),
    (np.zeros(12, np.float32), np.zeros((1, 3), np.int32), ValueError, "positions must have shape"),
    (np.zeros((4, 3), np.float32), np.zeros((3,), np.int32), ValueError, "indices must have shape"),
    (np.zeros((4, 3), np.int32), np.zeros((1, 3), np.int32), TypeError, "positions must be float32 or float64"),
    (np.zeros((4, 3), np.complex64), np.zeros((1, 3), np.int32), TypeError, "positions must be float32"),
    (np.zeros((4, 3), np.float32), np.zeros((1, 3), np.float32), TypeError, "indices must be integers"),
    (np.array([["a", "b", "c"]]), np.zeros((1, 3), np.int32), TypeError, "positions must be"),
    (np.array([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]), ValueError,
     "vertex 1: position is not finite"),
    (np.array([[0, 0, 0], [1, 0, np.inf], [0, 1, 0]], np.float64), np.array([[0, 1, 2]]), ValueError,
     "vertex 1: position is not finite"),
    (np.eye(3, dtype=np.float32), np.array([[0, 1, 3]]), ValueError, r"index 3 out of range \(3 vertices\)"),
    (np.eye(3, dtype=np.float32), np.array([[0, -1, 2]]), ValueError, "index -1 out of range"),
    (np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.uint64) + np.uint64(2**40), ValueError, "out of range"),
]


@pytest.mark.parametrize("positions, indices, error, message", BAD_ARRAYS)
def test_bad_arrays_raise(positions, indices, error, message):
    with pytest.raises(error, match=message):
        clusterbake.bake((positions, indices))


def test_bad_sources_raise():
    with pytest.raises(TypeError):
        clusterbake.bake((np.eye(3, dtype=np.float32),))
    with pytest.raises(TypeError):
        clusterbake.bake(42)


def test_no_triangles_is_an_empty_asset_with_a_warning():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        asset = clusterbake.bake((np.eye(3, dtype=np.float32), np.zeros((0, 3), np.int32)))
    assert any("no triangles" in str(w.message) for w in caught)
    assert asset.info["triangles"] == 0
    answers = asset.occluded(np.zeros((5, 3)), (0, 10, 0))
    assert answers.dtype == bool and answers.shape == (5,) and not answers.any()


def external_gltf(folder, buffer_uri):
    """A one-triangle glTF whose buffer is the file buffer_uri names (relative to folder)."""
    import json

    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"uri": buffer_uri, "byteLength": len(positions)}],
        "bufferViews": [{"buffer": 0, "byteLength": len(positions)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
    }
    (folder / "scene.gltf").write_text(json.dumps(doc))
    return positions


def test_files_outside_the_scene_folder(tmp_path):
    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    (tmp_path / "shared.bin").write_bytes(external_gltf(scene_dir, "../shared.bin"))
    scene = scene_dir / "scene.gltf"
    code, _, err = run_cli("bake", scene, "-o", tmp_path / "x.cbk", check=False)
    assert code == 2
    with pytest.raises(ValueError) as e:
        clusterbake.bake(scene)
    assert str(e.value) == err.strip()
    run_cli("bake", scene, "-o", tmp_path / "cli.cbk", "-q", "--allow-outside-files")
    assert clusterbake.bake(scene, allow_outside_files=True).to_bytes() == (tmp_path / "cli.cbk").read_bytes()
    run_cli("bake", scene, "-o", tmp_path / "root.cbk", "-q", "--files-root", tmp_path)
    assert clusterbake.bake(scene, files_root=tmp_path).to_bytes() == (tmp_path / "root.cbk").read_bytes()
    with pytest.raises(ValueError, match="arrays name no files"):
        clusterbake.bake((np.eye(3, dtype=np.float32), np.array([[0, 1, 2]])), allow_outside_files=True)


def test_memory_budget_refuses_as_the_command_line(tmp_path):
    # The budget's estimate, before any clustering: the command line's line, and its refusal of the bytes
    # the default scene's 33,952 triangles need.
    code, _, err = run_cli("bake", SCENE, "-o", tmp_path / "x.cbk", "--memory-budget", "1MB", check=False)
    assert code == 2
    with pytest.raises(ValueError) as e:
        clusterbake.bake(SCENE, memory_budget=1 << 20)
    assert str(e.value) == err.strip()
    assert "over the memory budget of 1 MiB" in str(e.value)
    positions = np.random.default_rng(1).random((30000, 3))
    indices = np.arange(30000).reshape(-1, 3)
    with pytest.raises(ValueError, match="over the memory budget"):
        clusterbake.bake((positions, indices), memory_budget=1 << 20)
    assert clusterbake.bake(SCENE, memory_budget=1 << 30).to_bytes() == clusterbake.bake(SCENE).to_bytes()
    for bad in (0, -5, 1.5, "1MB", True, 1 << 70):
        with pytest.raises(ValueError, match="memory_budget takes a whole number of bytes"):
            clusterbake.bake(SCENE, memory_budget=bad)
