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

/// Prints coarse progress to stderr ("levelforge: <stage> 40%"), at most every `minStep` percent.
class StderrProgress : public openvdb::util::NullInterrupter
{
public:
    explicit StderrProgress(int minStep = 10, bool enabled = true);
    void start(const char* name = nullptr) override;
    void end() override;
    bool wasInterrupted(int percent = -1) override;

private:
    std::string mName;
    std::atomic<int> mLast{-1};
    int mStep;
    bool mEnabled;
    std::chrono::steady_clock::time_point mStart;
};

} // namespace levelforge
