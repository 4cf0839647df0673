// SPDX-License-Identifier: Apache-2.0
// Deterministic lanes: lane counts, the lane runner and the row wavefront (see Lanes.h).
#include "detail/Lanes.h"

#include "detail/MessageText.h"

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <system_error>
#include <vector>

namespace levelforge::detail {

namespace {

/// testing::failLaneThreadsFrom(): 0 = off.
std::atomic<int> gFailLaneThreadsFrom{0};

/// The start gate of runLanes(): every lane thread waits here until all of them exist (go) or
/// one could not be created (abort: leave without running the lane).
class StartGate
{
public:
    void open(bool go)
    {
        {
            std::lock_guard<std::mutex> lock(mMutex);
            mState = go ? State::Go : State::Abort;
        }
        mCondition.notify_all();
    }
    /// Blocks until open(); true for go.
    bool pass()
    {
        std::unique_lock<std::mutex> lock(mMutex);
        mCondition.wait(lock, [this] { return mState != State::Wait; });
        return mState == State::Go;
    }

private:
    enum class State { Wait, Go, Abort };
    std::mutex mMutex;
    std::condition_variable mCondition;
    State mState = State::Wait;
};

} // namespace

namespace testing {

void failLaneThreadsFrom(int firstLane) { gFailLaneThreadsFrom.store(std::max(0, firstLane)); }

} // namespace testing

void runLanes(int lanes, const std::function<void(int)>& lane, std::atomic<bool>* stop)
{
    if (lanes <= 1) {
        lane(0);
        return;
    }
    StartGate gate;
    std::mutex errorMutex;
    std::exception_ptr error;
    // Runs one lane; an exception is kept (the first one) and stops the other lanes.
    auto body = [&](int t) {
        try {
            lane(t);
        } catch (...) {
            {
                std::lock_guard<std::mutex> lock(errorMutex);
                if (!error) error = std::current_exception();
            }
            if (stop) stop->store(true, std::memory_order_release);
        }
    };

    std::vector<std::thread> threads;
    // A thread that cannot be created (std::system_error: no more threads; std::bad_alloc): the
    // threads that exist must leave and be joined before anything else may throw (a joinable
    // std::thread destroyed by the unwinding would end the process), so the handler only keeps
    // the exception; the message (which allocates) is built after the joins.
    std::exception_ptr startError;
    try {
        threads.reserve(size_t(lanes - 1));
        for (int t = 1; t < lanes; ++t) {
            const int failFrom = gFailLaneThreadsFrom.load(std::memory_order_relaxed);
            if (failFrom > 0 && t >= failFrom) {
                throw std::system_error(std::make_error_code(std::errc::resource_unavailable_try_again),
                                        "thread creation refused (test hook)");
            }
            threads.emplace_back([&gate, &body, t] {
                if (gate.pass()) body(t);
            });
        }
    } catch (...) {
        startError = std::current_exception();
    }
    if (startError) {
        gate.open(false); // the threads that exist leave without running their lane
        for (auto& th : threads) th.join();
        std::string why = "unknown error";
        try {
            std::rethrow_exception(startError);
        } catch (const std::exception& e) {
            why = message_internal::cutDependencyMessage(e.what());
        } catch (...) {
        }
        throw LaneStartError("cannot start lane thread " + std::to_string(threads.size() + 1) + " of " +
                             std::to_string(lanes) + ": " + why);
    }
    gate.open(true);
    body(0);
    for (auto& th : threads) th.join();
    if (error) std::rethrow_exception(error);
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

namespace {

/// runRowWavefront() on lanes > 1 threads. Sets @p ran once any lane started (a
/// LaneStartError thrown before that left nothing to undo).
bool wavefrontOnLanes(int stages, int rows, int chunks, int lookahead, int lanes,
                      const std::function<void(int, int, int)>& work, const std::function<bool(int)>& beginStage,
                      std::atomic<bool>& ran)
{
    const auto progress = std::make_unique<LaneProgress[]>(size_t(rows));
    SpinBarrier barrier(lanes);
    std::atomic<bool> stop{false};   // beginStage asked to stop (seen by all after the barrier)
    std::atomic<bool> failed{false}; // a lane threw (raised by runLanes): leave every wait now

    auto lane = [&](int t) {
        ran.store(true, std::memory_order_relaxed);
        for (int s = 0; s < stages; ++s) {
            if (t == 0 && beginStage && !beginStage(s)) stop.store(true, std::memory_order_relaxed);
            // The previous stage is complete everywhere; `stop` is visible.
            if (!barrier.wait(&failed)) return;
            if (stop.load(std::memory_order_relaxed) || failed.load(std::memory_order_acquire)) return;
            const int64_t base = int64_t(s) * chunks;
            for (int r = t; r < rows; r += lanes) {
                for (int c = 0; c < chunks; ++c) {
                    if (r > 0) {
                        const int64_t need = base + std::min(c + lookahead, chunks - 1) + 1;
                        for (int spin = 0; progress[r - 1].value.load(std::memory_order_acquire) < need; ++spin) {
                            if (failed.load(std::memory_order_relaxed)) return; // row r-1's lane died
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

    runLanes(lanes, lane, &failed); // rethrows the first exception of any lane
    return !stop.load();
}

} // namespace

bool runRowWavefront(int stages, int rows, int chunks, int lookahead, int lanes,
                     const std::function<void(int, int, int)>& work,
                     const std::function<bool(int)>& beginStage)
{
    if (stages <= 0 || rows <= 0) return true;
    chunks = std::max(1, chunks);
    lookahead = std::max(0, lookahead);
    lanes = std::max(1, std::min(lanes, rows));
    while (lanes > 1) {
        std::atomic<bool> ran{false};
        try {
            return wavefrontOnLanes(stages, rows, chunks, lookahead, lanes, work, beginStage, ran);
        } catch (const LaneStartError&) {
            if (ran.load()) throw; // thrown by the work itself, after lanes ran: not ours to retry
            lanes /= 2;            // no lane ran: nothing to undo; fewer threads
        }
    }
    for (int s = 0; s < stages; ++s) {
        if (beginStage && !beginStage(s)) return false;
        for (int r = 0; r < rows; ++r)
            for (int c = 0; c < chunks; ++c) work(s, r, c);
    }
    return true;
}

} // namespace levelforge::detail
