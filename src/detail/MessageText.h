// SPDX-License-Identifier: Apache-2.0
// levelforge — small helpers for error messages (internal to the library's .cc files).
#pragma once

#include <cstddef>
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

} // namespace levelforge::message_internal
