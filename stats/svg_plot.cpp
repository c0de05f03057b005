#include "svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace cb {
namespace {

const char* palette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};

std::string num(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f", v);
    return buf;
}

std::string tick_text(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", std::fabs(v) < 1e-12 ? 0.0 : v);
    return buf;
}

struct Axis {
    double lo, hi;
    bool log;
    std::vector<double> ticks;
    double map(double v, double a, double b) const {  // value -> pixel between a and b
        double t = log ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)) : (v - lo) / (hi - lo);
        return a + t * (b - a);
    }
};

Axis make_axis(std::vector<double> values, bool log) {
    Axis a;
    a.log = log;
    double mn = *std::min_element(values.begin(), values.end()), mx = *std::max_element(values.begin(), values.end());
    if (log) {
        a.lo = std::pow(10, std::floor(std::log10(mn) * 20) / 20 - 0.05);
        a.hi = std::pow(10, std::ceil(std::log10(mx) * 20) / 20 + 0.05);
        for (double decade = std::pow(10, std::floor(std::log10(a.lo))); decade <= a.hi; decade *= 10)
            for (double m : {1.0, 2.0, 5.0})
                if (m * decade >= a.lo && m * decade <= a.hi) a.ticks.push_back(m * decade);
        return a;
    }
    if (mn >= 0 && mn < 0.35 * mx) mn = 0;
    if (mx - mn <= 0) {
        double pad = mx != 0 ? std::fabs(mx) * 0.1 : 1;
        mn -= pad, mx += pad;
    }
    double span = mx - mn, raw = span / 5, step = std::pow(10, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * step >= raw) {
            step *= m;
            break;
        }
    a.lo = mn == 0 ? 0 : std::floor((mn - 0.04 * span) / step) * step;
    a.hi = std::ceil((mx + 0.04 * span) / step) * step;
    for (double t = a.lo; t <= a.hi + step * 1e-9; t += step) a.ticks.push_back(t);
    return a;
}

}  // namespace

std::string html_escape(const std::string& s) {
    std::string out;
    for (char c : s) {
        if (c == '&')
            out += "&amp;";
        else if (c == '<')
            out += "&lt;";
        else if (c == '>')
            out += "&gt;";
        else if (c == '"')
            out += "&quot;";
        else
            out += c;
    }
    return out;
}

std::vector<size_t> pareto_front(const std::vector<PlotPoint>& p) {
    std::vector<size_t> front;
    for (size_t i = 0; i < p.size(); ++i) {
        bool beaten = false;
        for (size_t j = 0; j < p.size() && !beaten; ++j)
            beaten = j != i && p[j].x <= p[i].x && p[j].y <= p[i].y && (p[j].x < p[i].x || p[j].y < p[i].y);
        if (!beaten) front.push_back(i);
    }
    std::sort(front.begin(), front.end(),
              [&](size_t a, size_t b) { return p[a].x < p[b].x || (p[a].x == p[b].x && p[a].y < p[b].y); });
    return front;
}

std::string svg_scatter(const Plot& plot, const std::vector<std::string>& colour_names,
                        const std::vector<std::string>& style_names, int width, int height) {
    const double left = 70, right = width - 150, top = 34, bottom = height - 52;
    std::string s = "<svg class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(width) +
        "\" height=\"" + std::to_string(height) + "\" viewBox=\"0 0 " + std::to_string(width) + " " +
        std::to_string(height) + "\" role=\"img\" aria-label=\"" + html_escape(plot.title) + "\">\n";
    s += "<title>" + html_escape(plot.title) + "</title>\n";
    s += "<rect x=\"0\" y=\"0\" width=\"" + std::to_string(width) + "\" height=\"" + std::to_string(height) +
        "\" fill=\"#ffffff\"/>\n";
    s += "<text class=\"plot-title\" x=\"" + num(left) + "\" y=\"20\" font-size=\"14\" font-weight=\"bold\">" +
        html_escape(plot.title) + "</text>\n";
    if (plot.points.empty())
        return s + "<text x=\"" + num(left) + "\" y=\"" + num(top + 40) + "\">no data</text>\n</svg>\n";

    std::vector<double> xs, ys;
    for (const PlotPoint& p : plot.points) xs.push_back(p.x), ys.push_back(p.y);
    bool positive = *std::min_element(xs.begin(), xs.end()) > 0;
    bool log_x = plot.log_x ||
        (positive && *std::max_element(xs.begin(), xs.end()) > 20 * *std::min_element(xs.begin(), xs.end()));
    Axis ax = make_axis(xs, log_x), ay = make_axis(ys, false);
    auto X = [&](double v) { return ax.map(v, left, right); };
    auto Y = [&](double v) { return ay.map(v, bottom, top); };

    // Axes: lines, ticks, grid, tick labels, axis labels.
    s += "<g class=\"axis x-axis\">\n<line x1=\"" + num(left) + "\" y1=\"" + num(bottom) + "\" x2=\"" + num(right) +
        "\" y2=\"" + num(bottom) + "\" stroke=\"#000\"/>\n";
    for (double t : ax.ticks) {
        s += "<line x1=\"" + num(X(t)) + "\" y1=\"" + num(top) + "\" x2=\"" + num(X(t)) + "\" y2=\"" + num(bottom + 5) +
            "\" stroke=\"#ddd\"/>\n";
        s += "<text class=\"tick\" x=\"" + num(X(t)) + "\" y=\"" + num(bottom + 18) +
            "\" font-size=\"11\" text-anchor=\"middle\">" + tick_text(t) + "</text>\n";
    }
    s += "<text class=\"axis-label\" x=\"" + num((left + right) / 2) + "\" y=\"" + num(bottom + 38) +
        "\" font-size=\"12\" text-anchor=\"middle\">" + html_escape(plot.x_label + (log_x ? " (log scale)" : "")) +
        "</text>\n</g>\n";
    s += "<g class=\"axis y-axis\">\n<line x1=\"" + num(left) + "\" y1=\"" + num(top) + "\" x2=\"" + num(left) +
        "\" y2=\"" + num(bottom) + "\" stroke=\"#000\"/>\n";
    for (double t : ay.ticks) {
        s += "<line x1=\"" + num(left - 5) + "\" y1=\"" + num(Y(t)) + "\" x2=\"" + num(right) + "\" y2=\"" + num(Y(t)) +
            "\" stroke=\"#ddd\"/>\n";
        s += "<text class=\"tick\" x=\"" + num(left - 8) + "\" y=\"" + num(Y(t) + 4) +
            "\" font-size=\"11\" text-anchor=\"end\">" + tick_text(t) + "</text>\n";
    }
    s += "<text class=\"axis-label\" x=\"16\" y=\"" + num((top + bottom) / 2) +
        "\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 16 " + num((top + bottom) / 2) + ")\">" +
        html_escape(plot.y_label) + "</text>\n</g>\n";

    // The Pareto front under the markers.
    std::vector<size_t> front = pareto_front(plot.points);
    std::vector<bool> on_front(plot.points.size(), false);
    s += "<polyline class=\"pareto-front\" fill=\"none\" stroke=\"#444\" stroke-dasharray=\"4 3\" points=\"";
    for (size_t i : front) s += num(X(plot.points[i].x)) + "," + num(Y(plot.points[i].y)) + " ", on_front[i] = true;
    s += "\"/>\n";
    for (size_t i = 0; i < plot.points.size(); ++i) {
        const PlotPoint& p = plot.points[i];
        const char* c = palette[p.colour % 6];
        s += "<g class=\"point" + std::string(on_front[i] ? " pareto" : "") + "\" data-config=\"" +
            html_escape(p.label) + "\">";
        s += "<circle cx=\"" + num(X(p.x)) + "\" cy=\"" + num(Y(p.y)) + "\" r=\"" + (on_front[i] ? "6" : "4.5") +
            "\" fill=\"" + (p.hollow ? "#fff" : c) + "\" stroke=\"" + (on_front[i] ? "#000" : c) +
            "\" stroke-width=\"" + (on_front[i] ? "2" : "1.5") + "\"><title>" + html_escape(p.label) +
            "</title></circle>";
        if (!p.tag.empty())
            s += "<text x=\"" + num(X(p.x) + 7) + "\" y=\"" + num(Y(p.y) - 5) + "\" font-size=\"9\" fill=\"#555\">" +
                html_escape(p.tag) + "</text>";
        s += "</g>\n";
    }
    // Legend.
    double ly = top + 6;
    s += "<g class=\"legend\">\n";
    for (size_t i = 0; i < colour_names.size(); ++i, ly += 18)
        s += "<circle cx=\"" + num(right + 22) + "\" cy=\"" + num(ly) + "\" r=\"5\" fill=\"" + palette[i % 6] +
            "\"/><text x=\"" + num(right + 32) + "\" y=\"" + num(ly + 4) + "\" font-size=\"11\">" +
            html_escape(colour_names[i]) + "</text>\n";
    for (size_t i = 0; i < style_names.size(); ++i, ly += 18)
        s += "<circle cx=\"" + num(right + 22) + "\" cy=\"" + num(ly) + "\" r=\"5\" fill=\"" + (i ? "#fff" : "#888") +
            "\" stroke=\"#888\" stroke-width=\"1.5\"/><text x=\"" + num(right + 32) + "\" y=\"" + num(ly + 4) +
            "\" font-size=\"11\">" + html_escape(style_names[i]) + "</text>\n";
    s += "<line x1=\"" + num(right + 14) + "\" y1=\"" + num(ly) + "\" x2=\"" + num(right + 30) + "\" y2=\"" + num(ly) +
        "\" stroke=\"#444\" stroke-dasharray=\"4 3\"/><text x=\"" + num(right + 34) + "\" y=\"" + num(ly + 4) +
        "\" font-size=\"11\">Pareto front</text>\n";
    s += "<text x=\"" + num(right + 14) + "\" y=\"" + num(ly + 20) +
        "\" font-size=\"10\" fill=\"#555\">labels: fine size</text>\n";
    s += "</g>\n</svg>\n";
    return s;
}

}  // namespace cb
