// SPDX-License-Identifier: Apache-2.0
// Tests for detail/Lanes.h: exceptions thrown in a lane or a wavefront row reach the caller
// (no std::terminate, no lane left waiting for a dead one), and a failed thread creation stops
// cleanly (runLanes) or falls back to fewer lanes (runRowWavefront).
#include "TestUtil.h"

#include "detail/Lanes.h"

#include <levelforge/core/Exceptions.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <vector>

using levelforge::detail::runLanes;
using levelforge::detail::runRowWavefront;

namespace {

/// Switches the thread-creation failure hook off again at the end of a test.
struct HookReset
{
    ~HookReset() { levelforge::detail::testing::failLaneThreadsFrom(0); }
};

/// The serial result of the wavefront used below: cell (s, r, c) of a stages x rows x chunks
/// array, each the sum of the cell above it (row r-1, same chunk) and the chunk before it.
std::vector<int64_t> wavefrontReference(int stages, int rows, int chunks)
{
    std::vector<int64_t> v(size_t(rows) * size_t(chunks), 0);
    for (int s = 0; s < stages; ++s) {
        for (int r = 0; r < rows; ++r) {
            for (int c = 0; c < chunks; ++c) {
                const int64_t up = r > 0 ? v[size_t(r - 1) * size_t(chunks) + size_t(c)] : s;
                const int64_t left = c > 0 ? v[size_t(r) * size_t(chunks) + size_t(c - 1)] : 1;
                v[size_t(r) * size_t(chunks) + size_t(c)] = (up + left) % 1000003;
            }
        }
    }
    return v;
}

} // namespace

TEST(Lanes, ExceptionInOneLaneReachesTheCallerAndStopsTheOthers)
{
    for (int thrower : {0, 1, 3}) {
        std::atomic<bool> stop{false};
        std::atomic<int> finished{0};
        try {
            runLanes(4, [&](int t) {
                if (t == thrower) throw std::runtime_error("lane " + std::to_string(t) + " failed");
                // The other lanes wait for a lane that will never publish: they must see `stop`.
                std::atomic<int64_t> never{0};
                EXPECT_FALSE(levelforge::detail::waitUntil(never, 1, stop));
                ++finished;
            }, &stop);
            ADD_FAILURE() << "expected the lane's exception";
        } catch (const std::runtime_error& e) {
            EXPECT_EQ(std::string(e.what()), "lane " + std::to_string(thrower) + " failed");
        }
        EXPECT_TRUE(stop.load());
        EXPECT_EQ(finished.load(), 3);
    }
}

TEST(Lanes, FirstOfSeveralExceptionsIsRethrown)
{
    try {
        runLanes(3, [&](int t) { throw levelforge::IoError("lane " + std::to_string(t)); });
        ADD_FAILURE() << "expected an exception";
    } catch (const levelforge::IoError& e) {
        const std::string what = e.what();
        EXPECT_TRUE(what == "lane 0" || what == "lane 1" || what == "lane 2") << what;
    }
}

TEST(Lanes, FailedThreadCreationRunsNoLaneAndThrowsTyped)
{
    HookReset reset;
    levelforge::detail::testing::failLaneThreadsFrom(2); // lane 1 starts, lane 2 cannot
    std::atomic<int> ran{0};
    try {
        runLanes(4, [&](int) { ++ran; });
        ADD_FAILURE() << "expected LaneStartError";
    } catch (const levelforge::detail::LaneStartError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot start lane thread 2 of 4"), std::string::npos) << e.what();
    }
    EXPECT_EQ(ran.load(), 0);
    // A ResourceLimitError for callers that do not know the lanes.
    levelforge::detail::testing::failLaneThreadsFrom(1);
    EXPECT_THROW(runLanes(2, [&](int) { ++ran; }), levelforge::ResourceLimitError);
    EXPECT_EQ(ran.load(), 0);
    runLanes(1, [&](int) { ++ran; }); // one lane needs no thread
    EXPECT_EQ(ran.load(), 1);
}

TEST(Lanes, WavefrontRowThrowReachesTheCaller)
{
    const int stages = 4, rows = 24, chunks = 6;
    for (int lanes : {1, 2, 4}) {
        for (int failStage : {0, 2}) {
            std::vector<int64_t> v(size_t(rows) * size_t(chunks), 0);
            try {
                runRowWavefront(stages, rows, chunks, 1, lanes, [&](int s, int r, int c) {
                    if (s == failStage && r == 7 && c == 3) throw levelforge::InvalidArgumentError("row 7 failed");
                    const int64_t up = r > 0 ? v[size_t(r - 1) * size_t(chunks) + size_t(c)] : s;
                    const int64_t left = c > 0 ? v[size_t(r) * size_t(chunks) + size_t(c - 1)] : 1;
                    v[size_t(r) * size_t(chunks) + size_t(c)] = (up + left) % 1000003;
                }, nullptr);
                ADD_FAILURE() << "expected the row's exception (lanes " << lanes << ")";
            } catch (const levelforge::InvalidArgumentError& e) {
                EXPECT_EQ(std::string(e.what()), "row 7 failed");
            }
        }
    }
}

TEST(Lanes, WavefrontBeginStageThrowReachesTheCaller)
{
    for (int lanes : {1, 3}) {
        EXPECT_THROW(runRowWavefront(3, 9, 2, 0, lanes, [](int, int, int) {},
                                     [](int s) -> bool {
                                         if (s == 1) throw levelforge::InterruptedError("stage 1");
                                         return true;
                                     }),
                     levelforge::InterruptedError);
    }
}

TEST(Lanes, WavefrontFallsBackToFewerLanesWhenThreadsCannotStart)
{
    HookReset reset;
    const int stages = 3, rows = 16, chunks = 5;
    const std::vector<int64_t> reference = wavefrontReference(stages, rows, chunks);
    for (int failFrom : {1, 2, 3}) {
        levelforge::detail::testing::failLaneThreadsFrom(failFrom);
        std::vector<int64_t> v(size_t(rows) * size_t(chunks), 0);
        const bool done = runRowWavefront(stages, rows, chunks, 0, 8, [&](int s, int r, int c) {
            const int64_t up = r > 0 ? v[size_t(r - 1) * size_t(chunks) + size_t(c)] : s;
            const int64_t left = c > 0 ? v[size_t(r) * size_t(chunks) + size_t(c - 1)] : 1;
            v[size_t(r) * size_t(chunks) + size_t(c)] = (up + left) % 1000003;
        }, nullptr);
        EXPECT_TRUE(done);
        EXPECT_EQ(v, reference) << "failing from lane " << failFrom;
    }
}

TEST(Lanes, WavefrontInterruptionStillReturnsFalse)
{
    for (int lanes : {1, 4}) {
        int stagesBegun = 0;
        const bool done = runRowWavefront(5, 12, 3, 1, lanes, [](int, int, int) {},
                                          [&](int s) { stagesBegun = s + 1; return s < 2; });
        EXPECT_FALSE(done);
        EXPECT_EQ(stagesBegun, 3);
    }
}
