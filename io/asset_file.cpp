#include "asset_file.h"

#include <cstring>
#include <fstream>

#include "source_files.h"

namespace cb {

AssetError open_asset_copy(const void* bytes, size_t size, LoadedAsset& out) {
    out.size = size;
    out.storage.assign((size + asset_alignment - 1) / asset_alignment, LoadedAsset::Block{});
    if (size) std::memcpy(out.storage.data(), bytes, size);
    out.view = AssetView{};
    AssetError e = open_asset(out.data(), size, &out.view);
    if (e != AssetError::ok) out.view = AssetView{};
    return e;
}

bool read_asset_file(const std::string& path, LoadedAsset& out, std::string& error) {
    FileBytes raw;
    if (!raw.read(path, error)) return false;
    AssetError e = open_asset_copy(raw.data(), raw.size(), out);
    if (e != AssetError::ok) {
        error = path + ": " + asset_error_text(e);
        return false;
    }
    return true;
}

bool is_asset_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[8] = {};
    return in.read(magic, 8) && std::memcmp(magic, asset_magic, 8) == 0;
}

}  // namespace cb
