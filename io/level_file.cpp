#include "level_file.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace cb {

namespace {

using nlohmann::json;

struct LevelError {
    std::string text;
};

// `count` finite numbers from the entry's array `key` into `out`.
void read_numbers(const json& entry, const char* key, size_t count, double* out) {
    const json& v = entry[key];
    if (!v.is_array() || v.size() != count)
        throw LevelError{std::string(key) + " needs " + std::to_string(count) + " numbers"};
    for (size_t i = 0; i < count; ++i) {
        if (!v[i].is_number()) throw LevelError{std::string(key) + "[" + std::to_string(i) + "] is not a number"};
        out[i] = v[i].get<double>();
        if (!std::isfinite(out[i])) throw LevelError{std::string(key) + "[" + std::to_string(i) + "] is not finite"};
    }
}

// The entry's transform: its matrix, or its translation, rotation and scale (each optional), as glTF's nodes.
Transform entry_transform(const json& entry) {
    const bool trs = entry.contains("translation") || entry.contains("rotation") || entry.contains("scale");
    Transform m = identity_transform();
    if (entry.contains("matrix")) {
        if (trs) throw LevelError{"a matrix and a translation, rotation or scale: give one or the other"};
        read_numbers(entry, "matrix", 16, m.data());
        if (m[3] != 0 || m[7] != 0 || m[11] != 0 || m[15] != 1)
            throw LevelError{"matrix is not affine (its last row, elements 3, 7, 11 and 15, must be 0 0 0 1)"};
        return m;
    }
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    if (entry.contains("translation")) read_numbers(entry, "translation", 3, t);
    if (entry.contains("scale")) read_numbers(entry, "scale", 3, s);
    if (entry.contains("rotation")) {
        read_numbers(entry, "rotation", 4, q);
        const double length = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (!(length > 0) || !std::isfinite(length)) throw LevelError{"rotation quaternion has zero length"};
        for (double& c : q) c /= length;  // written to a few digits, as glTF exporters do
    }
    return trs_transform(t, q, s);
}

LevelEntry read_entry(const json& entry, const std::filesystem::path& folder) {
    if (!entry.is_object()) throw LevelError{"not an object"};
    for (const auto& item : entry.items())
        if (item.key() != "asset" && item.key() != "matrix" && item.key() != "translation" &&
            item.key() != "rotation" && item.key() != "scale")
            throw LevelError{"unknown key '" + item.key() + "' (asset, matrix, translation, rotation, scale)"};
    const auto asset = entry.find("asset");
    if (asset == entry.end() || !asset->is_string() || asset->get<std::string>().empty())
        throw LevelError{"needs \"asset\": the path of a baked asset"};
    const std::filesystem::path path = asset->get<std::string>();
    return {(path.is_absolute() ? path : folder / path).string(), entry_transform(entry)};
}

}  // namespace

bool is_level_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    char c;
    while (in.get(c))
        if (c != ' ' && c != '\t' && c != '\r' && c != '\n') return c == '{';
    return false;
}

bool read_level_file(const std::string& path, std::vector<LevelEntry>& out, std::string& error) {
    out.clear();
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        error = path + ": cannot open";
        return false;
    }
    std::stringstream text;
    text << in.rdbuf();
    json doc;
    try {
        doc = json::parse(text.str());
    } catch (const json::parse_error& e) {
        error = path + ": not JSON text (parse error at byte " + std::to_string(e.byte) + ")";
        return false;
    } catch (const json::exception&) {
        error = path + ": a number out of range";
        return false;
    }
    const auto instances = doc.is_object() ? doc.find("instances") : doc.end();
    if (instances == doc.end() || !instances->is_array()) {
        error = path + ": a level file is an object with an \"instances\" array";
        return false;
    }
    if (instances->empty()) {
        error = path + ": instances: no entry";
        return false;
    }
    const std::filesystem::path folder = std::filesystem::path(path).parent_path();
    for (size_t i = 0; i < instances->size(); ++i) {
        try {
            out.push_back(read_entry((*instances)[i], folder));
        } catch (const LevelError& e) {
            out.clear();
            error = path + ": instances[" + std::to_string(i) + "]: " + e.text;
            return false;
        }
    }
    return true;
}

}  // namespace cb
