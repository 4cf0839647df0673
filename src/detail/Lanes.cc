// SPDX-License-Identifier: Apache-2.0
// Deterministic lanes: lane counts, the lane runner and the row wavefront (see Lanes.h).
#include "detail/Lanes.h"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <exception>
#include <memory>
#include <vector>

namespace levelforge::detail {

void runLanes(int lanes, const std::function<void(int)>& lane)
{
    std::vector<std::thread> threads;
    threads.reserve(size_t(std::max(0, lanes - 1)));
    for (int t = 1; t < lanes; ++t) threads.emplace_back(lane, t);
    lane(0);
    for (auto& th : threads) th.join();
}

int defaultLaneCount()
{
    const int arena = tbb::this_task_arena::max_concurrency();
    const int global = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    return std::max(1, std::min(arena, global));
}

int wavefrontChunks(int width, int lanes)
{
    if (lanes <= 1 || width < 16) return 1;
    return std::max(1, std::min(width / 8, 4 * lanes));
}

int laneCountFor(int nx, int ny, int threads)
{
    if (threads == 1) return 1;
    int lanes = defaultLaneCount();
    if (threads > 1) lanes = std::min(lanes, threads);
    else if (int64_t(nx) * ny < 128 * 128) lanes = 1;
    return std::max(1, std::min(lanes, ny));
}

bool runRowWavefront(int stages, int rows, int chunks, int lookahead, int lanes,
                     const std::function<void(int, int, int)>& work,
                     const std::function<bool(int)>& beginStage)
{
    if (stages <= 0 || rows <= 0) return true;
    chunks = std::max(1, chunks);
    lookahead = std::max(0, lookahead);
    lanes = std::max(1, std::min(lanes, rows));
    if (lanes == 1) {
        for (int s = 0; s < stages; ++s) {
            if (beginStage && !beginStage(s)) return false;
            for (int r = 0; r < rows; ++r)
                for (int c = 0; c < chunks; ++c) work(s, r, c);
        }
        return true;
    }

    std::unique_ptr<LaneProgress[]> progress(new LaneProgress[size_t(rows)]);
    SpinBarrier barrier(lanes);
    std::atomic<bool> stop{false};
    std::exception_ptr error;

    auto lane = [&](int t) {
        for (int s = 0; s < stages; ++s) {
            if (t == 0 && beginStage) {
                try {
                    if (!beginStage(s)) stop.store(true, std::memory_order_relaxed);
                } catch (...) {
                    error = std::current_exception();
                    stop.store(true, std::memory_order_relaxed);
                }
            }
            barrier.wait(); // the previous stage is complete everywhere; `stop` is visible
            if (stop.load(std::memory_order_relaxed)) return;
            const int64_t base = int64_t(s) * chunks;
            for (int r = t; r < rows; r += lanes) {
                for (int c = 0; c < chunks; ++c) {
                    if (r > 0) {
                        const int64_t need = base + std::min(c + lookahead, chunks - 1) + 1;
                        for (int spin = 0; progress[r - 1].value.load(std::memory_order_acquire) < need; ++spin) {
                            if (spin < 1024) cpuRelax();
                            else std::this_thread::yield();
                        }
                    }
                    work(s, r, c);
                    progress[r].value.store(base + c + 1, std::memory_order_release);
                }
            }
        }
    };

    runLanes(lanes, lane);
    if (error) std::rethrow_exception(error);
    return !stop.load();
}

} // namespace levelforge::detail
