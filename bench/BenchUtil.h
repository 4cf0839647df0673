// SPDX-License-Identifier: Apache-2.0
// Small helpers shared by the benchmark programs.
#pragma once

#include <chrono>
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

} // namespace levelforge_bench
