// SPDX-License-Identifier: Apache-2.0
// levelforge operators — number formatting and timing shared by the operators' printed summaries.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

namespace levelforge::ops {

/// printf-style formatting of one number, e.g. fmt("%.2f", seconds).
inline std::string fmt(const char* format, double v)
{
    char buf[64];
    std::snprintf(buf, sizeof(buf), format, v);
    return buf;
}

/// Wall-clock seconds since @p t0 (steady clock), for the summaries' "time:" lines.
inline double secondsSince(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// 1234567 -> "1,234,567".
inline std::string withThousands(uint64_t n)
{
    std::string s = std::to_string(n);
    for (int i = int(s.size()) - 3; i > 0; i -= 3) s.insert(size_t(i), ",");
    return s;
}

} // namespace levelforge::ops
