#include "file_access.h"

#include <cctype>
#include <filesystem>

namespace cb {
namespace fs = std::filesystem;
namespace {

// "file:", "http:" and the like: letters, digits, '+', '-' or '.' before a colon, starting with a letter.
bool has_scheme(const std::string& uri) {
    size_t colon = uri.find(':');
    if (colon == std::string::npos || colon == 0 || !std::isalpha(uint8_t(uri[0]))) return false;
    for (size_t i = 0; i < colon; ++i)
        if (!std::isalnum(uint8_t(uri[i])) && uri[i] != '+' && uri[i] != '-' && uri[i] != '.') return false;
    return true;
}

// The path with every symbolic link of its existing part resolved, absolute and normal.
fs::path resolved(const fs::path& p) {
    std::error_code ec;
    fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec);
    return ec ? fs::absolute(p).lexically_normal() : r;
}

// Whether `inner` is `outer` or lies below it (both resolved).
bool is_within(const fs::path& inner, const fs::path& outer) {
    auto o = outer.begin(), i = inner.begin();
    for (; o != outer.end(); ++o, ++i)
        if (o->empty() && std::next(o) == outer.end())
            return true;  // a trailing separator
        else if (i == inner.end() || *i != *o)
            return false;
    return true;
}

}  // namespace

std::string percent_decoded(const std::string& uri) {
    std::string out;
    for (size_t i = 0; i < uri.size(); ++i) {
        if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(uint8_t(uri[i + 1])) &&
            std::isxdigit(uint8_t(uri[i + 2]))) {
            out += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else {
            out += uri[i];
        }
    }
    return out;
}

std::string path_outside_root(const std::string& path, const std::string& root, const std::string& root_name) {
    if (is_within(resolved(path), resolved(root.empty() ? "." : root))) return {};
    return "a symbolic link leads out of " + root_name;
}

std::string outside_root_problem(const std::string& uri, const std::string& base_dir, const std::string& root,
                                 const std::string& root_name) {
    if (has_scheme(uri)) return "a URI with a scheme ('" + uri.substr(0, uri.find(':') + 1) + "'), not a relative path";
    const std::string decoded = percent_decoded(uri);
    if (!decoded.empty() && (decoded[0] == '/' || decoded[0] == '\\')) return "an absolute path";
    const fs::path folder = base_dir.empty() ? "." : base_dir;
    const fs::path top = root.empty() ? folder : fs::path(root);
    const fs::path joined = folder / decoded;
    if (!is_within(fs::absolute(joined).lexically_normal(), fs::absolute(top).lexically_normal()))
        return "a '..' leads out of " + root_name;
    if (!is_within(resolved(joined), resolved(top))) return "a symbolic link leads out of " + root_name;
    return {};
}

}  // namespace cb
