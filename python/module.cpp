// `import clusterbake`: bakes, assets and their exact shadow queries for Python, over the libraries the
// command line calls (docs/PYTHON.md). Options come from the bake options table and are checked by its
// code, so a bad one raises ValueError with the command line's own line. The work runs without the GIL;
// the caller's float64 arrays are read in place when C-contiguous.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <new>
#include <stdexcept>
#include <string>
#include <unistd.h>
#include <vector>

#include "asset_file.h"
#include "bake.h"
#include "bake_file.h"
#include "bake_options.h"
#include "baked_scene.h"
#include "cluster_stats.h"
#include "level_file.h"
#include "load.h"
#include "mesh_frame.h"
#include "scene_query.h"

namespace py = pybind11;

namespace {

// Python's OSError with the library's line (a file that cannot be read or written).
[[noreturn]] void raise_os_error(const std::string& message) {
    PyErr_SetString(PyExc_OSError, message.c_str());
    throw py::error_already_set();
}

// A str, bytes or os.PathLike as a path (os.fsdecode: bytes decoded as the file system names them).
std::string fspath(const py::object& path) {
    return py::module_::import("os").attr("fsdecode")(path).cast<std::string>();
}

// An asset's bytes, held aligned and opened. Held by shared_ptr, so that a Level keeps its assets alive;
// the bytes never move, so the views a Level holds stay valid.
struct Asset {
    cb::LoadedAsset loaded;
};
using AssetPtr = std::shared_ptr<Asset>;

AssetPtr asset_from_bytes(const void* bytes, size_t size, const std::string& name) {
    auto asset = std::make_shared<Asset>();
    cb::AssetError e = cb::open_asset_copy(bytes, size, asset->loaded);
    if (e != cb::AssetError::ok) throw py::value_error(name + ": " + cb::asset_error_text(e));
    return asset;
}

AssetPtr open_asset_file(const py::object& path_obj) {
    const std::string path = fspath(path_obj);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) raise_os_error(path + ": cannot open");
    auto asset = std::make_shared<Asset>();
    std::string error;
    bool ok;
    {
        py::gil_scoped_release release;
        ok = cb::read_asset_file(path, asset->loaded, error);
    }
    if (!ok) throw py::value_error(error);
    return asset;
}

// --- options -------------------------------------------------------------------------------------------

// A Python value as the command line would write it: whole numbers in decimal, reals with 17 digits (they
// read back as the same double), lists joined with commas (bounds=["obb", "cone"]), text as it is.
std::string option_text(const py::handle& value) {
    if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
    if (py::isinstance<py::int_>(value)) return py::str(value);
    if (py::isinstance<py::float_>(value)) {
        char text[32];
        std::snprintf(text, sizeof text, "%.17g", value.cast<double>());
        return text;
    }
    if (py::isinstance<py::str>(value)) return value.cast<std::string>();
    if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
        std::string out;
        for (const py::handle& item : value) out += (out.empty() ? "" : ",") + option_text(item);
        return out;
    }
    return py::str(value);
}

// The keyword options as a command line's words, in the table's order, then applied and checked as the
// command line does (cli/args.cpp: the values, the rules, then the options that would change nothing).
cb::BakeRequest request_from(const py::kwargs& kwargs, bool fit) {
    py::dict options = kwargs.attr("copy")();
    // What the scene file is trusted with (the command line's --allow-outside-files and --files-root, which
    // are load options, not rows of the table).
    cb::LoadOptions load;
    if (options.contains("allow_outside_files")) {
        const py::object value = options.attr("pop")("allow_outside_files");
        if (!py::isinstance<py::bool_>(value)) throw py::value_error("allow_outside_files takes True or False");
        load.allow_outside_files = value.cast<bool>();
    }
    if (options.contains("files_root")) load.root = fspath(options.attr("pop")("files_root"));
    if (options.contains("memory_budget")) {  // bytes, as --memory-budget's value after its unit
        const py::object value = options.attr("pop")("memory_budget");
        uint64_t bytes = 0;
        if (py::isinstance<py::int_>(value) && !py::isinstance<py::bool_>(value) &&
            value.cast<py::int_>() > py::int_(0)) {
            try {
                bytes = value.cast<uint64_t>();
            } catch (const py::cast_error&) {  // past 2^64: no budget to hold to
            }
        }
        if (!bytes)
            throw py::value_error("memory_budget takes a whole number of bytes from 1 to 2^64 - 1 (got '" +
                                  option_text(value) + "')");
        load.memory_budget = bytes;
    }
    for (const auto& item : options) {
        const std::string flag = "--" + [](std::string s) {
            std::replace(s.begin(), s.end(), '_', '-');
            return s;
        }(py::str(item.first).cast<std::string>());
        const cb::BakeOption* o = cb::find_bake_option(flag);
        if (!o || (!fit && o->use == cb::OptionUse::bounds))
            throw py::value_error(flag + " is not a " + (fit ? "bake" : "cluster") + " option");
    }
    std::vector<std::string> argv;
    for (const cb::BakeOption& o : cb::bake_options()) {
        std::string name = o.flag + 2;
        std::replace(name.begin(), name.end(), '-', '_');
        if (!options.contains(name)) continue;
        const py::handle value = options[name.c_str()];
        if (!o.takes_value) {  // a switch: True turns it on, False leaves it off
            if (!py::isinstance<py::bool_>(value))
                throw py::value_error(std::string(o.flag) + " takes True or False (got '" + option_text(value) + "')");
            if (value.cast<bool>()) argv.push_back(o.flag);
            continue;
        }
        argv.push_back(o.flag);
        argv.push_back(option_text(value));
    }
    cb::BakeRequest r;
    r.fit = fit;
    r.load = load;
    std::vector<std::string> given;
    std::string error = cb::apply_options(argv, r, &given);
    if (error.empty()) error = cb::request_options_error(r);
    if (error.empty()) error = cb::ignored_option_error(given, r);
    if (!error.empty()) throw py::value_error(error);
    return r;
}

// `a` as a C-contiguous array of `dtype`: `a` itself when it is one already, else numpy's copy. Raises
// numpy's own error when the copy cannot be made (MemoryError for a broadcast view of 10^12 rows).
py::array contiguous(const py::array& a, const char* dtype) {
    return py::module_::import("numpy").attr("ascontiguousarray")(a, py::arg("dtype") = dtype).cast<py::array>();
}

const double* doubles(const py::array& a) { return static_cast<const double*>(a.data()); }

// --- bake ----------------------------------------------------------------------------------------------

// A mesh from the caller's arrays, as a loader makes one: float32 positions keep their values exactly
// (as glTF or float PLY coordinates do), float64 ones are centred on their box (as text coordinates are).
cb::Scene scene_from_arrays(const py::handle& positions_obj, const py::handle& indices_obj, cb::SourceFiles& source) {
    const std::string name = "arrays";
    py::array positions = py::array::ensure(positions_obj);
    py::array indices = py::array::ensure(indices_obj);
    if (!positions || !indices) throw py::type_error("bake takes a path or (positions, indices) numpy arrays");
    const char pk = positions.dtype().kind(), ik = indices.dtype().kind();
    if (pk != 'f' || (positions.itemsize() != 4 && positions.itemsize() != 8))
        throw py::type_error("positions must be float32 or float64 (got " + std::string(py::str(positions.dtype())) +
                             ")");
    if (ik != 'i' && ik != 'u')
        throw py::type_error("indices must be integers (got " + std::string(py::str(indices.dtype())) + ")");
    if (positions.ndim() != 2 || positions.shape(1) != 3)
        throw py::value_error("positions must have shape (n, 3) (got " + std::string(py::str(positions.attr("shape"))) +
                              ")");
    if (indices.ndim() != 2 || indices.shape(1) != 3)
        throw py::value_error("indices must have shape (m, 3) (got " + std::string(py::str(indices.attr("shape"))) +
                              ")");
    const size_t n = size_t(positions.shape(0)), m = size_t(indices.shape(0));
    if (n > UINT32_MAX || m > UINT32_MAX / 3) throw py::value_error("arrays: more than 2^32 vertices or corners");

    const py::array idx = contiguous(indices, "int64");
    cb::Mesh mesh;
    mesh.indices.resize(m * 3);
    const int64_t* in = static_cast<const int64_t*>(idx.data());
    for (size_t i = 0; i < m * 3; ++i) {
        if (in[i] < 0 || uint64_t(in[i]) >= n)
            throw py::value_error(name + ": mesh 0: triangle " + std::to_string(i / 3) + ": index " +
                                  std::to_string(in[i]) + " out of range (" + std::to_string(n) + " vertices)");
        mesh.indices[i] = uint32_t(in[i]);
    }
    cb::SourceHasher hasher;
    cb::Origin origin{0, 0, 0};
    if (positions.itemsize() == 4) {
        const py::array p = contiguous(positions, "float32");
        const float* f = static_cast<const float*>(p.data());
        mesh.positions.assign(f, f + n * 3);
    } else {
        const py::array p = contiguous(positions, "float64");
        std::vector<double> xyz(doubles(p), doubles(p) + n * 3);
        for (size_t i = 0; i < xyz.size(); ++i)
            if (!std::isfinite(xyz[i]))
                throw py::value_error(name + ": mesh 0: vertex " + std::to_string(i / 3) + ": position is not finite");
        hasher.add("positions", reinterpret_cast<const uint8_t*>(xyz.data()), xyz.size() * sizeof(double));
        origin = cb::store_centred(xyz, mesh.positions);
    }
    for (size_t i = 0; i < mesh.positions.size(); ++i)
        if (!std::isfinite(mesh.positions[i]))
            throw py::value_error(name + ": mesh 0: vertex " + std::to_string(i / 3) + ": position is not finite");
    if (positions.itemsize() == 4) {
        hasher.add("positions", reinterpret_cast<const uint8_t*>(mesh.positions.data()),
                   mesh.positions.size() * sizeof(float));
        origin = cb::shift_exactly(mesh.positions);
    }
    hasher.add("indices", reinterpret_cast<const uint8_t*>(mesh.indices.data()), mesh.indices.size() * 4);
    source = hasher.finish();
    source.names.clear();  // no files: the hash is over the two arrays (docs/FORMAT.md)
    return cb::single_mesh_scene(std::move(mesh), name, origin);
}

// The warning a bake of this scene raises, as `clusterbake bake` prints it, or empty.
std::string bake_warning(const cb::Scene& scene, const std::string& name, uint64_t triangles) {
    std::string warning;
    if (triangles == 0)
        warning = name + ": no triangles (" + std::to_string(scene.report.skipped_primitives) +
            " point or line primitives skipped): the asset holds no geometry";
    for (const std::string& w : scene.report.warnings) warning += (warning.empty() ? "" : "; ") + w;
    return warning;
}

AssetPtr bake(const py::object& source, bool fit, const py::kwargs& options) {
    cb::BakeRequest r = request_from(options, fit);
    cb::Scene scene;
    std::string name;
    if (py::isinstance<py::tuple>(source) || py::isinstance<py::list>(source)) {
        if (py::len(source) != 2) throw py::type_error("bake takes a path or (positions, indices) numpy arrays");
        name = "arrays";
        if (options.contains("allow_outside_files") || options.contains("files_root"))
            throw py::value_error("allow_outside_files and files_root do nothing here: arrays name no files");
        cb::SourceFiles files;
        scene = scene_from_arrays(source[py::int_(0)], source[py::int_(1)], files);
        scene.report.source = files;
    } else {
        name = fspath(source);
        std::error_code ec;
        if (!std::filesystem::is_regular_file(name, ec)) raise_os_error(name + ": cannot open");
        std::string error;
        {
            py::gil_scoped_release release;
            try {
                scene = cb::load_scene(name, r.load);
            } catch (const cb::LoadError& e) {
                error = e.what();
            }
        }
        if (!error.empty()) throw py::value_error(error);
    }
    r.input = name;
    try {
        cb::check_bake_memory(scene, r);
    } catch (const cb::LoadError& e) {
        throw py::value_error(e.what());
    }
    std::vector<uint8_t> bytes;
    uint64_t triangles = 0;
    {
        py::gil_scoped_release release;
        cb::BakeStats stats;
        std::vector<cb::AssetMesh> meshes = cb::cluster_scene(scene, r.clustering, stats, {}, r.threads);
        if (r.fit) cb::fit_scene_bounds(meshes, r.bounds, r.threads, stats);
        bytes = cb::encode_asset(meshes, scene.instances,
                                 cb::source_text(scene.report.source, r.clustering, r.bounds, r.fit));
        triangles = stats.triangles;
    }
    const std::string warning = bake_warning(scene, name, triangles);
    if (!warning.empty() && PyErr_WarnEx(PyExc_UserWarning, warning.c_str(), 1) != 0) throw py::error_already_set();
    return asset_from_bytes(bytes.data(), bytes.size(), name);
}

// --- queries -------------------------------------------------------------------------------------------

// Points as (n, 3) float64, read in place when C-contiguous float64, else copied; every coordinate finite.
py::array points_array(const py::handle& obj, const char* what) {
    py::array a = py::array::ensure(obj);
    if (!a) throw py::type_error(std::string(what) + " must be a numpy array of floats");
    if (a.dtype().kind() != 'f' && a.dtype().kind() != 'i' && a.dtype().kind() != 'u')
        throw py::type_error(std::string(what) + " must be numbers (got " + std::string(py::str(a.dtype())) + ")");
    return contiguous(a, "float64");
}

void check_finite(const double* v, size_t count, const char* what) {
    for (size_t i = 0; i < count; ++i)
        if (!std::isfinite(v[i]))
            throw py::value_error(std::string(what) + ": row " + std::to_string(i / 3) + ": coordinate is not finite");
}

cb::SceneQueryOptions query_options(bool one_sided, const std::string& traversal, unsigned threads, double bias,
                                    bool sun) {
    cb::SceneQueryOptions o;
    if (!cb::parse_traversal(traversal, o.traversal))
        throw py::value_error("traversal takes scan, top-two, top-one, mtsv-one or mtsv-two (got '" + traversal + "')");
    o.sun = sun;
    if (!(bias >= 0 && bias < INFINITY))
        throw py::value_error("bias takes a distance of at least 0 (0: the level's default)");
    o.one_sided = one_sided;
    o.threads = threads;
    o.bias = bias;
    return o;
}

// Points against one light ((3,): answers (n,)) or several ((k, 3): answers (k, n)), over the level. With
// `sun`, each light is the direction toward a sun (cb_segment.h, "A sun").
py::array occluded(const cb::LevelInput& level, const py::handle& points_obj, const py::handle& light_obj,
                   bool one_sided, const std::string& traversal, unsigned threads, double bias, bool sun) {
    const cb::SceneQueryOptions options = query_options(one_sided, traversal, threads, bias, sun);
    auto points = points_array(points_obj, "points");
    if (points.ndim() != 2 || points.shape(1) != 3)
        throw py::value_error("points must have shape (n, 3) (got " + std::string(py::str(points.attr("shape"))) + ")");
    auto lights = points_array(light_obj, "light");
    const bool one_light = lights.ndim() == 1;
    if (!(one_light ? lights.shape(0) == 3 : lights.ndim() == 2 && lights.shape(1) == 3))
        throw py::value_error("light must have shape (3,), or (k, 3) for several (got " +
                              std::string(py::str(lights.attr("shape"))) + ")");
    const size_t n = size_t(points.shape(0)), k = one_light ? 1 : size_t(lights.shape(0));
    check_finite(doubles(points), n * 3, "points");
    check_finite(doubles(lights), k * 3, "light");
    for (size_t i = 0; sun && i < k; ++i) {
        const double* d = doubles(lights) + i * 3;
        if (d[0] == 0 && d[1] == 0 && d[2] == 0)
            throw py::value_error("light: row " + std::to_string(i) + ": a sun's direction has no length");
    }

    py::array_t<bool> answers = one_light ? py::array_t<bool>(std::vector<py::ssize_t>{py::ssize_t(n)})
                                          : py::array_t<bool>(std::vector<py::ssize_t>{py::ssize_t(k), py::ssize_t(n)});
    bool* out = answers.mutable_data();
    const double* p = doubles(points);
    const double* l = doubles(lights);
    {
        py::gil_scoped_release release;
        if (n > 0 && k > 0) {
            if (one_light) {
                cb::SceneQueryResult q = cb::query_level(level, l, p, n, options);
                for (size_t i = 0; i < n; ++i) out[i] = q.shadowed[i] != 0;
            } else {
                cb::query_level_lights(level, l, k, p, n, options, [&](size_t light, const cb::SceneQueryResult& q) {
                    for (size_t i = 0; i < n; ++i) out[light * n + i] = q.shadowed[i] != 0;
                });
            }
        }
    }
    return answers;
}

// --- levels --------------------------------------------------------------------------------------------

// Assets placed in one world: each add places every baked instance of an asset under a matrix.
struct Level {
    std::vector<AssetPtr> assets;  // kept alive while the level holds their views
    cb::LevelInput input;

    void add(const AssetPtr& asset, const py::object& matrix_obj) {
        if (!asset) throw py::type_error("add takes an Asset");
        if (std::find(assets.begin(), assets.end(), asset) == assets.end()) assets.push_back(asset);
        if (matrix_obj.is_none()) {
            cb::place_baked(input, asset->loaded.view);
            return;
        }
        auto m = points_array(matrix_obj, "matrix");
        if (m.ndim() != 2 || m.shape(1) != 4 || (m.shape(0) != 3 && m.shape(0) != 4))
            throw py::value_error("matrix must have shape (4, 4) or (3, 4) (got " +
                                  std::string(py::str(m.attr("shape"))) + ")");
        const double* v = doubles(m);
        check_finite(v, size_t(m.shape(0)) * 4, "matrix");
        if (m.shape(0) == 4 && !(v[12] == 0 && v[13] == 0 && v[14] == 0 && v[15] == 1))
            throw py::value_error("matrix: the last row must be 0, 0, 0, 1 (an affine transform)");
        // Row-major M (M @ (x, y, z, 1)) to the library's column-major 3x4: the x, y, z axes, the translation.
        double columns[12];
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 3; ++r) columns[c * 3 + r] = v[r * 4 + c];
        cb::place_baked(input, asset->loaded.view, columns);
    }
};

std::shared_ptr<Level> open_level(const py::object& path_obj) {
    const std::string path = fspath(path_obj);
    std::vector<cb::LevelEntry> entries;
    std::string error;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) raise_os_error(path + ": cannot open");
    if (!cb::read_level_file(path, entries, error)) throw py::value_error(error);
    auto level = std::make_shared<Level>();
    std::vector<std::pair<std::string, AssetPtr>> opened;  // each asset file opened once
    for (size_t i = 0; i < entries.size(); ++i) {
        const std::string asset_path = std::filesystem::path(entries[i].asset).lexically_normal().string();
        AssetPtr asset;
        for (const auto& [p, a] : opened)
            if (p == asset_path) asset = a;
        if (!asset) {
            auto loaded = std::make_shared<Asset>();
            if (!cb::read_asset_file(asset_path, loaded->loaded, error))
                throw py::value_error(path + ": instances[" + std::to_string(i) + "]: " + error);
            opened.emplace_back(asset_path, loaded);
            asset = loaded;
        }
        const cb::Transform& t = entries[i].transform;  // column-major 4x4
        py::array_t<double> m({3, 4});
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) m.mutable_at(r, c) = t[c * 4 + r];
        level->add(asset, m);
    }
    return level;
}

// --- asset facts -----------------------------------------------------------------------------------------

py::list level_kinds(const cb::LevelBounds& level) {
    py::list kinds;
    if (level.obbs) kinds.append("obb");
    if (level.spheres) kinds.append("sphere");
    if (level.capsules) kinds.append("capsule");
    if (level.cones) kinds.append("cone");
    if (level.slabs) kinds.append("slab");
    return kinds;
}

// What `clusterbake validate --json` says of the asset, but its file and source lines (Asset.source).
py::dict asset_info(const Asset& a) {
    const cb::AssetView& view = a.loaded.view;
    py::dict d;
    d["format"] = cb::asset_version;
    d["bytes"] = a.loaded.size;
    d["meshes"] = view.mesh_count;
    d["instances"] = view.instance_count;
    d["vertices"] = view.vertex_count;
    d["triangles"] = view.triangle_count;
    d["fine_clusters"] = view.fine_count;
    d["coarse_clusters"] = view.coarse_count;
    d["fine_bounds"] = level_kinds(view.fine_bounds);
    d["coarse_bounds"] = level_kinds(view.coarse_bounds);
    if (view.mesh_flags) {
        uint32_t closed = 0;
        size_t double_sided = 0;
        for (uint32_t m = 0; m < view.mesh_count; ++m) closed += view.mesh_flags[m] & cb::mesh_closed ? 1 : 0;
        for (size_t t = 0; t < view.triangle_count; ++t) double_sided += view.double_sided(t);
        d["closed_meshes"] = closed;
        d["double_sided_triangles"] = double_sided;
    }
    return d;
}

// The figures of `clusterbake stats --json ASSET` with the same options.
py::object asset_stats(const Asset& a, uint32_t sample_lights, uint32_t samples, uint64_t light_seed,
                       uint32_t acmr_cache, unsigned threads, uint32_t sample_suns) {
    cb::StatsOptions so;
    so.lights = sample_lights;
    so.suns = sample_suns;
    so.samples = samples;
    so.seed = light_seed;
    so.acmr_cache = acmr_cache;
    so.threads = threads;
    std::string text;
    {
        py::gil_scoped_release release;
        cb::BoundsOptions bounds;
        bounds.mask = cb::bounds_all;  // as `stats` asks: the kinds the asset lacks are fitted for the figures
        std::string note;
        cb::BakedScene baked = cb::baked_from_asset(a.loaded.view, bounds, &note, {}, threads);
        nlohmann::json j = cb::to_json(cb::cluster_statistics(baked.meshes, baked.instances, so));
        j["tool"] = cb::tool_version();
        j["input"] = "asset";
        if (!note.empty()) j["note"] = note;
        text = j.dump();
    }
    return py::module_::import("json").attr("loads")(text);
}

void save_asset(const Asset& a, const std::string& path) {
    const uint8_t* data = a.loaded.data();
    const size_t size = a.loaded.size;
    std::string error;
    {
        py::gil_scoped_release release;
        try {
            cb::write_file_atomic(path, [&](int fd) {
                for (size_t at = 0; at < size;) {
                    const ssize_t wrote = ::write(fd, data + at, size - at);
                    if (wrote < 0) {
                        if (errno == EINTR) continue;
                        return false;
                    }
                    at += size_t(wrote);
                }
                return true;
            });
        } catch (const std::exception& e) {
            error = e.what();
        }
    }
    if (!error.empty()) raise_os_error(error);
}

}  // namespace

PYBIND11_MODULE(clusterbake, m) {
    m.doc() =
        "Bakes triangle scenes into clusterbake assets and answers exact shadow queries of point lights and suns on "
        "them.";
    m.attr("__version__") = std::string(cb::tool_version()).substr(std::strlen("clusterbake "));
    m.attr("asset_format") = cb::asset_version;
    m.attr("build_id") = std::string(cb::build_id());  // in every source section, as the command line's

    py::class_<Asset, AssetPtr>(m, "Asset", "A baked asset, held in memory and validated as the runtime reads it.")
        .def_static("open", &open_asset_file, py::arg("path"), "Reads and validates an asset file (.cbk).")
        .def_static(
            "from_bytes",
            [](const py::bytes& b) {
                std::string_view v = b;
                return asset_from_bytes(v.data(), v.size(), "bytes");
            },
            py::arg("data"), "Validates an asset held in bytes.")
        .def(
            "save", [](const Asset& a, const py::object& path) { save_asset(a, fspath(path)); }, py::arg("path"),
            "Writes the asset atomically: a failure leaves an existing file untouched.")
        .def(
            "to_bytes",
            [](const Asset& a) { return py::bytes(reinterpret_cast<const char*>(a.loaded.data()), a.loaded.size); },
            "The asset's bytes, as save writes them.")
        .def_property_readonly("info", &asset_info, "Counts and stored volumes, as `clusterbake validate --json`.")
        .def_property_readonly(
            "source",
            [](const Asset& a) -> py::object {
                const cb::AssetView& v = a.loaded.view;
                if (!v.source) return py::none();
                PyObject* text = PyUnicode_DecodeUTF8(v.source, v.source_size, "replace");
                if (!text) throw py::error_already_set();
                return py::reinterpret_steal<py::str>(text);
            },
            "What the asset was made from (the source section's text), or None.")
        .def("stats", &asset_stats, py::kw_only(), py::arg("sample_lights") = 8, py::arg("samples") = 32,
             py::arg("light_seed") = 1, py::arg("acmr_cache") = 32, py::arg("threads") = 0, py::arg("sample_suns") = 8,
             "Cluster-quality figures, as `clusterbake stats --json` prints them for the asset.")
        .def(
            "occluded",
            [](const Asset& a, const py::handle& points, const py::handle& light, bool one_sided,
               const std::string& traversal, unsigned threads, double bias, bool sun) {
                return occluded(cb::baked_level(a.loaded.view), points, light, one_sided, traversal, threads, bias,
                                sun);
            },
            py::arg("points"), py::arg("light"), py::kw_only(), py::arg("one_sided") = false,
            py::arg("traversal") = "scan", py::arg("threads") = 0, py::arg("bias") = 0.0, py::arg("sun") = false,
            "Whether each point is in the shadow of the light, exactly: a bool array of shape (n,) for a light "
            "(3,), (k, n) for lights (k, 3). With sun=True each light is the direction toward a sun.");

    py::class_<Level, std::shared_ptr<Level>>(m, "Level", "Assets placed in one world under affine transforms.")
        .def(py::init<>())
        .def_static("open", &open_level, py::arg("path"), "Reads a level file (JSON, docs/RUNTIME.md).")
        .def("add", &Level::add, py::arg("asset"), py::arg("matrix") = py::none(),
             "Places every baked instance of the asset under matrix ((4, 4) or (3, 4), M @ (x, y, z, 1)).")
        .def_property_readonly("instance_count", [](const Level& l) { return l.input.instances.size(); })
        .def(
            "occluded",
            [](const Level& l, const py::handle& points, const py::handle& light, bool one_sided,
               const std::string& traversal, unsigned threads, double bias, bool sun) {
                // A copy taken with the GIL held: another thread may add to the level while this one asks.
                const cb::LevelInput snapshot = l.input;
                return occluded(snapshot, points, light, one_sided, traversal, threads, bias, sun);
            },
            py::arg("points"), py::arg("light"), py::kw_only(), py::arg("one_sided") = false,
            py::arg("traversal") = "scan", py::arg("threads") = 0, py::arg("bias") = 0.0, py::arg("sun") = false,
            "As Asset.occluded, over every instance of the level.");

    m.def(
        "bake", [](const py::object& source, const py::kwargs& options) { return bake(source, true, options); },
        py::arg("source"),
        "Bakes a scene file, or (positions (n, 3) float, indices (m, 3) int) arrays, into an Asset. Options by "
        "the command line's names (fine=8, bounds='all', coarse_morton=True), and for a file allow_outside_files "
        "and files_root.");
    m.def(
        "cluster", [](const py::object& source, const py::kwargs& options) { return bake(source, false, options); },
        py::arg("source"), "As bake, without bounding volumes (`clusterbake cluster`).");
    m.def(
        "bake_options",
        [] {
            py::list out;
            for (const cb::BakeOption& o : cb::bake_options()) {
                std::string name = o.flag + 2;
                std::replace(name.begin(), name.end(), '-', '_');
                py::dict d;
                d["name"] = name;
                d["flag"] = o.flag;
                d["default"] = o.takes_value ? py::object(py::str(o.default_value)) : py::object(py::bool_(false));
                d["help"] = o.help;
                out.append(d);
            }
            return out;
        },
        "The bake options: name, command-line flag, default (as the command line writes it) and help.");
}
