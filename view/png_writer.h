// A minimal PNG encoder: 8-bit RGB, one IDAT compressed with zlib, our own chunk framing and CRCs.
#pragma once

#include <cstdint>
#include <vector>

namespace cb {

// `rgb` holds width * height * 3 bytes, rows top to bottom.
std::vector<uint8_t> encode_png_rgb(const uint8_t* rgb, uint32_t width, uint32_t height);

}  // namespace cb
