// Scatter plots as inline SVG for the HTML report, drawn by our own code: axes with ticks and labels,
// one marker per point, and the Pareto front (lower is better on both axes) joined by a line.
#pragma once

#include <string>
#include <vector>

namespace cb {

struct PlotPoint {
    double x = 0, y = 0;
    std::string label;    // tooltip and data-config attribute
    std::string tag;      // short text drawn beside the marker
    int colour = 0;       // index into the plot palette
    bool hollow = false;  // a second marker style
};

struct Plot {
    std::string title, x_label, y_label;
    std::vector<PlotPoint> points;
    bool log_x = false;  // chosen automatically when the x values span more than 20x and are positive
};

// Indices of the points no other point beats on both coordinates (minimising both), sorted by x.
std::vector<size_t> pareto_front(const std::vector<PlotPoint>& points);

// A self-contained <svg> element, `width` x `height` pixels. Legend entries name the colours.
std::string svg_scatter(const Plot& plot, const std::vector<std::string>& colour_names,
                        const std::vector<std::string>& style_names, int width = 560, int height = 380);

// Escapes &, <, >, " for HTML and SVG text.
std::string html_escape(const std::string& s);

}  // namespace cb
