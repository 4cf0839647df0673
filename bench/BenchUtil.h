// SPDX-License-Identifier: Apache-2.0
// Small helpers shared by the benchmark programs.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

namespace levelforge_bench {

/// "1,2.5,3" -> {1, 2.5, 3}
inline std::vector<double> parseList(const char* s)
{
    std::vector<double> v;
    std::stringstream ss(s);
    for (std::string t; std::getline(ss, t, ',');) v.push_back(std::stod(t));
    return v;
}

/// Seconds elapsed since t.
inline double since(std::chrono::steady_clock::time_point t)
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

/// 3 -> "3", 2.5 -> "2.5" (for labels)
inline std::string shortNumber(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return buf;
}

/// One machine-readable comparison of a levelforge row with its anchor (an OpenVDB call timed in
/// the same process), newline included, for scripts/bench --smoke:
///   SPEED label=<row> levelforge_s=<t> anchor=<name> anchor_s=<t> ratio=<anchor_s / levelforge_s>
/// Spaces in label and anchor become '_'. Times should be the best of the program's repeats.
inline std::string speedLine(std::string label, double levelforgeSeconds, std::string anchor, double anchorSeconds)
{
    for (std::string* s : {&label, &anchor})
        for (char& c : *s)
            if (c == ' ' || c == '\t' || c == '=') c = '_';
    const double ratio = levelforgeSeconds > 0 ? anchorSeconds / levelforgeSeconds : NAN;
    char buf[96];
    std::snprintf(buf, sizeof buf, " levelforge_s=%.6f anchor=", levelforgeSeconds);
    std::string line = "SPEED label=" + label + buf + anchor;
    std::snprintf(buf, sizeof buf, " anchor_s=%.6f ratio=%.4f\n", anchorSeconds, ratio);
    return line + buf;
}

} // namespace levelforge_bench
