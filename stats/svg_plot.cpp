#include "svg_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace cb {
namespace {

const char* palette[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
const char* gold = "#d49b00";
const double marker_r = 5, pareto_r = 8.5, recommended_r = 12.5;  // marker, its Pareto ring, its gold ring

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

struct Tick {
    double value;
    bool numbered;  // a log axis over many decades numbers only its powers of ten
};

struct Axis {
    double lo, hi;
    bool log;
    std::vector<Tick> ticks;
    double map(double v, double a, double b) const {  // value -> pixel between a and b
        double t = log ? (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo)) : (v - lo) / (hi - lo);
        return a + t * (b - a);
    }
};

Axis make_axis(const std::vector<double>& values, bool log) {
    Axis a;
    a.log = log;
    double mn = *std::min_element(values.begin(), values.end()), mx = *std::max_element(values.begin(), values.end());
    if (log) {
        a.lo = std::pow(10, std::floor(std::log10(mn) * 20) / 20 - 0.05);
        a.hi = std::pow(10, std::ceil(std::log10(mx) * 20) / 20 + 0.05);
        // Over more than two decades, 1-2-5 numbers would crowd: number the decades, grid the rest.
        bool decades_only = std::log10(a.hi / a.lo) > 2.2;
        for (double decade = std::pow(10, std::floor(std::log10(a.lo))); decade <= a.hi; decade *= 10)
            for (double m : {1.0, 2.0, 5.0})
                if (m * decade >= a.lo && m * decade <= a.hi) a.ticks.push_back({m * decade, !decades_only || m == 1});
        return a;
    }
    if (mn >= 0 && mn < 0.35 * mx) mn = 0;
    if (mx - mn <= 0) {
        double pad = mx != 0 ? std::fabs(mx) * 0.1 : 1;
        mn -= pad;
        mx += pad;
    }
    double span = mx - mn, raw = span / 5, step = std::pow(10, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (m * step >= raw) {
            step *= m;
            break;
        }
    a.lo = mn == 0 ? 0 : std::floor((mn - 0.04 * span) / step) * step;
    a.hi = std::ceil((mx + 0.04 * span) / step) * step;
    for (double t = a.lo; t <= a.hi + step * 1e-9; t += step) a.ticks.push_back({t, true});
    return a;
}

std::string circle(double x, double y, double r, const std::string& fill, const std::string& stroke, double width,
                   const std::string& cls = "") {
    return "<circle" + (cls.empty() ? "" : " class=\"" + cls + "\"") + " cx=\"" + num(x) + "\" cy=\"" + num(y) +
        "\" r=\"" + num(r) + "\" fill=\"" + fill + "\" stroke=\"" + stroke + "\" stroke-width=\"" + num(width) + "\"/>";
}

// A point's marker: a circle of radius marker_r, or a square, diamond or triangle within a circle a little
// larger (their areas then look alike), for the plots' third style.
std::string marker(double x, double y, int shape, const std::string& fill, const std::string& stroke, double width) {
    if (shape <= 0 || shape > 3) return circle(x, y, marker_r, fill, stroke, width);
    const double r = marker_r + 0.5, h = r / std::sqrt(2.0);
    std::string d;
    if (shape == 1)
        d = "M" + num(x - h) + " " + num(y - h) + "H" + num(x + h) + "V" + num(y + h) + "H" + num(x - h) + "Z";
    else if (shape == 2)
        d = "M" + num(x) + " " + num(y - r) + "L" + num(x + r) + " " + num(y) + "L" + num(x) + " " + num(y + r) + "L" +
            num(x - r) + " " + num(y) + "Z";
    else
        d = "M" + num(x) + " " + num(y - r) + "L" + num(x + r * 0.866) + " " + num(y + r * 0.5) + "L" +
            num(x - r * 0.866) + " " + num(y + r * 0.5) + "Z";
    return "<path class=\"marker\" data-cx=\"" + num(x) + "\" data-cy=\"" + num(y) + "\" data-r=\"" + num(r) +
        "\" d=\"" + d + "\" fill=\"" + fill + "\" stroke=\"" + stroke + "\" stroke-width=\"" + num(width) +
        "\" stroke-linejoin=\"round\"/>";
}

// A label's place: its box, and whether it sits far enough from its marker to need a leader line.
struct Placed {
    TextBox box;
    bool leader = false;
};

// Tries, for each point in turn (the recommended one, then the Pareto front, then the rest), positions
// around its marker at three distances (right, left, above, below, then the diagonals) and takes the first
// whose box stays inside the plot area and, with a pixel to spare, clears every marker and every label
// placed before. A point with no such position keeps its tooltip only. Deterministic: no randomness.
std::vector<Placed> place_labels(const std::vector<PlotPoint>& points, const std::vector<double>& px,
                                 const std::vector<double>& py, const std::vector<double>& radius,
                                 const std::vector<std::string>& texts, const TextBox& area) {
    std::vector<TextBox> taken;
    for (size_t i = 0; i < points.size(); ++i)
        taken.push_back({px[i] - radius[i], py[i] - radius[i], 2 * radius[i], 2 * radius[i]});
    std::vector<size_t> order(points.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    auto rank = [&](size_t i) { return points[i].recommended ? 0 : radius[i] > marker_r + 1 ? 1 : 2; };
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return rank(a) < rank(b); });
    const int directions[8][2] = {{1, 0}, {-1, 0}, {0, -1}, {0, 1}, {1, -1}, {1, 1}, {-1, -1}, {-1, 1}};
    std::vector<Placed> out(points.size(), Placed{{0, 0, 0, 0}, false});
    for (size_t i : order) {
        if (texts[i].empty()) continue;
        TextBox size = label_box(0, 0, texts[i], point_label_font);
        bool done = false;
        for (int ring = 0; ring < 3 && !done; ++ring) {
            double d = radius[i] + 2 + 12 * ring;
            for (const auto& dir : directions) {
                double cx = px[i] + dir[0] * d, cy = py[i] + dir[1] * d;
                TextBox b{dir[0] > 0       ? cx
                              : dir[0] < 0 ? cx - size.w
                                           : cx - size.w / 2,
                          dir[1] > 0       ? cy
                              : dir[1] < 0 ? cy - size.h
                                           : cy - size.h / 2,
                          size.w, size.h};
                if (b.x < area.x || b.y < area.y || b.x + b.w > area.x + area.w || b.y + b.h > area.y + area.h)
                    continue;
                TextBox padded{b.x - 1, b.y - 1, b.w + 2, b.h + 2};
                bool clear = true;
                for (const TextBox& t : taken) clear = clear && !padded.overlaps(t);
                if (!clear) continue;
                out[i] = {b, ring > 0};
                taken.push_back(b);
                done = true;
                break;
            }
        }
    }
    return out;
}

}  // namespace

bool wants_log_axis(const std::vector<double>& values) {
    if (values.empty()) return false;
    double mn = *std::min_element(values.begin(), values.end()), mx = *std::max_element(values.begin(), values.end());
    return mn > 0 && mx > 10 * mn;
}

TextBox label_box(double x, double baseline, const std::string& text, double font_size) {
    return {x, baseline - 0.78 * font_size, 0.66 * font_size * double(text.size()), font_size};
}

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
                        const std::vector<std::string>& style_names, const std::vector<std::string>& shape_names,
                        int width, int height) {
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
    bool log_x = wants_log_axis(xs) || (plot.log_x && *std::min_element(xs.begin(), xs.end()) > 0);
    bool log_y = wants_log_axis(ys);
    Axis ax = make_axis(xs, log_x), ay = make_axis(ys, log_y);
    auto X = [&](double v) { return ax.map(v, left, right); };
    auto Y = [&](double v) { return ay.map(v, bottom, top); };

    // Axes: lines, ticks, grid, tick labels, axis labels; each axis says when it is logarithmic.
    s += "<g class=\"axis x-axis" + std::string(log_x ? " log" : "") + "\">\n<line x1=\"" + num(left) + "\" y1=\"" +
        num(bottom) + "\" x2=\"" + num(right) + "\" y2=\"" + num(bottom) + "\" stroke=\"#000\"/>\n";
    for (const Tick& t : ax.ticks) {
        s += "<line x1=\"" + num(X(t.value)) + "\" y1=\"" + num(top) + "\" x2=\"" + num(X(t.value)) + "\" y2=\"" +
            num(bottom + (t.numbered ? 5 : 0)) + "\" stroke=\"" + (t.numbered ? "#ddd" : "#eee") + "\"/>\n";
        if (t.numbered)
            s += "<text class=\"tick\" x=\"" + num(X(t.value)) + "\" y=\"" + num(bottom + 18) +
                "\" font-size=\"11\" text-anchor=\"middle\">" + tick_text(t.value) + "</text>\n";
    }
    s += "<text class=\"axis-label\" x=\"" + num((left + right) / 2) + "\" y=\"" + num(bottom + 38) +
        "\" font-size=\"12\" text-anchor=\"middle\">" + html_escape(plot.x_label + (log_x ? " (log scale)" : "")) +
        "</text>\n</g>\n";
    s += "<g class=\"axis y-axis" + std::string(log_y ? " log" : "") + "\">\n<line x1=\"" + num(left) + "\" y1=\"" +
        num(top) + "\" x2=\"" + num(left) + "\" y2=\"" + num(bottom) + "\" stroke=\"#000\"/>\n";
    for (const Tick& t : ay.ticks) {
        s += "<line x1=\"" + num(left - (t.numbered ? 5 : 0)) + "\" y1=\"" + num(Y(t.value)) + "\" x2=\"" + num(right) +
            "\" y2=\"" + num(Y(t.value)) + "\" stroke=\"" + (t.numbered ? "#ddd" : "#eee") + "\"/>\n";
        if (t.numbered)
            s += "<text class=\"tick\" x=\"" + num(left - 8) + "\" y=\"" + num(Y(t.value) + 4) +
                "\" font-size=\"11\" text-anchor=\"end\">" + tick_text(t.value) + "</text>\n";
    }
    s += "<text class=\"axis-label\" x=\"16\" y=\"" + num((top + bottom) / 2) +
        "\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 16 " + num((top + bottom) / 2) + ")\">" +
        html_escape(plot.y_label + (log_y ? " (log scale)" : "")) + "</text>\n</g>\n";

    // The Pareto front under the markers.
    std::vector<size_t> front = pareto_front(plot.points);
    std::vector<bool> on_front(plot.points.size(), false);
    s += "<polyline class=\"pareto-front\" fill=\"none\" stroke=\"#444\" stroke-dasharray=\"4 3\" points=\"";
    for (size_t i : front) {
        s += num(X(plot.points[i].x)) + "," + num(Y(plot.points[i].y)) + " ";
        on_front[i] = true;
    }
    s += "\"/>\n";

    // Markers keep their method's colour; the front is ringed in dark grey, the recommendation in gold.
    std::vector<double> px, py, radius;
    std::vector<std::string> texts;
    for (size_t i = 0; i < plot.points.size(); ++i) {
        const PlotPoint& p = plot.points[i];
        px.push_back(X(p.x)), py.push_back(Y(p.y));
        radius.push_back(p.recommended ? recommended_r + 1.5 : on_front[i] ? pareto_r + 0.75 : marker_r + 0.75);
        texts.push_back(p.recommended ? (p.tag.empty() ? "" : p.tag + ", ") + "recommended" : p.tag);
        const std::string c = palette[p.colour % 6];
        s += "<g class=\"point" + std::string(on_front[i] ? " pareto" : "") + (p.recommended ? " recommended" : "") +
            "\" data-config=\"" + html_escape(p.label) + "\"><title>" + html_escape(p.label) +
            (p.recommended ? " (recommended)" : "") + "</title>";
        if (p.recommended) s += circle(px[i], py[i], recommended_r, "none", gold, 3, "recommended-ring");
        if (on_front[i]) s += circle(px[i], py[i], pareto_r, "none", "#222", 1.5, "pareto-ring");
        s += marker(px[i], py[i], p.shape, p.hollow ? "#fff" : c, c, p.hollow ? 2 : 1.5);
        s += "</g>\n";
    }
    std::vector<Placed> labels =
        place_labels(plot.points, px, py, radius, texts, {left, top, right - left, bottom - top});
    s += "<g class=\"labels\">\n";
    for (size_t i = 0; i < labels.size(); ++i) {
        const TextBox& b = labels[i].box;
        if (b.w == 0) continue;
        if (labels[i].leader) {  // from the marker's edge to the nearest point of the label's box
            double tx = std::clamp(px[i], b.x, b.x + b.w), ty = std::clamp(py[i], b.y, b.y + b.h);
            double dx = tx - px[i], dy = ty - py[i], len = std::max(1e-9, std::hypot(dx, dy));
            s += "<line class=\"leader\" x1=\"" + num(px[i] + dx / len * radius[i]) + "\" y1=\"" +
                num(py[i] + dy / len * radius[i]) + "\" x2=\"" + num(tx) + "\" y2=\"" + num(ty) +
                "\" stroke=\"#999\" stroke-width=\"0.8\"/>\n";
        }
        s += "<text class=\"config-label\" x=\"" + num(b.x) + "\" y=\"" + num(b.y + 0.78 * point_label_font) +
            "\" font-size=\"" + num(point_label_font) + "\" fill=\"" +
            (plot.points[i].recommended ? "#7a5600" : "#444") + "\">" + html_escape(texts[i]) + "</text>\n";
    }
    s += "</g>\n";

    // Legend.
    double ly = top + 6, lx = right + 22;
    s += "<g class=\"legend\">\n";
    auto entry = [&](const std::string& sample, const std::string& text) {
        s += sample + "<text x=\"" + num(right + 40) + "\" y=\"" + num(ly + 4) + "\" font-size=\"11\">" +
            html_escape(text) + "</text>\n";
        ly += 20;
    };
    for (size_t i = 0; i < colour_names.size(); ++i)
        entry(circle(lx, ly, marker_r, palette[i % 6], palette[i % 6], 1.5), colour_names[i]);
    for (size_t i = 0; i < style_names.size(); ++i)
        entry(circle(lx, ly, marker_r, i ? "#fff" : "#888", "#888", i ? 2 : 1.5), style_names[i]);
    for (size_t i = 0; i < shape_names.size(); ++i) entry(marker(lx, ly, int(i), "#888", "#888", 1.5), shape_names[i]);
    entry("<line x1=\"" + num(lx - 10) + "\" y1=\"" + num(ly) + "\" x2=\"" + num(lx + 10) + "\" y2=\"" + num(ly) +
              "\" stroke=\"#444\" stroke-dasharray=\"4 3\"/>" + circle(lx, ly, pareto_r, "none", "#222", 1.5),
          "Pareto front");
    entry(circle(lx, ly, 7, "none", gold, 3), "recommended");
    s += "<text x=\"" + num(right + 12) + "\" y=\"" + num(ly + 4) +
        "\" font-size=\"10\" fill=\"#555\">labels: fine size</text>\n";
    s += "</g>\n</svg>\n";
    return s;
}

}  // namespace cb
