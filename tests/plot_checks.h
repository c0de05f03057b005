// Checks on the report's SVG plots that several test files make: point labels read back with their boxes,
// and no label over another label or over a marker.
#pragma once

#include <gtest/gtest.h>

#include <regex>
#include <string>
#include <vector>

#include "svg_plot.h"

namespace cb::test {

struct SvgLabel {
    double x, y;
    std::string text;
};

// How many times `what` occurs in `text`, not overlapping.
inline size_t count_of(const std::string& text, const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
    return n;
}

inline std::vector<SvgLabel> labels_of(const std::string& svg) {
    std::vector<SvgLabel> out;
    std::regex label("<text class=\"config-label\" x=\"([-0-9.]+)\" y=\"([-0-9.]+)\"[^>]*>([^<]*)</text>");
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), label); it != std::sregex_iterator(); ++it)
        out.push_back({std::stod((*it)[1]), std::stod((*it)[2]), (*it)[3]});
    return out;
}

struct SvgCircle {
    double x, y, r;
};

// The circles, and the circles that hold the other markers (squares, diamonds, triangles).
inline std::vector<SvgCircle> circles_of(const std::string& svg) {
    std::vector<SvgCircle> out;
    for (const char* pattern :
         {"<circle[^>]* cx=\"([-0-9.]+)\" cy=\"([-0-9.]+)\" r=\"([-0-9.]+)\"",
          "<path class=\"marker\" data-cx=\"([-0-9.]+)\" data-cy=\"([-0-9.]+)\" data-r=\"([-0-9.]+)\""}) {
        std::regex shape(pattern);
        for (auto it = std::sregex_iterator(svg.begin(), svg.end(), shape); it != std::sregex_iterator(); ++it)
            out.push_back({std::stod((*it)[1]), std::stod((*it)[2]), std::stod((*it)[3])});
    }
    return out;
}

// Every label box of the plot apart from every other and from every marker and ring of another point
// (the legend's samples are outside the plot area, where no label goes). Returns the number of labels.
inline size_t expect_labels_clear(const std::string& svg) {
    std::string legend_free = svg.substr(0, svg.find("<g class=\"legend\">"));
    std::vector<SvgLabel> labels = labels_of(legend_free);
    std::vector<SvgCircle> circles = circles_of(legend_free);
    std::vector<cb::TextBox> boxes;
    for (const SvgLabel& l : labels) boxes.push_back(cb::label_box(l.x, l.y, l.text, cb::point_label_font));
    for (size_t i = 0; i < boxes.size(); ++i) {
        for (size_t j = i + 1; j < boxes.size(); ++j)
            EXPECT_FALSE(boxes[i].overlaps(boxes[j])) << labels[i].text << " and " << labels[j].text;
        for (const SvgCircle& c : circles)
            EXPECT_FALSE(boxes[i].overlaps({c.x - c.r, c.y - c.r, 2 * c.r, 2 * c.r}))
                << "label " << labels[i].text << " covers a marker at " << c.x << ", " << c.y;
    }
    return labels.size();
}

}  // namespace cb::test
