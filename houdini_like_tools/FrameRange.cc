// SPDX-License-Identifier: Apache-2.0
// levelforge operators — frame ranges and frame tokens (see FrameRange.h).
#include "FrameRange.h"

#include "Operator.h" // UsageError

#include <cctype>
#include <cstdio>
#include <limits>
#include <regex>

namespace levelforge::ops {
namespace {

/// One token found at text[pos]: its length and its padding width (0: none); length 0 if none.
struct Token
{
    size_t length = 0;
    int width = 0;
    bool literal = false; ///< "$$" or "%%"
};

Token tokenAt(const std::string& s, size_t pos)
{
    Token t;
    const auto digit = [&](size_t i) { return i < s.size() && std::isdigit(static_cast<unsigned char>(s[i])); };
    const auto word = [&](size_t i) {
        return i < s.size() && (std::isalnum(static_cast<unsigned char>(s[i])) || s[i] == '_');
    };
    if (s[pos] == '$') {
        if (pos + 1 < s.size() && s[pos + 1] == '$') return Token{2, 0, true};
        if (s.compare(pos, 4, "${F}") == 0) return Token{4, 0, false};
        if (pos + 1 < s.size() && s[pos + 1] == 'F') {
            size_t i = pos + 2;
            if (digit(i) && s[i] != '0' && !word(i + 1)) return Token{3, s[i] - '0', false};
            if (!word(i)) return Token{2, 0, false};
        }
    } else if (s[pos] == '%') {
        if (pos + 1 < s.size() && s[pos + 1] == '%') return Token{2, 0, true};
        if (pos + 1 < s.size() && s[pos + 1] == 'd') return Token{2, 0, false};
        if (s.compare(pos + 1, 1, "0") == 0 && digit(pos + 2) && s[pos + 2] != '0' && pos + 3 < s.size() &&
            s[pos + 3] == 'd')
            return Token{4, s[pos + 2] - '0', false};
    }
    return t;
}

} // namespace

std::vector<int> FrameRange::frames() const
{
    std::vector<int> f;
    for (long long i = first; i <= last; i += step) f.push_back(int(i));
    return f;
}

std::string FrameRange::text() const
{
    std::string s = std::to_string(first);
    if (last != first) s += "-" + std::to_string(last);
    if (step != 1) s += ":" + std::to_string(step);
    return s;
}

FrameRange parseFrameRange(const std::string& text)
{
    static const std::regex pattern(R"(^\s*(-?\d{1,9})(?:\s*-\s*(-?\d{1,9}))?(?:\s*:\s*(\d{1,9}))?\s*$)");
    std::smatch m;
    const std::string bad = "invalid value '" + text + "' for --frames (Frame Range): ";
    if (!std::regex_match(text, m, pattern)) throw UsageError(bad + "expected A, A-B or A-B:step, e.g. 1-240:2");
    FrameRange r;
    r.first = std::stoi(m[1].str());
    r.last = m[2].matched ? std::stoi(m[2].str()) : r.first;
    r.step = m[3].matched ? std::stoi(m[3].str()) : 1;
    if (r.last < r.first) throw UsageError(bad + "the last frame is before the first");
    if (r.step < 1) throw UsageError(bad + "the step must be at least 1");
    if ((long long)(r.last) - r.first >= 1000000LL * r.step) throw UsageError(bad + "more than 1,000,000 frames");
    return r;
}

bool hasFrameToken(const std::string& text)
{
    for (size_t i = 0; i < text.size(); ++i) {
        const Token t = tokenAt(text, i);
        if (t.length && !t.literal) return true;
        if (t.length) i += t.length - 1;
    }
    return false;
}

std::string substituteFrame(const std::string& text, int frame)
{
    if (!hasFrameToken(text)) return text;
    std::string out;
    for (size_t i = 0; i < text.size();) {
        const Token t = tokenAt(text, i);
        if (!t.length) {
            out += text[i++];
            continue;
        }
        if (t.literal) {
            out += text[i];
        } else {
            char buf[32];
            std::snprintf(buf, sizeof buf, "%0*d", t.width, frame);
            out += buf;
        }
        i += t.length;
    }
    return out;
}

} // namespace levelforge::ops
