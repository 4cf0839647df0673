// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one wall-clock timer of the library: seconds since a steady-clock time point,
///        used by every stage that fills a `seconds*` statistic.
#pragma once

#include <chrono>

namespace levelforge::detail {

using Clock = std::chrono::steady_clock;

/// Seconds elapsed since @p t0 (steady clock, so never negative).
inline double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

} // namespace levelforge::detail
