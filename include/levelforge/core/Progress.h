// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Progress reporting and interruption.
///
/// Long operations take an `openvdb::util::NullInterrupter*` (OpenVDB's own convention): they call
/// start(name), then wasInterrupted(percent) at coarse steps from inside TBB loops, then end().
/// When wasInterrupted returns true the operation throws InterruptedError and discards its
/// partial result. StderrProgress prints "name: NN%" lines on stderr for the CLI.
#pragma once

#include <openvdb/util/NullInterrupter.h>

#include <atomic>
#include <chrono>
#include <string>

namespace levelforge {

/// @brief Prints coarse progress to stderr ("levelforge: <stage> 40%"), at most every `minStep`
///        percent.
///
/// Work that finishes within half a second prints nothing; a stage that printed anything ends
/// with "levelforge: <stage> done (N.NN s)". It never asks to stop: wasInterrupted() is always
/// false.
class StderrProgress : public openvdb::util::NullInterrupter
{
public:
    /// @brief A reporter printing at most once per @p minStep percent.
    /// @param[in] minStep  the step between printed percentages, clamped to [1, 100]
    /// @param[in] enabled  false: print nothing (a silent interrupter)
    explicit StderrProgress(int minStep = 10, bool enabled = true);
    /// @brief Begins a stage: remembers its name and start time, resets the last printed percent.
    /// @param[in] name  the stage name printed in each line; null or empty: "working"
    void start(const char* name = nullptr) override;
    /// @brief Ends the stage: prints "<stage> done (N.NN s)" if any percentage was printed.
    void end() override;
    /// @brief Reports progress; safe to call concurrently from TBB loops (one thread prints each
    ///        new multiple of minStep).
    /// @param[in] percent  progress of the current stage in [0, 100] (larger values count as 100);
    ///                     < 0: no progress to report
    /// @return false: this reporter never interrupts
    bool wasInterrupted(int percent = -1) override;

private:
    std::string mName;
    std::atomic<int> mLast{-1};
    int mStep;
    bool mEnabled;
    std::chrono::steady_clock::time_point mStart;
};

} // namespace levelforge
