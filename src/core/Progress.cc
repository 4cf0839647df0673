// SPDX-License-Identifier: Apache-2.0
// levelforge — progress reporting and interruption (see Progress.h).
#include "detail/ProgressCheck.h"
#include "detail/Timer.h"
#include <levelforge/core/Progress.h>

#include <levelforge/core/Exceptions.h>

#include <cstdio>

namespace levelforge {

namespace progress_internal {
/// Work that finishes sooner than this prints nothing: progress is for long work.
constexpr std::chrono::milliseconds kQuietStart{500};
} // namespace progress_internal

StderrProgress::StderrProgress(int minStep, bool enabled)
    : mStep(minStep < 1 ? 1 : (minStep > 100 ? 100 : minStep))
    , mEnabled(enabled)
    , mStart(std::chrono::steady_clock::now())
{
}

void StderrProgress::start(const char* name)
{
    mName = (name && *name) ? name : "working";
    mLast.store(-1);
    mStart = std::chrono::steady_clock::now();
}

void StderrProgress::end()
{
    if (!mEnabled || mLast.load() < 0) return; // nothing printed: stay silent
    const double seconds =
        detail::secondsSince(mStart);
    std::fprintf(stderr, "levelforge: %s done (%.2f s)\n", mName.c_str(), seconds);
    std::fflush(stderr);
}

bool StderrProgress::wasInterrupted(int percent)
{
    if (!mEnabled || percent < 0) return false;
    if (percent > 100) percent = 100;
    if (std::chrono::steady_clock::now() - mStart < progress_internal::kQuietStart) return false;
    // Report only when a new multiple of mStep is reached; called concurrently from TBB loops,
    // so the winner of the compare-exchange prints and the others stay silent.
    const int bucket = (percent / mStep) * mStep;
    int last = mLast.load(std::memory_order_relaxed);
    while (bucket > last) {
        if (mLast.compare_exchange_weak(last, bucket, std::memory_order_relaxed)) {
            std::fprintf(stderr, "levelforge: %s %d%%\n",
                         mName.empty() ? "working" : mName.c_str(), bucket);
            std::fflush(stderr);
            break;
        }
    }
    return false;
}

namespace progress_internal {

void check(openvdb::util::NullInterrupter* interrupter, int percent)
{
    if (interrupter && interrupter->wasInterrupted(percent)) throw InterruptedError();
}

} // namespace progress_internal
} // namespace levelforge
