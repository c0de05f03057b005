// Line and number scanning shared by the text-format readers.
#pragma once

#include <algorithm>
#include <charconv>
#include <string>
#include <string_view>
#include <vector>

namespace cb {

struct LineReader {
    std::string_view text;
    size_t pos = 0;
    size_t line_number = 0;  // of the line last returned, 1-based

    // Next logical line without its comment; joins OBJ-style continuations when `join` is set.
    bool next(std::string& line, bool join) {
        line.clear();
        if (pos >= text.size()) return false;
        size_t first_line = line_number + 1;
        while (pos < text.size()) {
            size_t end = text.find('\n', pos);
            if (end == std::string_view::npos) end = text.size();
            std::string_view part = text.substr(pos, end - pos);
            pos = end < text.size() ? end + 1 : end;
            ++line_number;
            if (!part.empty() && part.back() == '\r') part.remove_suffix(1);
            if (join && !part.empty() && part.back() == '\\') {
                line.append(part.substr(0, part.size() - 1)).push_back(' ');
                continue;
            }
            line.append(part);
            break;
        }
        size_t hash = line.find('#');
        if (hash != std::string::npos) line.resize(hash);
        line_number = std::max(line_number, first_line);
        return true;
    }
};

// Splits on spaces and tabs.
inline void split(std::string_view s, std::vector<std::string_view>& out) {
    out.clear();
    size_t i = 0;
    while (i < s.size()) {
        while (i < s.size() && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r' || s[i] == '\f' || s[i] == '\v')) ++i;
        size_t j = i;
        while (j < s.size() && !(s[j] == ' ' || s[j] == '\t' || s[j] == '\r' || s[j] == '\f' || s[j] == '\v')) ++j;
        if (j > i) out.push_back(s.substr(i, j - i));
        i = j;
    }
}

inline bool parse_double(std::string_view s, double& v) {
    if (!s.empty() && s[0] == '+') s.remove_prefix(1);
    auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

inline bool parse_int(std::string_view s, long long& v) {
    if (!s.empty() && s[0] == '+') s.remove_prefix(1);
    auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// A token quoted for an error message: at most 40 characters, anything unprintable shown as '?', so the
// message stays one line of text whatever the file holds.
inline std::string quoted(std::string_view s) {
    std::string out = "'";
    for (char c : s.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
    return out + (s.size() > 40 ? "...'" : "'");
}

}  // namespace cb
