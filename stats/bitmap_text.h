// Labels inside PNG pictures: an 8-bit RGB raster with filled rectangles and text in a 5 x 7 pixel font
// of our own (digits, capital letters, a few symbols), scaled by whole pixels so it stays crisp.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cb {

struct Colour {
    uint8_t r = 0, g = 0, b = 0;
    bool operator==(const Colour&) const = default;
};

struct RgbImage {
    uint32_t width = 0, height = 0;
    std::vector<uint8_t> pixels;  // rgb, rows top to bottom

    RgbImage() = default;
    RgbImage(uint32_t width, uint32_t height, Colour background);
    Colour get(uint32_t x, uint32_t y) const;
    void set(int x, int y, Colour c);                 // a pixel outside the image is ignored
    void fill(int x, int y, int w, int h, Colour c);  // clipped to the image
};

// One glyph is 5 x 7 cells; characters sit 6 cells apart, lines read well 9 cells apart.
constexpr int glyph_columns = 5, glyph_rows = 7, glyph_advance = 6;

// True for the characters the font draws; lower-case letters count, as they are drawn as capitals.
bool has_glyph(char c);

// Pixels `text` spans at `scale` (cells of scale x scale pixels), without the gap after its last character.
int text_width(const std::string& text, int scale);

// Draws `text` with its top-left corner at (x, y); a character without a glyph is drawn as '?'.
void draw_text(RgbImage& image, int x, int y, const std::string& text, int scale, Colour ink);

// The same text ringed by one pixel of `outline`, legible over any colour.
void draw_text_outlined(RgbImage& image, int x, int y, const std::string& text, int scale, Colour ink, Colour outline);

}  // namespace cb
