// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one number formatter of error messages: the shortest text that reads back as
///        the same double (std::to_chars), "nan", "inf" or "-inf" for non-finite values.
#pragma once

#include <charconv>
#include <cmath>
#include <string>

namespace levelforge::detail {

/// Shortest round-trip text of @p v (double or float: the shortest text that reads back as
/// the same value of that type, so 0.15f prints "0.15"): fixed notation for magnitudes in
/// [1e-4, 1e15) ("0.1", "100000", "2.5"), scientific elsewhere ("1e+30", "1e-07"); "nan",
/// "inf", "-inf".
template<typename T>
inline std::string formatNumber(T v)
{
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    char buf[400];
    const T a = std::fabs(v);
    const bool fixed = a == T(0) || (a >= T(1e-4) && a < T(1e15));
    const auto r = fixed ? std::to_chars(buf, buf + sizeof(buf), v, std::chars_format::fixed)
                         : std::to_chars(buf, buf + sizeof(buf), v);
    return std::string(buf, r.ptr);
}

inline std::string formatDouble(double v) { return formatNumber(v); }
inline std::string formatFloat(float v) { return formatNumber(v); }

} // namespace levelforge::detail
