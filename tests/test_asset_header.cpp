// The asset's header and section table are covered by the checksum (docs/FORMAT.md): any change to one of
// their bytes is refused, and so are non-zero reserved bytes even under a checksum made right.
#include <gtest/gtest.h>

#include <cb_asset.h>

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <string>
#include <vector>

#include "baked.h"

namespace {

// The default scene's asset bytes, in storage the view may read in place.
std::vector<uint64_t> default_asset(size_t& size) {
    cb::test::Baked b = cb::test::bake(std::string(CB_SOURCE_DIR) + "/data/default_scene.glb");
    size = b.size;
    std::vector<uint64_t> storage((size + 7) / 8);
    std::memcpy(storage.data(), b.data(), size);
    return storage;
}

}  // namespace

TEST(AssetHeader, EveryChangedHeaderOrTableByteIsRefused) {
    size_t size = 0;
    std::vector<uint64_t> storage = default_asset(size);
    uint8_t* bytes = reinterpret_cast<uint8_t*>(storage.data());
    cb::AssetView view;
    ASSERT_EQ(cb::open_asset(bytes, size, &view), cb::AssetError::ok);
    cb::AssetHeader h;
    std::memcpy(&h, bytes, sizeof h);
    const size_t table_end = sizeof(cb::AssetHeader) + size_t(h.section_count) * sizeof(cb::SectionEntry);
    ASSERT_GT(h.section_count, 7u);
    size_t tried = 0;
    for (size_t i = 0; i < table_end; ++i)
        for (uint8_t flip : {uint8_t(0x01), uint8_t(0x80), uint8_t(0xff)}) {
            bytes[i] ^= flip;
            EXPECT_NE(cb::open_asset(bytes, size, &view), cb::AssetError::ok) << "byte " << i << " xor " << int(flip);
            bytes[i] ^= flip;
            ++tried;
        }
    EXPECT_EQ(tried, table_end * 3);
    // Fewer sections in the table (the trailing optional ones dropped): the checksum no longer matches.
    cb::AssetHeader fewer = h;
    fewer.section_count -= 2;
    std::memcpy(bytes, &fewer, sizeof fewer);
    EXPECT_EQ(cb::open_asset(bytes, size, &view), cb::AssetError::bad_checksum);
    std::memcpy(bytes, &h, sizeof h);
    ASSERT_EQ(cb::open_asset(bytes, size, &view), cb::AssetError::ok);
}

TEST(AssetHeader, ReservedBytesMustBeZeroEvenUnderAGoodChecksum) {
    size_t size = 0;
    std::vector<uint64_t> storage = default_asset(size);
    uint8_t* bytes = reinterpret_cast<uint8_t*>(storage.data());
    cb::AssetView view;
    for (size_t i = offsetof(cb::AssetHeader, reserved); i < sizeof(cb::AssetHeader); ++i) {
        bytes[i] = 1;
        const uint64_t sum = cb::asset_checksum(bytes, size);
        std::memcpy(bytes + offsetof(cb::AssetHeader, checksum), &sum, 8);
        EXPECT_EQ(cb::open_asset(bytes, size, &view), cb::AssetError::bad_header) << "reserved byte " << i;
        bytes[i] = 0;
    }
    const uint64_t sum = cb::asset_checksum(bytes, size);
    std::memcpy(bytes + offsetof(cb::AssetHeader, checksum), &sum, 8);
    EXPECT_EQ(cb::open_asset(bytes, size, &view), cb::AssetError::ok);
}

// The checksum is a stream: fed in pieces of any size, cut anywhere in a stripe, it is the checksum of the
// whole. A flipped bit anywhere in the stream changes it, and so does a zero byte more at the end (the
// zero padding of the last stripe must not hide the length).
TEST(AssetHeader, ChecksumOfPiecesIsTheChecksumOfTheWhole) {
    std::vector<uint8_t> bytes(301);
    for (size_t i = 0; i < bytes.size(); ++i) bytes[i] = uint8_t(i * 37 + 11);
    cb::AssetChecksum whole;
    whole.add(bytes.data(), bytes.size());
    const uint64_t expected = whole.finish();
    for (size_t piece : {size_t(1), size_t(3), size_t(8), size_t(31), size_t(32), size_t(33), size_t(100)}) {
        cb::AssetChecksum sum;
        for (size_t at = 0; at < bytes.size(); at += piece)
            sum.add(bytes.data() + at, std::min(piece, bytes.size() - at));
        EXPECT_EQ(sum.finish(), expected) << "pieces of " << piece;
    }
    for (size_t i = 0; i < bytes.size(); ++i)
        for (int bit = 0; bit < 8; ++bit) {
            bytes[i] ^= uint8_t(1 << bit);
            cb::AssetChecksum sum;
            sum.add(bytes.data(), bytes.size());
            EXPECT_NE(sum.finish(), expected) << "byte " << i << " bit " << bit;
            bytes[i] ^= uint8_t(1 << bit);
        }
    bytes.push_back(0);
    cb::AssetChecksum longer;
    longer.add(bytes.data(), bytes.size());
    EXPECT_NE(longer.finish(), expected);
}
