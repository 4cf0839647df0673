// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one number formatter of error messages: the shortest text that reads back as
///        the same double (std::to_chars), "nan", "inf" or "-inf" for non-finite values.
#pragma once

#include <charconv>
#include <cmath>
#include <string>

namespace levelforge::detail {

/// Shortest round-trip text of @p v ("0.1", "1e+30", "nan", "-inf").
inline std::string formatDouble(double v)
{
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    char buf[64];
    const auto r = std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
}

} // namespace levelforge::detail
