// Scatter plots as inline SVG for the HTML report, drawn by our own code: axes with ticks and labels (log
// scale where the values span decades), one marker per point in its method's colour (filled or hollow, of
// four shapes), the Pareto front (lower is better on both axes) joined by a line and ringed, the
// recommended point marked, and labels placed where they cover no other label or marker.
#pragma once

#include <string>
#include <vector>

namespace cb {

struct PlotPoint {
    double x = 0, y = 0;
    std::string label;         // tooltip and data-config attribute
    std::string tag;           // short text drawn beside the marker
    int colour = 0;            // index into the plot palette
    bool hollow = false;       // a second marker style
    bool recommended = false;  // ringed in gold and labelled "recommended"
    int shape = 0;             // a third: 0 circle, 1 square, 2 diamond, 3 triangle
};

struct Plot {
    std::string title, x_label, y_label;
    std::vector<PlotPoint> points;
    bool log_x = false;  // forces a log x axis; either axis is log anyway when wants_log_axis says so
};

// True when the values are all positive and the largest is more than 10 times the smallest: a linear axis
// would crowd the small ones into its first tick.
bool wants_log_axis(const std::vector<double>& values);

// Indices of the points no other point beats on both coordinates (minimising both), sorted by x.
std::vector<size_t> pareto_front(const std::vector<PlotPoint>& points);

// A text's box in SVG pixels (top-left corner and size), as the plots estimate it to keep labels apart:
// start-anchored at x, baseline at y, 0.66 em a character (wider than a sans-serif digit or letter on average).
struct TextBox {
    double x = 0, y = 0, w = 0, h = 0;
    bool overlaps(const TextBox& o) const { return x < o.x + o.w && o.x < x + w && y < o.y + o.h && o.y < y + h; }
};
TextBox label_box(double x, double baseline, const std::string& text, double font_size);

// The font size of point labels; each is a <text class="point-label"> start-anchored at its box's x.
constexpr double point_label_font = 9;

// A self-contained <svg> element, `width` x `height` pixels. Legend entries name the colours, the styles
// (filled, hollow) and the shapes. A marker other than a circle is a <path class="marker"> whose data-cx,
// data-cy and data-r give the circle that holds it.
std::string svg_scatter(const Plot& plot, const std::vector<std::string>& colour_names,
                        const std::vector<std::string>& style_names, const std::vector<std::string>& shape_names = {},
                        int width = 600, int height = 420);

// Escapes &, <, >, " for HTML and SVG text.
std::string html_escape(const std::string& s);

}  // namespace cb
