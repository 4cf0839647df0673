// SPDX-License-Identifier: Apache-2.0
// levelforge — small helpers for error messages (internal to the library's .cc files).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>

namespace levelforge::message_internal {

/// A printable, shortened ('...'-terminated beyond 40 characters) single-quoted copy of text
/// read from a file, for error messages: non-printable bytes become '?'.
inline std::string quotedExcerpt(std::string_view s)
{
    constexpr size_t kMax = 40;
    std::string out = "'";
    for (size_t i = 0; i < s.size() && i < kMax; ++i) {
        const unsigned char c = static_cast<unsigned char>(s[i]);
        out += (c >= 32 && c < 127) ? char(c) : '?';
    }
    if (s.size() > kMax) out += "...";
    return out + "'";
}

/// @p n with thousands separators: 3221225472 -> "3,221,225,472".
inline std::string groupedCount(uint64_t n)
{
    const std::string digits = std::to_string(n);
    std::string out;
    out.reserve(digits.size() + digits.size() / 3);
    for (size_t i = 0; i < digits.size(); ++i) {
        if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
        out += digits[i];
    }
    return out;
}

/// A byte count for people: "1 byte", "9,999 bytes", then decimal units with one digit
/// after the point: "7.1 MB" (7,109,137 bytes), "3.2 GB" (3,221,225,472 bytes).
inline std::string byteSize(uint64_t n)
{
    if (n == 1) return "1 byte";
    if (n < 10000) return groupedCount(n) + " bytes";
    static const char* const kUnits[] = {"kB", "MB", "GB", "TB", "PB", "EB"};
    double v = double(n) / 1000.0;
    int unit = 0;
    while (v >= 999.95 && unit < 5) {
        v /= 1000.0;
        ++unit;
    }
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f %s", v, kUnits[unit]);
    return buf;
}

/// The text of an exception that a dependency threw (OpenVDB, zlib, Blosc, OpenMesh, the
/// standard library), made safe to copy into one of our messages: at most @p max bytes of it
/// are kept (never splitting a UTF-8 sequence), control characters become '?' (line breaks and
/// tabs a space), and a cut text ends with "... (message cut, 3.2 GB in all)". A corrupt
/// file can make a dependency build a message of gigabytes (an unchecked length read from
/// the file); this copies only the first @p max bytes (the length is still measured once).
/// @p what may be null ("unknown error").
inline std::string cutDependencyMessage(const char* what, size_t max = 500)
{
    if (!what) return "unknown error";
    const size_t total = std::strlen(what);
    size_t keep = total <= max ? total : max;
    if (keep < total) {
        // Do not split a UTF-8 sequence: back up over continuation bytes (10xxxxxx) and the
        // lead byte they belong to.
        size_t k = keep;
        while (k > 0 && (static_cast<unsigned char>(what[k]) & 0xC0) == 0x80) --k;
        keep = k;
    }
    std::string out;
    out.reserve(keep + 48);
    for (size_t i = 0; i < keep; ++i) {
        const unsigned char c = static_cast<unsigned char>(what[i]);
        if (c == '\n' || c == '\r' || c == '\t') out += ' ';
        else if (c < 32 || c == 127) out += '?';
        else out += char(c);
    }
    if (keep < total) out += "... (message cut, " + byteSize(total) + " in all)";
    return out;
}

/// cutDependencyMessage() of a std::string.
inline std::string cutDependencyMessage(const std::string& what, size_t max = 500)
{
    return cutDependencyMessage(what.c_str(), max);
}

} // namespace levelforge::message_internal
