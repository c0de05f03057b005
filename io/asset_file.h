// An asset's bytes held where the runtime can read them in place, and opened: the one way the tools turn a
// file, or bytes just encoded, into a cb::AssetView.
#pragma once

#include <cb_asset.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cb {

// The bytes copied into storage aligned as the asset's sections are (asset_alignment: 16 bytes; the view's
// instance doubles need 8), and the view over them. Moving keeps the view valid, as the storage moves with
// it; a copy's view would point into the original, so there are no copies.
struct LoadedAsset {
    struct alignas(asset_alignment) Block {
        uint8_t bytes[asset_alignment];
    };
    std::vector<Block> storage;
    size_t size = 0;  // bytes
    AssetView view;   // empty (mesh_count 0) unless the bytes opened

    LoadedAsset() = default;
    LoadedAsset(LoadedAsset&&) = default;
    LoadedAsset& operator=(LoadedAsset&&) = default;
    LoadedAsset(const LoadedAsset&) = delete;
    LoadedAsset& operator=(const LoadedAsset&) = delete;

    const uint8_t* data() const { return storage.empty() ? nullptr : storage[0].bytes; }
};

// Copies `size` bytes and opens them; returns what open_asset said.
AssetError open_asset_copy(const void* bytes, size_t size, LoadedAsset& out);
inline AssetError open_asset_copy(const std::vector<uint8_t>& bytes, LoadedAsset& out) {
    return open_asset_copy(bytes.data(), bytes.size(), out);
}

// Reads the file and opens it. False, with a one-line message naming the file in `error`, when it cannot
// be read ("FILE: cannot open") or is not a valid asset ("FILE: " and asset_error_text).
bool read_asset_file(const std::string& path, LoadedAsset& out, std::string& error);

// True when the file starts with the asset magic.
bool is_asset_file(const std::string& path);

}  // namespace cb
