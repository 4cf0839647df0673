// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Deterministic lanes: a fixed set of std::threads that wait for each other by spinning
///        (spin barrier, progress counters, spin-wait), the lane counts of the dense transforms,
///        and the row-pipelined wavefront of the chamfer transforms.
///
/// Lanes are real threads, not TBB tasks: they spin-wait for each other, which must not
/// deadlock, and a TBB task that spins may hold the only worker the task it waits for needs.
/// Every scheduler here reproduces the serial order exactly, so results do not depend on the
/// lane count.
///
/// Failures: a lane that throws never ends the process. runLanes() catches the exception,
/// raises the caller's stop flag so that the lanes waiting for the dead lane give up (every
/// wait here watches that flag: waitUntil(), SpinBarrier::wait(stop)), joins every thread and
/// rethrows the first exception on the calling thread. A thread that cannot be created
/// (std::system_error, std::bad_alloc) stops the start before any lane runs: LaneStartError.
#pragma once

#include <levelforge/core/Exceptions.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <thread>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace levelforge::detail {

/// One step of a spin-wait: the `pause` hint on x86 (lets the sibling hyper-thread run and
/// leaves the spin loop without a memory-order mis-speculation), nothing elsewhere.
inline __attribute__((always_inline)) void cpuRelax()
{
#if defined(__x86_64__) || defined(__i386__)
    _mm_pause();
#endif
}

/// Sense-counting spin barrier for a fixed set of std::thread lanes (all of which exist, so
/// spinning always ends while none fails). Yields after a short spin so that oversubscribed
/// machines progress.
class SpinBarrier
{
public:
    explicit SpinBarrier(int n) : mN(n) {}
    /// Waits until all n lanes arrived: true. False when @p stop (if set) is raised first
    /// (a lane died and will never arrive); the barrier must not be used again after that.
    bool wait(const std::atomic<bool>* stop = nullptr)
    {
        const int gen = mGeneration.load(std::memory_order_acquire);
        if (mCount.fetch_add(1, std::memory_order_acq_rel) == mN - 1) {
            mCount.store(0, std::memory_order_relaxed);
            mGeneration.fetch_add(1, std::memory_order_acq_rel);
            return true;
        }
        for (int spin = 0; mGeneration.load(std::memory_order_acquire) == gen; ++spin) {
            if (stop && stop->load(std::memory_order_acquire)) return false;
            if (spin < 256) cpuRelax();
            else std::this_thread::yield();
        }
        return true;
    }

private:
    const int mN;
    std::atomic<int> mCount{0};
    std::atomic<int> mGeneration{0};
};

/// A lane's published progress, on a cache line of its own (lanes write their own only).
struct alignas(64) LaneProgress
{
    std::atomic<int64_t> value{0};
};

/// Spin until `value` reaches `need`; false when `stop` is raised first. The lanes wait about
/// once per slice (where a pass reverses the x order), briefly when the cores are free; when
/// they are not, the lane waited for is not running and spinning only delays it, so the wait
/// yields early. `seen`, if set, receives the value that ended the wait.
inline bool waitUntil(const std::atomic<int64_t>& value, int64_t need, const std::atomic<bool>& stop,
                      int64_t* seen = nullptr)
{
    int64_t v;
    for (int spin = 0; (v = value.load(std::memory_order_acquire)) < need; ++spin) {
        if (stop.load(std::memory_order_relaxed)) return false;
        if (spin < 32) cpuRelax();
        else std::this_thread::yield();
    }
    if (seen) *seen = v;
    return true;
}

/// A lane thread could not be created (std::system_error: no more threads; std::bad_alloc).
/// No lane ran: the caller may retry with fewer lanes (runRowWavefront() does, down to one)
/// or report it. A ResourceLimitError, so a caller that does not retry reports it as such.
class LaneStartError : public ResourceLimitError
{
public:
    explicit LaneStartError(const std::string& msg) : ResourceLimitError(msg) {}
};

/// Runs lane(1..lanes-1) on std::threads and lane(0) on the calling thread, then joins them all.
/// Real threads, not TBB tasks: lanes spin-wait for each other, which must not deadlock.
///
/// Every thread is created before any lane starts (they wait at a start gate). When one cannot
/// be created, the threads already created leave without running their lane, are joined, and
/// LaneStartError is thrown: no lane has run. When a lane throws, the exception is caught on
/// its thread, `*stop` (if given) is raised so that the other lanes stop waiting for the dead
/// one (lanes that wait for each other must watch it), all threads are joined, and the first
/// exception is rethrown on the calling thread. Lanes that do not wait for each other may
/// pass no stop flag. lanes <= 1 runs lane(0) on the calling thread.
void runLanes(int lanes, const std::function<void(int)>& lane, std::atomic<bool>* stop = nullptr);

/// Number of lanes by default (vector and chamfer transforms):
/// tbb::this_task_arena::max_concurrency(), capped by tbb::global_control's
/// max_allowed_parallelism; at least 1.
int defaultLaneCount();

/// Lanes for an nx x ny slice: threads == 1 gives 1; threads > 1 caps defaultLaneCount();
/// 0 picks defaultLaneCount() when nx * ny >= 128 * 128 (smaller slices do not repay the
/// per-pass synchronisation), else 1. Never more than ny.
int laneCountFor(int nx, int ny, int threads);

/// Chunk count used for rows of `width` voxels with `lanes` lanes (runRowWavefront()).
int wavefrontChunks(int width, int lanes);

/// A row-pipelined wavefront (used by the chamfer transforms; the vector transforms split
/// columns instead). Stages run one after another, separated by a barrier; within a stage, rows
/// 0..rows-1 (in the stage's own order) are dealt to `lanes` std::thread lanes round-robin, each
/// row in x-chunks 0..chunks-1 (in the stage's x order); chunk c of row r starts only after row
/// r-1 has finished chunk min(c + lookahead, chunks-1). work(stage, row, chunk) must read only
/// what that order makes final. beginStage(stage), if set, runs on lane 0 before each stage;
/// when it returns false the wavefront stops and runRowWavefront returns false. lanes <= 1 runs
/// serially on the calling thread. Deterministic: the serial raster order is reproduced, with
/// any lane count. An exception thrown by work or beginStage stops every lane (no lane waits
/// for a row or a barrier the failed lane will never reach) and is rethrown on the calling
/// thread once all lanes have ended. When the lane threads cannot be created, the wavefront
/// runs again with half the lanes, down to serially on the calling thread.
bool runRowWavefront(int stages, int rows, int chunks, int lookahead, int lanes,
                     const std::function<void(int stage, int row, int chunk)>& work,
                     const std::function<bool(int stage)>& beginStage);

namespace testing {

/// For tests only: from now on, creating lane thread number @p firstLane or higher (1-based,
/// as in runLanes()) fails with std::system_error, as it does when the system has no more
/// threads; 0 switches it off (the default). Not for library code.
void failLaneThreadsFrom(int firstLane);

} // namespace testing

} // namespace levelforge::detail
