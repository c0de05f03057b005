// One progress line on a terminal's stderr, redrawn in place at most ten times a second: a bar, the count
// done, a rate, the time left and what is being worked on; or only the stage of work, where its share is not
// known. Does nothing when stderr is not a terminal.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

#include <unistd.h>

namespace cb::cli {

class ProgressLine {
public:
    explicit ProgressLine(bool wanted) : on_(wanted && isatty(STDERR_FILENO)) {}
    ~ProgressLine() { clear(); }

    bool on() const { return on_; }

    // A new stage: the time left is reckoned from now.
    void restart() { start_ = std::chrono::steady_clock::now(); }

    // `fraction` of the work (0 to 1) is done; `text` follows the bar.
    void show(double fraction, const std::string& text, bool force = false) {
        if (!on_) return;
        auto now = std::chrono::steady_clock::now();
        if (!force && now - last_ < std::chrono::milliseconds(100)) return;
        last_ = now;
        double elapsed = std::chrono::duration<double>(now - start_).count();
        char eta[32] = "--:--";
        if (fraction > 0.01 && elapsed > 1) {
            long left = long(elapsed * (1 - fraction) / fraction + 0.5);
            std::snprintf(eta, sizeof eta, "%ld:%02ld", left / 60, left % 60);
        }
        const int width = 24;
        int filled = int(fraction * width + 0.5);
        std::string bar = std::string(size_t(filled), '#') + std::string(size_t(width - filled), '.');
        draw("[" + bar + "] " + text + "  ETA " + eta);
    }

    // A stage of work whose share of the whole is unknown: `text` alone.
    void stage(const std::string& text) {
        if (on_) draw(text);
    }

    // Removes the line so that ordinary output can follow.
    void clear() {
        if (!drawn_) return;
        std::fprintf(stderr, "\r%119s\r", "");
        std::fflush(stderr);
        drawn_ = false;
    }

private:
    void draw(std::string line) {
        if (line.size() > 119) line = line.substr(0, 116) + "...";
        std::fprintf(stderr, "\r%-119s", line.c_str());
        std::fflush(stderr);
        drawn_ = true;
    }

    bool on_, drawn_ = false;
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now(), last_{};
};

}  // namespace cb::cli
