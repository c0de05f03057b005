"""Shadow queries through the module against `clusterbake query` on the same points and asset."""

import json

import numpy as np
import pytest

import clusterbake
from conftest import run_cli, scene_points, write_points

LIGHTS = [(-4.0, 30.0, 2.0), (8.5, 3.0, -6.25), (0.3, 0.9, 0.1)]


def cli_answers(asset_path, light, points_path, *flags):
    _, out, _ = run_cli("query", asset_path, "--light", ",".join(map(repr, light)), "--points", points_path, *flags)
    return np.array([line == "1" for line in out.split()], dtype=bool)


@pytest.fixture(scope="module")
def points(tmp_path_factory):
    pts = scene_points(3000, seed=7)
    path = tmp_path_factory.mktemp("points") / "points.txt"
    write_points(path, pts)
    return pts, path


@pytest.mark.parametrize("light", LIGHTS)
@pytest.mark.parametrize(
    "options, flags",
    [({}, []), ({"one_sided": True}, ["--one-sided"]), ({"traversal": "top-two"}, ["--traversal", "top-two"]),
     ({"traversal": "mtsv-one", "bias": 0.01}, ["--traversal", "mtsv-one", "--bias", "0.01"])],
)
def test_answers_equal_the_command_line(scene_asset, scene_asset_file, points, light, options, flags):
    pts, path = points
    ours = scene_asset.occluded(pts, np.array(light), **options)
    theirs = cli_answers(scene_asset_file, light, path, *flags)
    assert ours.dtype == bool and ours.shape == (len(pts),)
    assert 0 < ours.sum() < len(pts)  # the points see both sides of some shadow
    assert np.array_equal(ours, theirs)


SUNS = [(-1.0, 0.4, 0.3), (0.3, 1.0, 0.2)]


@pytest.mark.parametrize("sun", SUNS)
@pytest.mark.parametrize("options, flags", [({}, []), ({"one_sided": True}, ["--one-sided"])])
def test_suns_equal_the_command_line(scene_asset, scene_asset_file, points, sun, options, flags):
    pts, path = points
    ours = scene_asset.occluded(pts, sun, sun=True, **options)
    _, out, _ = run_cli("query", scene_asset_file, "--sun", ",".join(map(repr, sun)), "--points", path, *flags)
    theirs = np.array([line == "1" for line in out.split()], dtype=bool)
    assert 0 < ours.sum() < len(pts)
    assert np.array_equal(ours, theirs)
    together = scene_asset.occluded(pts, np.array(SUNS), sun=True, **options)
    assert np.array_equal(together[SUNS.index(sun)], ours)
    for traversal in ("top-two", "top-one", "mtsv-one", "mtsv-two"):
        walked = scene_asset.occluded(pts, sun, sun=True, traversal=traversal, **options)
        assert np.array_equal(walked, ours), traversal


def test_bad_suns_raise(scene_asset):
    with pytest.raises(ValueError, match="a sun's direction has no length"):
        scene_asset.occluded(np.zeros((4, 3)), (0, 0, 0), sun=True)
    with pytest.raises(ValueError, match="traversal takes scan"):
        scene_asset.occluded(np.zeros((4, 3)), (0, 1, 0), sun=True, traversal="tree")


def test_several_lights_at_once(scene_asset, points):
    pts, _ = points
    lights = np.array(LIGHTS)
    together = scene_asset.occluded(pts, lights, threads=2)
    assert together.shape == (len(LIGHTS), len(pts))
    for k, light in enumerate(LIGHTS):
        assert np.array_equal(together[k], scene_asset.occluded(pts, light))
    assert scene_asset.occluded(pts, np.zeros((0, 3))).shape == (0, len(pts))


def test_layouts_and_dtypes_give_the_same_answers(scene_asset, points):
    pts, _ = points
    expected = scene_asset.occluded(pts, LIGHTS[0])
    wide = np.zeros((len(pts), 6))
    wide[:, ::2] = pts  # a strided view: read through a copy
    assert np.array_equal(scene_asset.occluded(wide[:, ::2], LIGHTS[0]), expected)
    assert np.array_equal(scene_asset.occluded(np.asfortranarray(pts), LIGHTS[0]), expected)
    assert np.array_equal(scene_asset.occluded(pts.tolist(), list(LIGHTS[0])), expected)
    f32 = pts.astype(np.float32)
    assert np.array_equal(scene_asset.occluded(f32, LIGHTS[0]), scene_asset.occluded(f32.astype(np.float64), LIGHTS[0]))
    assert scene_asset.occluded(np.zeros((0, 3)), LIGHTS[0]).shape == (0,)
    assert pts.flags.writeable and pts.flags.c_contiguous  # the caller's array is left as it was


BAD_QUERIES = [
    (np.zeros((4, 2)), (0, 10, 0), {}, ValueError, r"points must have shape \(n, 3\)"),
    (np.zeros(12), (0, 10, 0), {}, ValueError, "points must have shape"),
    (np.zeros((2, 3, 1)), (0, 10, 0), {}, ValueError, "points must have shape"),
    (np.array([[0, 1, np.nan]]), (0, 10, 0), {}, ValueError, "points: row 0: coordinate is not finite"),
    (np.array([[0, 1, 2], [0, np.inf, 0]]), (0, 10, 0), {}, ValueError, "points: row 1: coordinate is not finite"),
    (np.array([["a", "b", "c"]]), (0, 10, 0), {}, TypeError, "points must be numbers"),
    (np.zeros((4, 3), bool), (0, 10, 0), {}, TypeError, "points must be numbers"),
    (np.zeros((4, 3), complex), (0, 10, 0), {}, TypeError, "points must be numbers"),
    (np.broadcast_to(np.zeros(3), (2**40, 3)), (0, 10, 0), {}, MemoryError, ""),  # a 24 TiB copy refused
    (np.zeros((4, 3)), (0, 10), {}, ValueError, r"light must have shape \(3,\)"),
    (np.zeros((4, 3)), np.zeros((2, 4)), {}, ValueError, "light must have shape"),
    (np.zeros((4, 3)), (0, np.nan, 0), {}, ValueError, "light: row 0: coordinate is not finite"),
    (np.zeros((4, 3)), (0, 10, 0), {"traversal": "bvh"}, ValueError, "traversal takes scan, top-two"),
    (np.zeros((4, 3)), (0, 10, 0), {"bias": -1.0}, ValueError, "bias takes a distance of at least 0"),
    (np.zeros((4, 3)), (0, 10, 0), {"bias": float("nan")}, ValueError, "bias takes a distance"),
    (np.zeros((4, 3)), (0, 10, 0), {"threads": -1}, TypeError, ""),
]


@pytest.mark.parametrize("pts, light, options, error, message", BAD_QUERIES)
def test_bad_queries_raise(scene_asset, pts, light, options, error, message):
    with pytest.raises(error, match=message):
        scene_asset.occluded(pts, light, **options)


def test_level_equals_the_command_line(tmp_path, scene_asset, scene_asset_file, points):
    pts, path = points
    # The scene twice: as baked, and turned a quarter about y and lifted, so that each casts on the other.
    turn = np.array([[0.0, 0, 1, 3], [0, 1, 0, 0.5], [-1, 0, 0, -2], [0, 0, 0, 1]])
    level = clusterbake.Level()
    level.add(scene_asset)
    level.add(scene_asset, turn)
    assert level.instance_count == 2 * scene_asset.info["instances"]
    level_file = tmp_path / "level.json"
    level_file.write_text(json.dumps({"instances": [
        {"asset": str(scene_asset_file)},
        {"asset": str(scene_asset_file), "matrix": turn.T.reshape(-1).tolist()},  # column-major
    ]}))
    for light in LIGHTS[:2]:
        ours = level.occluded(pts, light)
        assert np.array_equal(ours, cli_answers(level_file, light, path))
        assert not np.array_equal(ours, scene_asset.occluded(pts, light))  # the second copy casts shadows
        assert np.array_equal(clusterbake.Level.open(level_file).occluded(pts, light), ours)
    assert np.array_equal(level.occluded(pts, np.array(LIGHTS[:2]))[1], level.occluded(pts, LIGHTS[1]))


def test_bad_levels_raise(tmp_path, scene_asset):
    level = clusterbake.Level()
    with pytest.raises(ValueError, match="matrix must have shape"):
        level.add(scene_asset, np.eye(3))
    with pytest.raises(ValueError, match="last row"):
        level.add(scene_asset, np.ones((4, 4)))
    with pytest.raises(ValueError, match="not finite"):
        level.add(scene_asset, np.full((3, 4), np.nan))
    with pytest.raises(TypeError):
        level.add(None)
    assert level.instance_count == 0
    assert not level.occluded(np.zeros((3, 3)), (0, 5, 0)).any()  # an empty level shadows nothing
    bad = tmp_path / "level.json"
    bad.write_text('{"instances": [{"asset": "missing.cbk"}]}')
    with pytest.raises(ValueError, match="instances"):
        clusterbake.Level.open(bad)
    with pytest.raises(OSError):
        clusterbake.Level.open(tmp_path / "none.json")


def test_stats_equal_the_command_line(scene_asset, scene_asset_file):
    _, out, _ = run_cli("stats", scene_asset_file, "--json", "-q", "--samples", "8")
    printed = json.loads(out)
    ours = scene_asset.stats(samples=8)
    for key in ("tool", "input", "note"):
        assert ours.get(key) == printed.get(key)
    printed.pop("file")
    assert ours == printed
    assert ours["fine"]["clusters"] == scene_asset.info["fine_clusters"]
    assert ours["fine"]["sun_prism"]["samples"] > 0
    _, out, _ = run_cli("stats", scene_asset_file, "--json", "-q", "--samples", "4", "--sample-suns", "3")
    printed = json.loads(out)
    printed.pop("file")
    assert scene_asset.stats(samples=4, sample_suns=3) == printed


def traced_peak(call):
    """The most bytes Python and NumPy held at once during call(), over what they held before it."""
    import tracemalloc

    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        call()
        return tracemalloc.get_traced_memory()[1] - before
    finally:
        tracemalloc.stop()


def test_contiguous_points_are_read_in_place(scene_asset):
    pts = scene_points(200_000, seed=3)  # 4.8 MB of float64; the answers take 0.2 MB
    fortran = np.asfortranarray(pts)
    in_place = traced_peak(lambda: scene_asset.occluded(pts, LIGHTS[0]))
    copied = traced_peak(lambda: scene_asset.occluded(fortran, LIGHTS[0]))
    assert in_place < pts.nbytes / 4
    assert copied > pts.nbytes  # the same measure sees a copy where one is made


def test_threads_query_one_asset_at_once(scene_asset, points):
    from concurrent.futures import ThreadPoolExecutor

    pts, _ = points
    expected = [scene_asset.occluded(pts, light, threads=1) for light in LIGHTS]
    with ThreadPoolExecutor(3) as pool:
        answers = list(pool.map(lambda light: scene_asset.occluded(pts, light, threads=1), LIGHTS * 4))
    for i, a in enumerate(answers):
        assert np.array_equal(a, expected[i % len(LIGHTS)])


def test_adding_to_a_level_while_it_answers(scene_asset, points):
    from concurrent.futures import ThreadPoolExecutor

    pts, _ = points
    level = clusterbake.Level()
    level.add(scene_asset)
    alone = level.occluded(pts, LIGHTS[0], threads=1)
    far = np.eye(4)
    far[:3, 3] = [1000, 0, 0]  # copies far away: no shadow on the points
    with ThreadPoolExecutor(2) as pool:
        answers = pool.submit(lambda: [level.occluded(pts, LIGHTS[0], threads=1) for _ in range(20)])
        for _ in range(200):
            level.add(scene_asset, far)
        for a in answers.result():
            assert np.array_equal(a, alone)
    assert level.instance_count == 201 * scene_asset.info["instances"]
