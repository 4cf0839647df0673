// SPDX-License-Identifier: Apache-2.0
// Exception safety of every parallel stage (issue 21, items 4 and 5).
//
// Each stage that takes an interrupter is run, in every mode its options offer, on a small input
// in task arenas of 1 and 2 threads (the std::thread lanes of the dense transforms follow the
// arena: 1 or 2 lanes), with failures injected at several points of its work:
//  - an interrupter that asks to stop from poll N on: the stage throws InterruptedError, or (when
//    only its closing 100 % report was answered) returns its normal result;
//  - an interrupter whose wasInterrupted() throws a foreign exception from poll N on, on
//    whichever thread polls: the exception reaches the caller (no std::terminate from a TBB
//    task or a lane thread), as itself (every stage passes it through unchanged today) or as a
//    levelforge::Error;
//  - allocation failure: operator new of this test binary fails the Nth large allocation (or
//    every large one from the Nth on) while a stage runs: the stage throws std::bad_alloc or a
//    levelforge::Error, or recovers and returns the normal result (the same, bit for bit);
//  - lane threads that cannot be created (detail::testing::failLaneThreadsFrom): a
//    ResourceLimitError, or the same result from fewer lanes.
// After each series the same call runs again and must give the reference result: a failure
// leaves no state behind. No assertion depends on timing: N counts polls or allocations.
//
// Poll density (item 4): on a mesh whose triangles crowd into a few leaves, the polls of the
// distance stage of meshToLevelSet are counted against its exact distance evaluations.
#include "TestUtil.h"

#include "detail/Lanes.h"

#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/mesh/TriangleListTree.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/scan/TetScanConversion.h>
#include <levelforge/volume/ChamferDistanceTransform.h>
#include <levelforge/volume/ExactDistanceTransform.h>
#include <levelforge/volume/SparseVolumeToLevelSet.h>
#include <levelforge/volume/SubvoxelShell.h>
#include <levelforge/volume/VectorDistanceTransform.h>
#include <levelforge/volume/VolumeToLevelSet.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iostream>
#include <mutex>
#include <new>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <typeinfo>
#include <utility>
#include <vector>

// ---- allocation failure injection: this binary's operator new ------------------------------
// Off (one relaxed load per large allocation) except while a test arms it around one library
// call. Armed, it counts the large allocations of every thread and fails number `failAt` (or
// every one from it on). Only allocations of kLargeBytes or more fail: a small allocation that
// fails inside a destructor ends the process, and OpenVDB's ~Tree allocates (Tree::clear()
// collects the nodes in vectors); under a real memory shortage the large ones (internal nodes,
// dense volumes, arrays of leaves and lists) fail first. Every non-aligned form is replaced, on
// malloc/free, so that new and delete always match; the aligned forms stay the runtime's own.
// Not under AddressSanitizer: the replacement would hide its new/delete checks from the whole
// test binary, and OpenVDB leaks when an allocation fails inside a tree copy (InternalNode's
// DeepCopy / TopologyCopy constructors), which LeakSanitizer would report at exit. Not under
// ThreadSanitizer either: its runtime defines operator new/delete itself (a second definition
// does not link).

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define LF_ALLOCATION_INJECTION 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define LF_ALLOCATION_INJECTION 0
#endif
#endif
#ifndef LF_ALLOCATION_INJECTION
#define LF_ALLOCATION_INJECTION 1
#endif

namespace {
namespace alloc_injection {

constexpr std::size_t kLargeBytes = 16384;

std::atomic<bool> gArmed{false};
std::atomic<int64_t> gLarge{0};       // allocations of kLargeBytes or more while armed
std::atomic<int64_t> gFailAt{-1};     // index (among the large ones) of the first to fail; -1: none
std::atomic<bool> gPersistent{false}; // fail every large allocation from gFailAt on
std::atomic<int64_t> gInjected{0};    // allocations failed

#if LF_ALLOCATION_INJECTION
/// Counts one allocation request; true when it must fail.
inline bool failThisOne(std::size_t n)
{
    if (n < kLargeBytes || !gArmed.load(std::memory_order_relaxed)) return false;
    const int64_t i = gLarge.fetch_add(1, std::memory_order_relaxed);
    const int64_t at = gFailAt.load(std::memory_order_relaxed);
    if (at < 0 || i < at || (i > at && !gPersistent.load(std::memory_order_relaxed))) return false;
    gInjected.fetch_add(1, std::memory_order_relaxed);
    return true;
}

// Not inlined into the operators: a call site that sees malloc/free behind operator new/delete
// would be reported as a mismatched allocation (-Wmismatched-new-delete).
[[gnu::noinline]] void* allocate(std::size_t n)
{
    if (failThisOne(n)) return nullptr;
    return std::malloc(n ? n : 1);
}

[[gnu::noinline]] void release(void* p) noexcept { std::free(p); }
#endif

} // namespace alloc_injection

/// Ends the injection window of the current call: a case calls it on what the library call
/// returned, before its own code reads and destroys the result.
template<typename T>
T injectionEnds(T&& result)
{
    alloc_injection::gArmed.store(false);
    return std::forward<T>(result);
}
void injectionEnds() { alloc_injection::gArmed.store(false); }

} // namespace

#if LF_ALLOCATION_INJECTION
void* operator new(std::size_t n)
{
    if (void* p = alloc_injection::allocate(n)) return p;
    throw std::bad_alloc();
}
void* operator new[](std::size_t n)
{
    if (void* p = alloc_injection::allocate(n)) return p;
    throw std::bad_alloc();
}
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return alloc_injection::allocate(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return alloc_injection::allocate(n); }
void operator delete(void* p) noexcept { alloc_injection::release(p); }
void operator delete[](void* p) noexcept { alloc_injection::release(p); }
void operator delete(void* p, std::size_t) noexcept { alloc_injection::release(p); }
void operator delete[](void* p, std::size_t) noexcept { alloc_injection::release(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { alloc_injection::release(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { alloc_injection::release(p); }
#endif

using namespace levelforge;
using openvdb::Coord;

namespace {

// ---- interrupters ------------------------------------------------------------------------

/// The foreign exception an interrupter throws (not a levelforge type).
struct InjectedFailure : std::runtime_error
{
    explicit InjectedFailure(const std::string& m) : std::runtime_error(m) {}
};

/// Counts polls (thread-safe) and, from poll number `after` (0-based) on, asks to stop (Stop)
/// or throws InjectedFailure (Throw); Count never interferes. Records what it did.
class InjectingInterrupter : public openvdb::util::NullInterrupter
{
public:
    enum class Mode { Count, Stop, Throw };

    explicit InjectingInterrupter(Mode mode = Mode::Count, int64_t after = 0) : mMode(mode), mAfter(after) {}

    void start(const char* = nullptr) override { mStarts.fetch_add(1, std::memory_order_relaxed); }
    void end() override { mEnds.fetch_add(1, std::memory_order_relaxed); }
    bool wasInterrupted(int percent = -1) override
    {
        const int64_t i = mPolls.fetch_add(1, std::memory_order_relaxed);
        if (mRecord) {
            std::lock_guard<std::mutex> lock(mMutex);
            mPercents.push_back(percent);
        }
        if (mMode == Mode::Count || i < mAfter) return false;
        mFired.fetch_add(1, std::memory_order_relaxed);
        if (percent != 100) mFiredMidway.fetch_add(1, std::memory_order_relaxed);
        if (mMode == Mode::Throw) throw InjectedFailure("injected failure at poll " + std::to_string(i));
        return true;
    }

    int64_t polls() const { return mPolls.load(); }
    int64_t fired() const { return mFired.load(); }
    /// Polls answered (true or a throw) that were not the closing 100 % report.
    int64_t firedMidway() const { return mFiredMidway.load(); }
    int64_t starts() const { return mStarts.load(); }
    int64_t ends() const { return mEnds.load(); }
    /// Keep the percent of every poll (in arrival order).
    void record() { mRecord = true; }
    std::vector<int> percents() const
    {
        std::lock_guard<std::mutex> lock(mMutex);
        return mPercents;
    }

private:
    const Mode mMode;
    const int64_t mAfter;
    std::atomic<int64_t> mPolls{0}, mFired{0}, mFiredMidway{0}, mStarts{0}, mEnds{0};
    bool mRecord = false;
    mutable std::mutex mMutex;
    std::vector<int> mPercents;
};

// ---- fingerprints of results -------------------------------------------------------------

struct Hash
{
    uint64_t h = 1469598103934665603ull;
    void add(uint64_t v)
    {
        for (int i = 0; i < 8; ++i) {
            h ^= (v >> (8 * i)) & 0xffu;
            h *= 1099511628211ull;
        }
    }
    void add(float f)
    {
        uint32_t b;
        std::memcpy(&b, &f, 4);
        add(uint64_t(b));
    }
    void add(const Coord& c)
    {
        add(uint64_t(uint32_t(c.x())));
        add(uint64_t(uint32_t(c.y())));
        add(uint64_t(uint32_t(c.z())));
    }
};

/// Every value of the tree (leaf voxels, tiles with their boxes, active or not) and the background.
template<typename TreeT>
uint64_t fingerprint(const TreeT& tree)
{
    Hash h;
    h.add(uint64_t(sizeof(typename TreeT::ValueType)));
    for (auto it = tree.cbeginValueAll(); it; ++it) {
        openvdb::CoordBBox b;
        it.getBoundingBox(b);
        h.add(b.min());
        h.add(b.max());
        h.add(uint64_t(it.isValueOn()));
        const auto v = it.getValue();
        Hash vh;
        if constexpr (std::is_same_v<typename TreeT::ValueType, float>) {
            vh.add(v);
        } else if constexpr (std::is_same_v<typename TreeT::ValueType, openvdb::Vec3f>) {
            vh.add(v[0]);
            vh.add(v[1]);
            vh.add(v[2]);
        } else {
            vh.add(uint64_t(int64_t(v)));
        }
        h.add(vh.h);
    }
    return h.h;
}

uint64_t fingerprint(const openvdb::FloatGrid& g)
{
    Hash h;
    h.add(fingerprint(g.tree()));
    h.add(g.background());
    h.add(uint64_t(g.getGridClass()));
    h.add(float(g.voxelSize()[0]));
    return h.h;
}

template<typename T>
uint64_t fingerprint(const DenseVolume<T>& v)
{
    Hash h;
    h.add(v.dims);
    const auto* b = reinterpret_cast<const unsigned char*>(v.data.data());
    const size_t n = v.data.size() * sizeof(T);
    for (size_t i = 0; i < n; i += 8) {
        uint64_t w = 0;
        std::memcpy(&w, b + i, std::min<size_t>(8, n - i));
        h.add(w);
    }
    return h.h;
}

// ---- the harness -------------------------------------------------------------------------

/// One stage in one mode: runs it with the given interrupter and returns a fingerprint of
/// everything it returned (or of the volume it transformed in place).
struct Case
{
    std::string name;
    std::function<uint64_t(openvdb::util::NullInterrupter*)> run;
    bool usesLanes = false; ///< runs std::thread lanes (lane start failures are injected too)
    bool slow = false;      ///< 100 ms or more: injected with 2 threads only, at fewer points
    /// Fail every large allocation from the Nth on, for N every 8 large allocations (a failure
    /// anywhere in a short run of allocations, e.g. the nodes of a tree that leaves move into).
    bool allocationSweep = false;
};

/// A task arena of `count` threads, and a global_control of that size (which the lane counts
/// also follow), for all the runs of one thread count.
struct Threads
{
    explicit Threads(int n)
        : count(n), allow(tbb::global_control::max_allowed_parallelism, size_t(n)), arena(n)
    {
    }
    template<typename Fn>
    void run(const Fn& fn)
    {
        arena.execute(fn);
    }
    const int count;
    tbb::global_control allow;
    tbb::task_arena arena;
};

/// Runs fn in a task arena of `threads` threads.
template<typename Fn>
void inArena(int threads, const Fn& fn)
{
    Threads(threads).run(fn);
}

/// Distinct points in [0, count): the first, the second, and a few spread over the rest.
std::vector<int64_t> injectionPoints(int64_t count, int spread)
{
    std::set<int64_t> s;
    if (count <= 0) return {};
    s.insert(0);
    if (count > 1) s.insert(1);
    for (int k = 1; k <= spread; ++k) s.insert(std::min(count - 1, (count * k) / (spread + 1)));
    s.insert(count - 1);
    return {s.begin(), s.end()};
}

std::string describe(const std::exception& e)
{
    std::ostringstream os;
    os << typeid(e).name() << ": " << e.what();
    return os.str();
}

/// Poll injection (Stop and Throw from poll N on) for one case; `ref` is the reference result.
void injectPolls(const Case& c, Threads& threads, uint64_t ref, int64_t polls)
{
    using Mode = InjectingInterrupter::Mode;
    for (int64_t n : injectionPoints(polls, c.slow || threads.count == 1 ? 1 : 2)) {
        for (Mode mode : {Mode::Stop, Mode::Throw}) {
            const bool stop = mode == Mode::Stop;
            SCOPED_TRACE(c.name + ", " + std::to_string(threads.count) + " thread(s), " + (stop ? "stop" : "throw") +
                         " from poll " + std::to_string(n) + " of " + std::to_string(polls));
            InjectingInterrupter it(mode, n);
            try {
                uint64_t fp = 0;
                threads.run([&] { fp = c.run(&it); });
                // Only the closing 100 % report may go unanswered: the work was complete.
                EXPECT_EQ(it.firedMidway(), 0) << "the interrupter " << (stop ? "asked to stop" : "threw")
                                               << " during the work, yet the call returned";
                if (!stop) {
                    EXPECT_EQ(it.fired(), 0) << "the interrupter's exception was swallowed";
                }
                EXPECT_EQ(fp, ref) << "the call returned a different result";
            } catch (const InterruptedError&) {
                EXPECT_TRUE(stop) << "InterruptedError from an interrupter that throws";
                EXPECT_GT(it.fired(), 0) << "InterruptedError although the interrupter never asked to stop";
            } catch (const InjectedFailure&) {
                EXPECT_FALSE(stop) << "the interrupter's exception from an interrupter that does not throw";
            } catch (const Error& e) {
                // a stage that converts foreign exceptions into its own typed errors would land here
                EXPECT_FALSE(stop) << "unexpected " << describe(e);
                EXPECT_GT(it.fired(), 0) << "unexpected " << describe(e);
            } catch (const std::exception& e) {
                ADD_FAILURE() << "unexpected exception " << describe(e);
            }
        }
    }
}

/// Allocation failure injection: the Nth large allocation fails (or every large one from the
/// Nth on). (Memory a failed call leaves behind is not checked: OpenVDB itself leaks when an
/// allocation fails inside a tree copy, InternalNode's DeepCopy / TopologyCopy constructors.)
void injectAllocationFailures(const Case& c, Threads& threads, uint64_t ref)
{
    if (!LF_ALLOCATION_INJECTION) return; // (AddressSanitizer build: see the top of the file)
    namespace ai = alloc_injection;
    struct Run
    {
        std::exception_ptr error;
        uint64_t fp = 0;
        int64_t large = 0, injected = 0;
    };
    auto armed = [&](int64_t failAt, bool persistent) {
        Run r;
        threads.run([&] {
            ai::gLarge = 0;
            ai::gInjected = 0;
            ai::gFailAt = failAt;
            ai::gPersistent = persistent;
            ai::gArmed = true;
            try {
                r.fp = c.run(nullptr); // disarms when the library call returns (injectionEnds)
            } catch (...) {
                r.error = std::current_exception();
            }
            ai::gArmed = false;
        });
        ai::gFailAt = -1;
        r.injected = ai::gInjected.load();
        r.large = ai::gLarge.load();
        return r;
    };

    const Run clean = armed(-1, false); // counts the large allocations
    ASSERT_FALSE(clean.error) << c.name << ": the counted run failed";
    ASSERT_EQ(clean.fp, ref) << c.name;
    if (clean.large == 0) {
        std::cout << "[ note ] " << c.name << ": no allocation of " << ai::kLargeBytes << " bytes or more\n";
        return;
    }
    std::vector<std::pair<int64_t, bool>> points; // (first failing allocation, and all after it)
    if (clean.large <= 24) {
        for (int64_t n = 0; n < clean.large; ++n) points.emplace_back(n, false); // each one
    } else if (c.slow) {
        points.emplace_back(clean.large / 2, false);
    } else {
        for (int64_t n : injectionPoints(clean.large, 1)) points.emplace_back(n, false);
    }
    points.emplace_back(clean.large / 3, true);
    if (c.allocationSweep)
        for (int64_t n = 1; n < clean.large; n += 8) points.emplace_back(n, true);
    for (const auto& [n, persistent] : points) {
        SCOPED_TRACE(c.name + ", " + std::to_string(threads.count) + " thread(s), large allocation " + std::to_string(n) +
                     " of " + std::to_string(clean.large) + (persistent ? " and all after it" : "") + " fails");
        const Run r = armed(n, persistent);
        if (!r.error) {
            EXPECT_EQ(r.fp, ref) << "recovered from the failed allocation with a different result";
            continue;
        }
        try {
            std::rethrow_exception(r.error);
        } catch (const std::bad_alloc&) {
            EXPECT_GT(r.injected, 0) << "std::bad_alloc without an injected failure";
        } catch (const Error& e) {
            EXPECT_GT(r.injected, 0) << describe(e);
        } catch (const std::exception& e) {
            ADD_FAILURE() << "unexpected exception " << describe(e);
        }
    }
}

/// Lane threads that cannot be created (every one: with 2 threads there are 2 lanes, the
/// calling thread and one lane thread): the chamfer wavefront falls back to the calling thread,
/// the vector transforms throw LaneStartError (a ResourceLimitError).
void injectLaneStartFailures(const Case& c, Threads& threads, uint64_t ref)
{
    struct HookReset
    {
        ~HookReset() { detail::testing::failLaneThreadsFrom(0); }
    } reset;
    SCOPED_TRACE(c.name + ", " + std::to_string(threads.count) + " thread(s), no lane thread starts");
    detail::testing::failLaneThreadsFrom(1);
    try {
        uint64_t fp = 0;
        threads.run([&] { fp = c.run(nullptr); });
        EXPECT_EQ(fp, ref) << "fell back to fewer lanes with a different result";
    } catch (const ResourceLimitError&) {
        // LaneStartError: no lane ran
    } catch (const std::exception& e) {
        ADD_FAILURE() << "unexpected exception " << describe(e);
    }
}

/// Every injection for every case: polls and lane starts with 1 and 2 threads, allocations
/// with 2 (failures on two threads at once); then each call again, unharmed and without an
/// interrupter, which must give the reference result.
void injectAll(const std::vector<Case>& cases)
{
    for (int n : {1, 2}) {
        Threads threads(n);
        for (const Case& c : cases) {
            if (c.slow && n == 1) continue;
            SCOPED_TRACE(c.name + ", " + std::to_string(n) + " thread(s)");
            InjectingInterrupter counter;
            uint64_t ref = 0;
            try {
                threads.run([&] { ref = c.run(&counter); });
            } catch (const std::exception& e) {
                ADD_FAILURE() << "the reference run failed: " << describe(e);
                continue;
            }
            EXPECT_GT(counter.polls(), 0) << "never polls the interrupter";
            EXPECT_GT(counter.starts(), 0) << "never calls start()";
            injectPolls(c, threads, ref, counter.polls());
            if (n == 2) injectAllocationFailures(c, threads, ref);
            if (c.usesLanes) injectLaneStartFailures(c, threads, ref);
            // nothing poisoned: the same call, unharmed, gives the same result
            uint64_t again = 0;
            EXPECT_NO_THROW(threads.run([&] { again = c.run(nullptr); }));
            EXPECT_EQ(again, ref) << "a call after the failures (without an interrupter) gives a different result";
        }
    }
}

// ---- inputs ------------------------------------------------------------------------------

const TriangleMesh& sphereMesh()
{
    static const TriangleMesh m = makeIcosphere(Vec3d(0.0), 1.0, 2); // 320 triangles, 10 voxels across
    return m;
}

/// A sphere field f = R - |x - c| (inside positive) of 64 x 16 x 12 samples: 64 columns, so that
/// the vector transforms can use 2 lanes (8 column groups, at least 4 per lane).
const ScalarVolume& sphereField()
{
    static const ScalarVolume f =
        makeSphereField(Coord(64, 16, 12), openvdb::Vec3d(31.3, 7.6, 5.7), 4.9);
    return f;
}

const MaskVolume& sphereFeatures()
{
    static const MaskVolume m = transverseFeatures(insideMask(sphereField(), 0.0f));
    return m;
}

/// sphereField() as a sparse FloatGrid (samples f <= -4 left inactive at the background -4).
const openvdb::FloatGrid& sphereFieldGrid()
{
    static const openvdb::FloatGrid::Ptr g = [] {
        const ScalarVolume& f = sphereField();
        auto grid = openvdb::FloatGrid::create(-4.0f);
        auto acc = grid->getAccessor();
        for (int k = 0; k < f.dims.z(); ++k)
            for (int j = 0; j < f.dims.y(); ++j)
                for (int i = 0; i < f.dims.x(); ++i)
                    if (f(i, j, k) > -4.0f) acc.setValue(Coord(i, j, k), f(i, j, k));
        grid->setName("density");
        return grid;
    }();
    return *g;
}

constexpr double kVoxelSize = 0.2;

/// sphereMesh() moved into the middle of one 128³ node of the ADF (a sphere at the origin would
/// subdivide eight of them, with 4096 tiles each to check).
const TriangleMesh& adfMesh()
{
    static const TriangleMesh m = makeIcosphere(Vec3d(64.25 * kVoxelSize), 1.0, 2);
    return m;
}

MeshToLevelSetOptions bandOptions(openvdb::util::NullInterrupter* it, double width = 3.0)
{
    MeshToLevelSetOptions o;
    o.voxelSize = kVoxelSize;
    o.exteriorWidth = o.interiorWidth = width;
    o.interrupter = it;
    return o;
}

} // namespace

// ---- the stages ----------------------------------------------------------------------------

TEST(ExceptionInjection, MeshToLevelSet)
{
    openvdb::initialize();
    std::vector<Case> cases;
    cases.push_back({"meshToLevelSet", [](openvdb::util::NullInterrupter* it) {
                         return fingerprint(*injectionEnds(meshToLevelSet(sphereMesh(), bandOptions(it))));
                     }});
    cases.push_back({"meshToLevelSetWithClosestPoints", [](openvdb::util::NullInterrupter* it) {
                         const LevelSetWithClosestPoints r =
                             injectionEnds(meshToLevelSetWithClosestPoints(sphereMesh(), bandOptions(it)));
                         Hash h;
                         h.add(fingerprint(*r.levelSet));
                         h.add(fingerprint(r.closestPoints->tree()));
                         h.add(fingerprint(r.closestTriangles->tree()));
                         return h.h;
                     }});
    injectAll(cases);
}

TEST(ExceptionInjection, TriangleListTree)
{
    // 1280 triangles: 5 chunks of 256 in pass 1
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 3);
    std::vector<Vec3d> cellPoints;
    for (const Vec3d& p : mesh.points) cellPoints.push_back(p / 0.05 + Vec3d(0.5));
    std::vector<uint32_t> use(mesh.triangles.size());
    for (uint32_t i = 0; i < use.size(); ++i) use[i] = i;
    std::vector<Case> cases;
    cases.push_back({"TriangleListTree::build", [&](openvdb::util::NullInterrupter* it) {
                         if (it) it->start("triangle lists"); // build() itself only polls
                         const TriangleListTree t =
                             injectionEnds(TriangleListTree::build(cellPoints, mesh.triangles, use, nullptr, it));
                         Hash h;
                         h.add(uint64_t(t.cellCount()));
                         h.add(uint64_t(t.entryCount()));
                         for (auto v = t.tree().cbeginValueOn(); v; ++v) {
                             h.add(v.getCoord());
                             for (const uint32_t* p = t.listBegin(*v); p != t.listEnd(*v); ++p) h.add(uint64_t(*p));
                         }
                         if (it) it->end();
                         return h.h;
                     }});
    injectAll(cases);
}

TEST(ExceptionInjection, ExpandLevelSet)
{
    openvdb::initialize();
    MeshToLevelSetOptions bo = bandOptions(nullptr, 2.0);
    const LevelSetWithClosestPoints band = meshToLevelSetWithClosestPoints(sphereMesh(), bo);
    struct Mode
    {
        const char* name;
        ExpansionMethod method;
        int closest; // Vector: 0 estimated offsets, 1 closest points, 2 closest points + triangles
        ExpansionDomain domain;
        bool fillInterior;
    };
    const Mode modes[] = {
        {"sweep band", ExpansionMethod::Sweep, 0, ExpansionDomain::Band, false},
        {"sweep box", ExpansionMethod::Sweep, 0, ExpansionDomain::BoundingBox, false},
        {"sweep fill", ExpansionMethod::Sweep, 0, ExpansionDomain::Band, true},
        {"vector estimated band", ExpansionMethod::Vector, 0, ExpansionDomain::Band, false},
        {"vector closest box", ExpansionMethod::Vector, 1, ExpansionDomain::BoundingBox, false},
        {"vector refined fill", ExpansionMethod::Vector, 2, ExpansionDomain::Band, true},
        // (vector refined band: the main road, in MeshToSdfPipeline)
    };
    std::vector<Case> cases;
    for (const Mode& m : modes) {
        cases.push_back({std::string("expandLevelSet ") + m.name, [&band, m](openvdb::util::NullInterrupter* it) {
                             ExpandLevelSetOptions o;
                             o.exteriorWidth = o.interiorWidth = 3.5;
                             o.method = m.method;
                             o.domain = m.domain;
                             o.boundingBoxMargin = 2.0;
                             o.fillInterior = m.fillInterior;
                             o.inputExteriorWidth = o.inputInteriorWidth = 2.0;
                             if (m.closest >= 1) o.closestPoints = &band.closestPoints->tree();
                             if (m.closest >= 2) {
                                 o.closestTriangles = &band.closestTriangles->tree();
                                 o.mesh = &sphereMesh();
                             }
                             o.interrupter = it;
                             return fingerprint(*injectionEnds(expandLevelSet(*band.levelSet, o)));
                         }});
    }
    injectAll(cases);
}

TEST(ExceptionInjection, AdaptiveDistanceField)
{
    openvdb::initialize();
    struct Mode
    {
        const char* name;
        double tolerance; // > 0: the refinement mode (error bounds of the tiles, then refined tiles)
        bool bounds;      // the error-bound stage after the values
    };
    // values: the sphere at the origin, across eight 128³ nodes (the type-1 band's tree grows
    // node by node while its leaves move in); bounds and refinement: inside one such node
    std::vector<Case> cases;
    for (const Mode& m : {Mode{"values", 0.0, false}, Mode{"bounds", 0.0, true}, Mode{"refinement", 1.0, false}}) {
        Case c{std::string("meshToAdaptiveDistanceField ") + m.name, [m](openvdb::util::NullInterrupter* it) {
                   AdaptiveDistanceFieldOptions o;
                   o.voxelSize = kVoxelSize;
                   o.toleranceVoxels = m.tolerance;
                   o.computeBounds = m.bounds;
                   o.interrupter = it;
                   const TriangleMesh& mesh = m.bounds || m.tolerance > 0 ? adfMesh() : sphereMesh();
                   const AdaptiveDistanceField adf = injectionEnds(meshToAdaptiveDistanceField(mesh, o));
                   return fingerprint(adf.grid()->tree());
               }};
        c.slow = m.bounds || m.tolerance > 0; // checks 4096 tiles at 27 points each
        c.allocationSweep = !c.slow;
        cases.push_back(c);
    }
    injectAll(cases);
}

TEST(ExceptionInjection, TetScanConversion)
{
    openvdb::initialize();
    std::vector<Case> cases;
    for (ShellMethod shell : {ShellMethod::PseudoNormal, ShellMethod::Thin, ShellMethod::Offset, ShellMethod::Obb}) {
        for (ShellCoverage coverage : {ShellCoverage::Complete, ShellCoverage::Paper}) {
            for (bool conservative : {false, true}) {
                if (conservative && (coverage == ShellCoverage::Paper || shell != ShellMethod::Obb)) continue;
                Case c{std::string("meshToLevelSetScan ") + toString(shell) +
                           (coverage == ShellCoverage::Paper ? " paper" : " complete") +
                           (conservative ? " conservative" : ""),
                       [=](openvdb::util::NullInterrupter* it) {
                           TetScanOptions o;
                           static_cast<GridSpec&>(o) = bandOptions(it);
                           o.shell = shell;
                           o.coverage = coverage;
                           o.conservative = conservative;
                           o.slabWidth = 16;
                           return fingerprint(*injectionEnds(meshToLevelSetScan(sphereMesh(), o)));
                       }};
                // the shells differ in the (serial) shell construction only; the parallel stages
                // after it are the same: the paper's hulls get the lighter series
                c.slow = coverage == ShellCoverage::Paper;
                cases.push_back(c);
            }
        }
    }
    injectAll(cases);
}

TEST(ExceptionInjection, VolumeToLevelSetDense)
{
    openvdb::initialize();
    const VolumeDistanceMethod methods[] = {
        VolumeDistanceMethod::CityBlock, VolumeDistanceMethod::Chessboard,   VolumeDistanceMethod::QuasiEuclidean3,
        VolumeDistanceMethod::Complete3, VolumeDistanceMethod::QuasiEuclidean5, VolumeDistanceMethod::EVDT,
        VolumeDistanceMethod::EVDTFullGrid, VolumeDistanceMethod::VCVDT4,    VolumeDistanceMethod::VCVDT8,
        VolumeDistanceMethod::Exact};
    std::vector<Case> cases;
    for (VolumeDistanceMethod m : methods) {
        for (bool subvoxel : {false, true}) {
            if (subvoxel && int(m) <= int(VolumeDistanceMethod::QuasiEuclidean5)) continue; // binary only
            cases.push_back({std::string("volumeToLevelSet ") + volumeDistanceMethodName(m) +
                                 (subvoxel ? " sub-voxel" : " binary"),
                             [=](openvdb::util::NullInterrupter* it) {
                                 VolumeToLevelSetOptions o;
                                 o.method = m;
                                 o.subvoxel = subvoxel;
                                 o.interrupter = it;
                                 return fingerprint(*injectionEnds(volumeToLevelSet(sphereField(), o)));
                             }});
        }
    }
    injectAll(cases);
}

TEST(ExceptionInjection, DistanceTransformsWithLanes)
{
    std::vector<Case> cases;
    for (ChamferMetric metric : {ChamferMetric::CityBlock, ChamferMetric::Chessboard, ChamferMetric::QuasiEuclidean3,
                                 ChamferMetric::Complete3, ChamferMetric::QuasiEuclidean5}) {
        Case c{std::string("chamferDistanceTransform ") + chamferMetricName(metric),
               [=](openvdb::util::NullInterrupter* it) {
                   ChamferOptions o;
                   o.interrupter = it;
                   o.threads = 2; // 2 lanes in an arena of 2, 1 in an arena of 1
                   return fingerprint(injectionEnds(chamferDistanceTransform(sphereFeatures(), metric, o)));
               }};
        c.usesLanes = true;
        cases.push_back(c);
    }
    for (VectorTransformMethod m : {VectorTransformMethod::EVDT, VectorTransformMethod::EVDTFullGrid,
                                    VectorTransformMethod::VCVDT4, VectorTransformMethod::VCVDT8}) {
        Case fromMask{std::string("vectorDistanceTransform (mask) ") + vectorTransformMethodName(m),
                      [=](openvdb::util::NullInterrupter* it) {
                          VectorTransformOptions o;
                          o.method = m;
                          o.interrupter = it;
                          o.threads = 2;
                          return fingerprint(injectionEnds(vectorDistanceTransform(sphereFeatures(), o)));
                      }};
        fromMask.usesLanes = true;
        cases.push_back(fromMask);
        Case inPlace{std::string("vectorDistanceTransform (in place) ") + vectorTransformMethodName(m),
                     [=](openvdb::util::NullInterrupter* it) {
                         VectorTransformOptions o;
                         o.method = m;
                         o.interrupter = it;
                         o.threads = 2;
                         VectorVolume v = initVectorVolume(sphereFeatures());
                         try {
                             vectorDistanceTransform(v, o);
                             injectionEnds();
                         } catch (...) {
                             // An interrupted or failed transform leaves every voxel in
                             // ClosestVector order (no row left in the lanes' grouped layout):
                             // each holds +inf or a vector whose squared length is its d2.
                             const openvdb::Vec3f sp(v.spacing);
                             size_t bad = 0;
                             for (const ClosestVector& c : v.data) {
                                 if (std::isinf(c.d2) && std::isinf(c.x)) continue;
                                 const float l2 = vectorLengthSquared(c.x, c.y, c.z, sp);
                                 if (!(std::abs(l2 - c.d2) <= 1e-4f * std::max(1.0f, c.d2))) ++bad;
                             }
                             EXPECT_EQ(bad, 0u) << "voxels left scrambled by the failed in-place transform";
                             throw;
                         }
                         return fingerprint(v);
                     }};
        inPlace.usesLanes = true;
        cases.push_back(inPlace);
    }
    cases.push_back({"exactDistanceTransform", [](openvdb::util::NullInterrupter* it) {
                         ExactTransformOptions o;
                         o.interrupter = it;
                         return fingerprint(injectionEnds(exactDistanceTransform(sphereFeatures(), o)));
                     }});
    cases.push_back({"distanceTransformReport", [](openvdb::util::NullInterrupter* it) {
                         DistanceTransformReportOptions o;
                         o.interrupter = it;
                         Hash h;
                         const std::vector<DistanceTransformComparison> report =
                             injectionEnds(distanceTransformReport(insideMask(sphereField(), 0.0f), o));
                         for (const DistanceTransformComparison& r : report) {
                             h.add(r.minError);
                             h.add(r.maxError);
                             h.add(uint64_t(r.voxelsWithError));
                         }
                         return h.h;
                     }});
    injectAll(cases);
}

TEST(ExceptionInjection, SubvoxelShell)
{
    std::vector<Case> cases;
    cases.push_back({"subvoxelShell", [](openvdb::util::NullInterrupter* it) {
                         SubvoxelShellOptions o;
                         o.interrupter = it;
                         if (it) it->start("shell"); // subvoxelShell() only polls
                         const uint64_t fp = fingerprint(injectionEnds(subvoxelShell(sphereField(), o)));
                         if (it) it->end();
                         return fp;
                     }});
    injectAll(cases);
}

TEST(ExceptionInjection, SparseVolumeToLevelSet)
{
    openvdb::initialize();
    std::vector<Case> cases;
    for (VolumeDistanceMethod m : {VolumeDistanceMethod::VCVDT8, VolumeDistanceMethod::Exact}) {
        for (bool fill : {false, true}) {
            cases.push_back({std::string("sparseVolumeToLevelSet ") + volumeDistanceMethodName(m) +
                                 (fill ? " fill interior" : ""),
                             [=](openvdb::util::NullInterrupter* it) {
                                 VolumeToLevelSetOptions o;
                                 o.method = m;
                                 o.fillInterior = fill;
                                 o.interrupter = it;
                                 return fingerprint(*injectionEnds(sparseVolumeToLevelSet(sphereFieldGrid(), o)));
                             }});
        }
    }
    injectAll(cases);
}

TEST(ExceptionInjection, MeshToSdfPipeline)
{
    openvdb::initialize();
    std::vector<Case> cases;
    for (BandMethod band : {BandMethod::Chang, BandMethod::Scan}) {
        for (Expansion e : {Expansion::None, Expansion::Sweep, Expansion::Vector}) {
            const char* en = e == Expansion::None ? "none" : e == Expansion::Sweep ? "sweep" : "vector";
            cases.push_back({std::string("meshToSdf ") + (band == BandMethod::Chang ? "chang" : "scan") + " + " + en,
                             [=](openvdb::util::NullInterrupter* it) {
                                 MeshToSdfOptions o;
                                 o.voxelSize = kVoxelSize;
                                 o.exteriorWidth = o.interiorWidth = 4.0;
                                 o.method = band;
                                 o.expansion = e;
                                 o.exactBandVoxels = 2.0;
                                 o.interrupter = it;
                                 return fingerprint(*injectionEnds(meshToSdf(sphereMesh(), o)));
                             }});
        }
    }
    injectAll(cases);
}

// ---- poll density (item 4) -----------------------------------------------------------------

namespace {

/// 20480 triangles on a sphere of 12 voxels' diameter: the whole mesh crowds into the few leaves
/// of its band (34), each with hundreds of triangles, so each leaf is a lot of work (box tests of
/// the hierarchy, bounds, exact distances) between two chances to poll.
struct PathologicalRun
{
    MeshToLevelSetStats stats;
    std::vector<int> percents;
    int64_t distancePolls = 0; ///< polls between the 20 % check and the closing 100 % report
};

PathologicalRun runPathological()
{
    openvdb::initialize();
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 5);
    InjectingInterrupter counter;
    counter.record();
    MeshToLevelSetOptions o;
    o.voxelSize = 2.0 / 12.0;
    o.interrupter = &counter;
    PathologicalRun r;
    inArena(2, [&] { meshToLevelSet(mesh, o, &r.stats); });
    r.percents = counter.percents();
    // the distance stage polls with 20 + 75 * done / leaves after its leaves (the 20 % check
    // comes first; the 100 % report last)
    const auto first20 = std::find(r.percents.begin(), r.percents.end(), 20);
    if (first20 != r.percents.end())
        for (auto p = first20 + 1; p != r.percents.end(); ++p)
            if (*p >= 20 && *p < 100) ++r.distancePolls;
    return r;
}

} // namespace

TEST(ExceptionInjectionPolls, PathologicalMeshPollsDuringDistances)
{
    const PathologicalRun r = runPathological();
    std::cout << "[ polls ] " << r.stats.triangles << " triangles, " << r.stats.candidateLeaves
              << " candidate leaves, " << r.stats.distanceEvaluations << " exact evaluations, "
              << r.stats.nodeTests << " node tests; " << r.percents.size() << " polls in all, "
              << r.distancePolls << " in the distance stage ("
              << (r.distancePolls ? double(r.stats.distanceEvaluations) / double(r.distancePolls) : 0.0)
              << " evaluations per poll)\n";
    ASSERT_GT(r.stats.candidateLeaves, 0u);
    // every stage polls: the hierarchy, the candidates (10 %, 20 %), the distances, the end
    EXPECT_GE(r.percents.size(), 4u);
    EXPECT_GE(r.distancePolls, 1) << "the distance stage never polls";
}

TEST(ExceptionInjectionPolls, AdaptiveDistanceFieldBoundsStagePolls)
{
    // the error-bound stage (computeBounds) runs after the value pipeline's 80 % check, and
    // takes most of the time of a small ADF: it must poll too
    openvdb::initialize();
    InjectingInterrupter counter;
    counter.record();
    AdaptiveDistanceFieldOptions o;
    o.voxelSize = kVoxelSize;
    o.computeBounds = true;
    o.interrupter = &counter;
    inArena(2, [&] { meshToAdaptiveDistanceField(adfMesh(), o); });
    const std::vector<int> p = counter.percents();
    const auto last80 = std::find(p.rbegin(), p.rend(), 80);
    ASSERT_NE(last80, p.rend()) << "no 80 % check";
    EXPECT_GT(std::count_if(p.rbegin(), last80, [](int percent) { return percent != 100; }), 0)
        << "the error-bound stage never polls the interrupter";
}

// The bound item 4 asks for, counted in work instead of time: at least one poll every
// kEvaluationsPerPoll exact evaluations (well under a millisecond), also inside a leaf. The
// distance stage of src/mesh/MeshToLevelSet.cc polls by work done (WorkPoller) as well as by the
// clock between leaves; a count proves the first.
TEST(ExceptionInjectionPolls, PathologicalMeshPollsByWork)
{
    constexpr uint64_t kEvaluationsPerPoll = 8192;
    const PathologicalRun r = runPathological();
    EXPECT_GE(uint64_t(r.distancePolls), r.stats.distanceEvaluations / kEvaluationsPerPoll)
        << r.stats.distanceEvaluations << " exact evaluations in " << r.stats.candidateLeaves << " leaves";
}
