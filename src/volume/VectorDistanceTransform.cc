// levelforge — dense vector distance transforms (Satherley & Jones VCVDT, Mullikin EVDT).
// See include/levelforge/volume/VectorDistanceTransform.h for the method and the pass tables.
#include <levelforge/volume/VectorDistanceTransform.h>

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define LEVELFORGE_CPU_RELAX() _mm_pause()
#define LEVELFORGE_PREFETCH(p) _mm_prefetch((p), _MM_HINT_T0)
#else
#define LEVELFORGE_PREFETCH(p) __builtin_prefetch((p))
#define LEVELFORGE_CPU_RELAX() ((void)0)
#endif

namespace levelforge {

namespace vector_transform_internal {

namespace {

// Every pass must have the shape the kernel implements: candidates in the order vertical
// (0,0,±1), previous row (0,-yOrder,0), previous voxel of the row (-xOrder,0,0), the last one
// always present; a perRow pass has only the in-row neighbour.
constexpr bool passShapeOk(const PassDef& p, int zOrder)
{
    if (p.neighbourCount < 1 || p.neighbourCount > 3) return false;
    if ((p.xOrder != 1 && p.xOrder != -1) || (p.yOrder != 1 && p.yOrder != -1)) return false;
    const Offset last = p.neighbours[p.neighbourCount - 1];
    if (last.x != -p.xOrder || last.y != 0 || last.z != 0) return false;
    int i = 0;
    if (i < p.neighbourCount - 1 && p.neighbours[i].z != 0) {
        if (p.neighbours[i].z != -zOrder || p.neighbours[i].x != 0 || p.neighbours[i].y != 0) return false;
        ++i;
    }
    if (i < p.neighbourCount - 1) {
        if (p.neighbours[i].y != -p.yOrder || p.neighbours[i].x != 0 || p.neighbours[i].z != 0) return false;
        ++i;
    }
    if (i != p.neighbourCount - 1) return false;
    if (p.perRow && p.neighbourCount != 1) return false;
    return true;
}

constexpr bool methodShapeOk(const MethodDef& m)
{
    for (int s = 0; s < 2; ++s) {
        const SweepDef& sw = m.sweeps[s];
        if (sw.passCount < 1 || sw.passCount > 4 || sw.passes[0].perRow) return false;
        for (int p = 0; p < sw.passCount; ++p) {
            if (!passShapeOk(sw.passes[p], sw.zOrder)) return false;
            if (sw.passes[p].perRow && sw.passes[p].yOrder != sw.passes[p - 1].yOrder) return false;
            // Only the first pass reads the previous slice (the grouped layout relies on it).
            for (int i = 0; p > 0 && i < sw.passes[p].neighbourCount; ++i)
                if (sw.passes[p].neighbours[i].z != 0) return false;
        }
    }
    return m.sweeps[0].zOrder == 1 && m.sweeps[1].zOrder == -1;
}

static_assert(methodShapeOk(kVCVDT4), "VCVDT4 pass table");
static_assert(methodShapeOk(kVCVDT8), "VCVDT8 pass table");
static_assert(methodShapeOk(kEVDT), "EVDT pass table");
static_assert(methodShapeOk(kEVDTFullGrid), "EVDT full grid pass table");

/// Sense-counting spin barrier for a fixed set of std::thread lanes (all of which exist, so
/// spinning always ends). Yields after a short spin so that oversubscribed machines progress.
class SpinBarrier
{
public:
    explicit SpinBarrier(int n) : mN(n) {}
    void wait()
    {
        const int gen = mGeneration.load(std::memory_order_acquire);
        if (mCount.fetch_add(1, std::memory_order_acq_rel) == mN - 1) {
            mCount.store(0, std::memory_order_relaxed);
            mGeneration.fetch_add(1, std::memory_order_acq_rel);
            return;
        }
        for (int spin = 0; mGeneration.load(std::memory_order_acquire) == gen; ++spin) {
            if (spin < 256) LEVELFORGE_CPU_RELAX();
            else std::this_thread::yield();
        }
    }

private:
    const int mN;
    std::atomic<int> mCount{0};
    std::atomic<int> mGeneration{0};
};

struct alignas(64) Progress
{
    std::atomic<int64_t> value{0};
};

/// Runs lane(1..lanes-1) on std::threads and lane(0) on the calling thread, then joins them all.
/// Real threads, not TBB tasks: lanes spin-wait for each other, which must not deadlock.
void runLanes(int lanes, const std::function<void(int)>& lane)
{
    std::vector<std::thread> threads;
    threads.reserve(size_t(std::max(0, lanes - 1)));
    for (int t = 1; t < lanes; ++t) threads.emplace_back(lane, t);
    lane(0);
    for (auto& th : threads) th.join();
}

} // namespace

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

    std::unique_ptr<Progress[]> progress(new Progress[size_t(rows)]);
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
                            if (spin < 1024) LEVELFORGE_CPU_RELAX();
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

} // namespace vector_transform_internal

namespace {

using namespace vector_transform_internal;

constexpr float kInf = std::numeric_limits<float>::infinity();

struct Spacing
{
    float sx, sy, sz;
};


// ---------------------------------------------------------------------------------------------
// Working layout. For the duration of a transform the volume's storage is reordered IN PLACE,
// row by row, into groups of 8 voxels along x (AoSoA): group g of a row holds x[8], y[8], z[8],
// d2[8] (a row's last group of w = nx - 8g < 8 voxels has the same layout with stride w). The
// bytes of a group are the bytes of its 8 ClosestVectors, so no memory is added, and the
// reorder is undone before vectorDistanceTransform() returns (also on interruption).
constexpr int kGroup = 8;
/// Fewest groups (of 8 columns) a lane gets; narrower volumes use fewer lanes.
constexpr int kMinGroupsPerLane = 4;
/// Rows a lane finishes between two publications of its progress.
constexpr int kPublishRows = 16;
/// Rows the first pass of a slice prefetches ahead.
constexpr int kPrefetchRows = 4;

inline int groupWidth(int g, int nx) { return std::min(kGroup, nx - g * kGroup); }

/// Reorders groups [g0, g1) of one row between ClosestVector order and the grouped layout.
void reorderGroups(float* row, int g0, int g1, int nx, bool toGroups)
{
    for (int g = g0; g < g1; ++g) {
        const int w = groupWidth(g, nx);
        float* b = row + size_t(g) * kGroup * 4;
#if defined(__SSE2__)
        if (w == kGroup) {
            // Two 4 x 4 transposes: voxels 0-3 and 4-7 <-> x, y, z, d2 of 4 voxels each.
            __m128 r[8];
            if (toGroups) {
                for (int i = 0; i < 8; ++i) r[i] = _mm_loadu_ps(b + 4 * i); // voxel i
            } else {
                for (int c = 0; c < 4; ++c) {
                    r[c] = _mm_loadu_ps(b + 8 * c);         // component c of voxels 0-3
                    r[4 + c] = _mm_loadu_ps(b + 8 * c + 4); // component c of voxels 4-7
                }
            }
            _MM_TRANSPOSE4_PS(r[0], r[1], r[2], r[3]);
            _MM_TRANSPOSE4_PS(r[4], r[5], r[6], r[7]);
            if (toGroups) {
                for (int c = 0; c < 4; ++c) {
                    _mm_storeu_ps(b + 8 * c, r[c]);
                    _mm_storeu_ps(b + 8 * c + 4, r[4 + c]);
                }
            } else {
                for (int i = 0; i < 8; ++i) _mm_storeu_ps(b + 4 * i, r[i]);
            }
            continue;
        }
#endif
        float tmp[4 * kGroup];
        for (int l = 0; l < w; ++l)
            for (int c = 0; c < 4; ++c) {
                if (toGroups) tmp[c * w + l] = b[l * 4 + c];
                else tmp[l * 4 + c] = b[c * w + l];
            }
        std::memcpy(b, tmp, sizeof(float) * 4 * size_t(w));
    }
}

/// reorderGroups() on every row of the volume (TBB).
void reorderRows(float* base, int nx, size_t rows, bool toGroups)
{
    const int groups = (nx + kGroup - 1) / kGroup;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rows, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) reorderGroups(base + i * size_t(nx) * 4, 0, groups, nx, toGroups);
    });
}

/// Puts the volume into the grouped layout for its lifetime (the two-slice EVDT).
class GroupedScope
{
public:
    GroupedScope(float* base, int nx, size_t rows) : mBase(base), mNx(nx), mRows(rows)
    {
        reorderRows(mBase, mNx, mRows, true);
    }
    ~GroupedScope() { reorderRows(mBase, mNx, mRows, false); }
    GroupedScope(const GroupedScope&) = delete;
    GroupedScope& operator=(const GroupedScope&) = delete;

private:
    float* mBase;
    int mNx;
    size_t mRows;
};

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
using v8f = float __attribute__((vector_size(32)));
using v8i = int32_t __attribute__((vector_size(32)));

#define LEVELFORGE_AI inline __attribute__((always_inline))

LEVELFORGE_AI v8f load8(const float* p)
{
    v8f v;
    std::memcpy(&v, p, sizeof(v));
    return v;
}
LEVELFORGE_AI void store8(float* p, const v8f& v) { std::memcpy(p, &v, sizeof(v)); }

/// One candidate for 8 voxels at once: (nx, ny, nz) replaces (X, Y, Z, D) where its d2 is
/// strictly smaller. The same single-precision operations as the scalar step (no FMA), so
/// every lane gets the bits the scalar code would.
/// Whether any lane of a comparison result is set.
LEVELFORGE_AI bool anyLane(const v8i& m)
{
    uint64_t bits[4];
    std::memcpy(bits, &m, sizeof(bits));
    return (bits[0] | bits[1] | bits[2] | bits[3]) != 0;
}

template<bool Unit>
LEVELFORGE_AI void tryCandidate8(v8f& X, v8f& Y, v8f& Z, v8f& D, v8f& YZ, v8i& changed, const v8f& nx,
                                 const v8f& ny, const v8f& nz, const Spacing& s)
{
    const v8f Xs = Unit ? nx : nx * s.sx, Ys = Unit ? ny : ny * s.sy, Zs = Unit ? nz : nz * s.sz;
    const v8f nyz = Ys * Ys + Zs * Zs;
    const v8f d2 = Xs * Xs + nyz;
    const v8i m = d2 < D;
    changed |= m;
    X = m ? nx : X;
    Y = m ? ny : Y;
    Z = m ? nz : Z;
    D = m ? d2 : D;
    YZ = m ? nyz : YZ;
}

template<bool Unit>
LEVELFORGE_AI void tryCandidate1(float& X, float& Y, float& Z, float& D, float& YZ, float nx, float ny, float nz,
                                 const Spacing& s)
{
    const float Xs = Unit ? nx : nx * s.sx, Ys = Unit ? ny : ny * s.sy, Zs = Unit ? nz : nz * s.sz;
    const float nyz = Ys * Ys + Zs * Zs;
    const float d2 = Xs * Xs + nyz;
    if (d2 < D) {
        X = nx;
        Y = ny;
        Z = nz;
        D = d2;
        YZ = nyz;
    }
}

/// The element-wise part of a pass on groups [g0, g1) of one row: the vertical candidate
/// (previous slice, offset oz) and the previous-row candidate (offset oy), in the table order,
/// neither of which depends on the row's own chain. Writes each voxel's Y*Y + Z*Z to yz[x].
template<bool Vert, bool Row, bool Unit>
LEVELFORGE_AI void rowCandidates(float* row, const float* prevRow, const float* vertRow, float* yz, int g0, int g1,
                                 int nx, float oy, float oz, const Spacing& s)
{
    for (int g = g0; g < g1; ++g) {
        const int w = groupWidth(g, nx);
        const size_t off = size_t(g) * kGroup * 4;
        float* c = row + off;
        float* yzg = yz + size_t(g) * kGroup;
        if (w == kGroup) {
            v8f X = load8(c), Y = load8(c + 8), Z = load8(c + 16), D = load8(c + 24);
            const v8f Ys = Unit ? Y : Y * s.sy, Zs = Unit ? Z : Z * s.sz;
            v8f YZ = Ys * Ys + Zs * Zs;
            v8i changed = v8i{};
            if constexpr (Vert) {
                const float* n = vertRow + off;
                tryCandidate8<Unit>(X, Y, Z, D, YZ, changed, load8(n), load8(n + 8), load8(n + 16) + oz, s);
            }
            if constexpr (Row) {
                const float* n = prevRow + off;
                tryCandidate8<Unit>(X, Y, Z, D, YZ, changed, load8(n), load8(n + 8) + oy, load8(n + 16), s);
            }
            if constexpr (Vert || Row) {
                // Most groups keep their vectors: writing only changed groups keeps the lines
                // clean (no write-back, no line shared with the next lane's range dirtied).
                if (anyLane(changed)) {
                    store8(c, X);
                    store8(c + 8, Y);
                    store8(c + 16, Z);
                    store8(c + 24, D);
                }
            }
            store8(yzg, YZ);
        } else {
            for (int l = 0; l < w; ++l) {
                float X = c[l], Y = c[w + l], Z = c[2 * w + l], D = c[3 * w + l];
                const float Ys = Unit ? Y : Y * s.sy, Zs = Unit ? Z : Z * s.sz;
                float YZ = Ys * Ys + Zs * Zs;
                if constexpr (Vert) {
                    const float* n = vertRow + off;
                    tryCandidate1<Unit>(X, Y, Z, D, YZ, n[l], n[w + l], n[2 * w + l] + oz, s);
                }
                if constexpr (Row) {
                    const float* n = prevRow + off;
                    tryCandidate1<Unit>(X, Y, Z, D, YZ, n[l], n[w + l] + oy, n[2 * w + l], s);
                }
                c[l] = X;
                c[w + l] = Y;
                c[2 * w + l] = Z;
                c[3 * w + l] = D;
                yzg[l] = YZ;
            }
        }
    }
}

/// The chain carried along a row: the previous voxel's final vector and its Y*Y + Z*Z.
struct Carry
{
    float x = kInf, y = kInf, z = kInf, yz = kInf;
};

/// One in-row step on voxel l of a group of width w: the previous voxel's vector moved by ox
/// against the voxel's current one.
template<bool Unit>
LEVELFORGE_AI void chainStep(float* c, const float* yzg, int l, int w, Carry& p, float ox, float sx)
{
    const float cx = p.x + ox;
    const float X = Unit ? cx : cx * sx;
    const float d2 = X * X + p.yz;
    if (d2 < c[3 * w + l]) {
        c[l] = cx;
        c[w + l] = p.y;
        c[2 * w + l] = p.z;
        c[3 * w + l] = d2;
        p.x = cx;
    } else {
        p.x = c[l];
        p.y = c[w + l];
        p.z = c[2 * w + l];
        p.yz = yzg[l];
    }
}

/// The chain through one group (w voxels at c, their Y*Y + Z*Z at yzg) in x order xs.
template<bool Unit>
LEVELFORGE_AI void chainGroup(float* c, const float* yzg, const int w, const int xs, Carry& p, const float ox,
                              const float sx)
{
    if (w == kGroup) {
        // Most groups keep every voxel (about 90 % on a sphere): test all 8 steps at once on
        // the assumption that no voxel changes, each candidate coming from the previous
        // voxel's current vector (the first from the carry). If none wins, the assumption
        // holds and the chain leaves the group as it is; otherwise run the steps one by one.
        // Same operations, so the same comparisons as the scalar steps.
        const v8f X = load8(c), D = load8(c + 24), YZ = load8(yzg);
        const v8f px = v8f{} + p.x, pyz = v8f{} + p.yz;
        const v8f cxs = xs > 0 ? __builtin_shuffle(X, px, v8i{8, 0, 1, 2, 3, 4, 5, 6})
                               : __builtin_shuffle(X, px, v8i{1, 2, 3, 4, 5, 6, 7, 8});
        const v8f yzs = xs > 0 ? __builtin_shuffle(YZ, pyz, v8i{8, 0, 1, 2, 3, 4, 5, 6})
                               : __builtin_shuffle(YZ, pyz, v8i{1, 2, 3, 4, 5, 6, 7, 8});
        const v8f cx = cxs + ox;
        const v8f Xs = Unit ? cx : cx * sx;
        const v8i win = (Xs * Xs + yzs) < D;
        if (!anyLane(win)) {
            const int last = xs > 0 ? kGroup - 1 : 0;
            p.x = c[last];
            p.y = c[kGroup + last];
            p.z = c[2 * kGroup + last];
            p.yz = yzg[last];
        } else if (xs > 0) {
            for (int l = 0; l < kGroup; ++l) chainStep<Unit>(c, yzg, l, kGroup, p, ox, sx);
        } else {
            for (int l = kGroup - 1; l >= 0; --l) chainStep<Unit>(c, yzg, l, kGroup, p, ox, sx);
        }
    } else {
        // The short last group of a row (stride w): one step at a time.
        for (int k = 0; k < w; ++k) chainStep<Unit>(c, yzg, xs > 0 ? k : w - 1 - k, w, p, ox, sx);
    }
}

/// The sequential part of a pass on groups [g0, g1) of one row, in x order xs (+1 / -1),
/// starting from carry p (the voxel before the span in pass order, or +inf) and leaving the
/// span's last voxel in it.
template<bool Unit>
LEVELFORGE_AI void rowChain(float* row, const float* yz, int g0, int g1, int nx, int xs, Carry& carry, const Spacing& s)
{
    const float ox = float(-xs), sx = s.sx;
    Carry p = carry; // a local copy stays in registers (the row may alias `carry`)
    const int gl = g1 - 1;
    const int wl = groupWidth(gl, nx);
    auto group = [&](int g) __attribute__((always_inline)) {
        chainGroup<Unit>(row + size_t(g) * kGroup * 4, yz + size_t(g) * kGroup, g == gl ? wl : kGroup, xs, p, ox, sx);
    };
    if (xs > 0)
        for (int g = g0; g < g1; ++g) group(g);
    else
        for (int g = g1 - 1; g >= g0; --g) group(g);
    carry = p;
}
#pragma GCC diagnostic pop

struct PassShape
{
    bool vert = false, row = false;
    float oy = 0, oz = 0;
};

PassShape shapeOf(const PassDef& p)
{
    PassShape sh;
    for (int i = 0; i + 1 < p.neighbourCount; ++i) {
        if (p.neighbours[i].z != 0) {
            sh.vert = true;
            sh.oz = p.neighbours[i].z;
        } else {
            sh.row = true;
            sh.oy = p.neighbours[i].y;
        }
    }
    return sh;
}

/// One row's share of a pass, on the grouped layout: rows are nx voxels = 4 * nx floats.
struct RowTask
{
    float* row;
    const float* prevRow; // null: no previous-row candidate (first row, or not in the pass)
    const float* vertRow; // null: no vertical candidate
    float oy, oz;
    int xs;
    int g0, g1; // groups of the span
    int nx;
};

/// The element-wise candidates of a row task (the pass shape picks the kernel).
template<bool Unit>
LEVELFORGE_AI void rowTaskCandidates(const RowTask& t, float* yz, const Spacing& s)
{
    if (t.vertRow && t.prevRow)
        rowCandidates<true, true, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
    else if (t.vertRow)
        rowCandidates<true, false, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
    else if (t.prevRow)
        rowCandidates<false, true, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
    else
        rowCandidates<false, false, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
}

void rowCandidatesBase(const RowTask& t, float* yz, const Spacing& s, bool unit)
{
    if (unit) rowTaskCandidates<true>(t, yz, s);
    else rowTaskCandidates<false>(t, yz, s);
}

void rowChainBase(const RowTask& t, const float* yz, Carry& carry, const Spacing& s, bool unit)
{
    if (unit) rowChain<true>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
    else rowChain<false>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
}

#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
#define LEVELFORGE_VDT_AVX 1
// The same kernel compiled for AVX2: the element-wise candidates run 8 voxels per instruction,
// the chain gets the VEX three-operand encoding. The arithmetic is the same IEEE single
// precision and FMA is NOT enabled (nothing is contracted), so the results are bit-identical.
__attribute__((target("avx2"))) void rowCandidatesAvx2(const RowTask& t, float* yz, const Spacing& s, bool unit)
{
    if (unit) rowTaskCandidates<true>(t, yz, s);
    else rowTaskCandidates<false>(t, yz, s);
}

__attribute__((target("avx2"))) void rowChainAvx2(const RowTask& t, const float* yz, Carry& carry, const Spacing& s,
                                                  bool unit)
{
    if (unit) rowChain<true>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
    else rowChain<false>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
}

bool cpuHasAvx2()
{
    static const bool has = __builtin_cpu_supports("avx2");
    return has;
}
#endif

std::atomic<bool> gAvx2KernelEnabled{true}; // testing hook (vector_transform_internal)

/// The kernel build (baseline or AVX2) chosen once per transform.
struct Kernel
{
    void (*candidates)(const RowTask&, float*, const Spacing&, bool) = rowCandidatesBase;
    void (*chain)(const RowTask&, const float*, Carry&, const Spacing&, bool) = rowChainBase;
    Spacing s{1, 1, 1};
    bool unit = true;
    bool avx2 = false; // the AVX2 builds are in use (also picks MaskIo's row conversions)

    Kernel(const Spacing& sp) : s(sp), unit(sp.sx == 1.0f && sp.sy == 1.0f && sp.sz == 1.0f)
    {
#ifdef LEVELFORGE_VDT_AVX
        if (cpuHasAvx2() && gAvx2KernelEnabled.load(std::memory_order_relaxed)) {
            avx2 = true;
            candidates = rowCandidatesAvx2;
            chain = rowChainAvx2;
        }
#endif
    }
};

/// Geometry of one slice on the grouped layout.
struct SliceView
{
    float* slice;
    const float* vertSlice; // the previous slice in sweep order, or null
    int nx, ny;
};

/// The task of pass p, row r (in pass order), groups [g0, g1).
RowTask rowTask(const PassDef& p, const SliceView& v, int r, int g0, int g1)
{
    const PassShape sh = shapeOf(p);
    const int y = p.yOrder > 0 ? r : v.ny - 1 - r;
    const size_t rowFloats = size_t(v.nx) * 4;
    RowTask t;
    t.row = v.slice + size_t(y) * rowFloats;
    t.prevRow = (sh.row && r > 0) ? v.slice + size_t(y - p.yOrder) * rowFloats : nullptr;
    t.vertRow = (sh.vert && v.vertSlice) ? v.vertSlice + size_t(y) * rowFloats : nullptr;
    t.oy = sh.oy;
    t.oz = sh.oz;
    t.xs = p.xOrder;
    t.g0 = g0;
    t.g1 = g1;
    t.nx = v.nx;
    return t;
}

/// A pass together with the perRow passes that follow it.
struct PassGroup
{
    int first, end;
};

std::vector<PassGroup> groupsOf(const SweepDef& sw)
{
    std::vector<PassGroup> g;
    for (int p = 0; p < sw.passCount; ++p) {
        if (sw.passes[p].perRow) g.back().end = p + 1;
        else g.push_back({p, p + 1});
    }
    return g;
}

bool hasPerRow(const MethodDef& m)
{
    for (const auto& sw : m.sweeps)
        for (int p = 0; p < sw.passCount; ++p)
            if (sw.passes[p].perRow) return true;
    return false;
}

/// Row r of pass group g over the whole row, serially (with its perRow passes).
void runGroupRowSerial(const SweepDef& sw, const PassGroup& g, const SliceView& v, int r, float* yz,
                       const Kernel& k)
{
    const int groups = (v.nx + kGroup - 1) / kGroup;
    for (int p = g.first; p < g.end; ++p) {
        // A perRow pass follows its pass on the same row (same y).
        const RowTask t = rowTask(sw.passes[p], v, r, 0, groups);
        Carry carry;
        k.candidates(t, yz, k.s, k.unit);
        k.chain(t, yz, carry, k.s, k.unit);
    }
}

void checkInterrupt(openvdb::util::NullInterrupter* interrupter, int percent)
{
    if (interrupter && interrupter->wasInterrupted(percent)) {
        interrupter->end();
        throw InterruptedError("vector distance transform interrupted");
    }
}

/// Mullikin's two-slice EVDT (grouped layout): each sweep starts from the input vectors and
/// keeps the current and the previous slice; the result is the shorter vector per voxel.
void runTwoSlices(VectorVolume& v, const MethodDef& m, const Kernel& k, openvdb::util::NullInterrupter* interrupter)
{
    const int nx = v.dims.x(), ny = v.dims.y(), nz = v.dims.z();
    const size_t nxy = size_t(nx) * size_t(ny), sliceFloats = nxy * 4, rowFloats = size_t(nx) * 4;
    float* data = reinterpret_cast<float*>(v.data.data());
    std::vector<float> result(v.data.size() * 4);
    std::vector<float> prev(sliceFloats), cur(sliceFloats), yz(size_t(nx) + kGroup);
    for (int s = 0; s < 2; ++s) {
        const SweepDef& sw = m.sweeps[s];
        const auto groups = groupsOf(sw);
        for (int i = 0; i < nz; ++i) {
            checkInterrupt(interrupter, int((100.0 * (s * nz + i)) / (2.0 * nz)));
            const int z = sw.zOrder > 0 ? i : nz - 1 - i;
            const float* in = data + size_t(z) * sliceFloats;
            std::copy(in, in + sliceFloats, cur.begin());
            const SliceView view{cur.data(), i > 0 ? prev.data() : nullptr, nx, ny};
            for (const PassGroup& g : groups)
                for (int r = 0; r < ny; ++r) runGroupRowSerial(sw, g, view, r, yz.data(), k);
            float* out = result.data() + size_t(z) * sliceFloats;
            if (s == 0) {
                std::copy(cur.begin(), cur.end(), out);
            } else {
                for (int y = 0; y < ny; ++y)
                    for (int x0 = 0; x0 < nx; x0 += kGroup) {
                        const int w = std::min(kGroup, nx - x0);
                        const size_t b = size_t(y) * rowFloats + size_t(x0) * 4;
                        for (int l = 0; l < w; ++l)
                            if (cur[b + 3 * w + l] < out[b + 3 * w + l])
                                for (int c = 0; c < 4; ++c) out[b + c * w + l] = cur[b + c * w + l];
                    }
            }
            std::swap(prev, cur);
        }
    }
    std::copy(result.begin(), result.end(), data);
}

/// Spin until `value` reaches `need`; false when `stop` is raised first. The lanes wait about
/// once per slice (where a pass reverses the x order), briefly when the cores are free; when
/// they are not, the lane waited for is not running and spinning only delays it, so the wait
/// yields early.
bool waitUntil(const std::atomic<int64_t>& value, int64_t need, const std::atomic<bool>& stop, int64_t* seen = nullptr)
{
    int64_t v;
    for (int spin = 0; (v = value.load(std::memory_order_acquire)) < need; ++spin) {
        if (stop.load(std::memory_order_relaxed)) return false;
        if (spin < 32) LEVELFORGE_CPU_RELAX();
        else std::this_thread::yield();
    }
    if (seen) *seen = v;
    return true;
}

/// The full-grid methods (VCVDT4, VCVDT8, EVDTFullGrid) over a storage policy `Io`: the passes
/// run on slices in the grouped layout that io.slice(z) returns, and the policy's hooks move rows
/// in and out of that layout (InPlaceIo: the volume itself; MaskIo: two slice buffers fed from a
/// mask, with a compact store between the sweeps).
///
/// Lanes own COLUMNS: lane t owns the groups [G_t, G_t+1) of every row of every slice and runs
/// every pass of every slice on them, in the serial order. A voxel's candidates come from its own
/// previous-pass value, the previous row and the previous slice (both in the lane's own columns)
/// and the previous voxel of its row; only the last crosses a column boundary, so the upstream
/// lane (t - 1 for passes in +x order, t + 1 for -x) publishes its row's final vector and
/// Y*Y + Z*Z in a carry slot with a progress counter, and the downstream lane starts that row's
/// chain after it (the row's element-wise candidates run before the wait). Every voxel therefore
/// sees exactly the values of the serial order: results are bit-identical for any lane count.
/// Only one vector per row and pass crosses between cores; the hooks touch only the lane's own
/// columns. Methods with perRow passes (EVDT's F2/B2, which reverse the x order on each row) run
/// on one lane.
///
/// Hooks, all on the lane's groups [g0, g1) of one row (y) of slice z:
///  - rowStart(lane, sweep, z, y): before the first pass of the slice in this sweep reads the row;
///  - vertDone(lane, sweep, vz, y): after that pass has read row y of the previous slice vz for
///    the last time in this sweep;
///  - rowEnd(lane, sweep, z, y): after the last pass of the slice in this sweep has finished the
///    row (its values are final for the sweep);
///  - prefetch(lane, sweep, z, y): the first pass of the slice will soon start row y;
///  - finish(lane, z): after the last stage (z = the last slice of the backward sweep);
///  - cleanup(lane): always, last (also after an interruption or an exception).
template<class Io>
void runFullGrid(Io& io, const MethodDef& m, const Kernel& k, openvdb::util::NullInterrupter* interrupter, int threads,
                 int& lanesUsed)
{
    const int nx = io.nx, ny = io.ny, nz = io.nz;
    struct Stage
    {
        int sweep, z;
        PassGroup group;
        bool sliceStart, sliceEnd;
    };
    std::vector<Stage> stages;
    for (int s = 0; s < 2; ++s) {
        const SweepDef& sw = m.sweeps[s];
        const auto groups = groupsOf(sw);
        for (int i = 0; i < nz; ++i) {
            const int z = sw.zOrder > 0 ? i : nz - 1 - i;
            for (size_t g = 0; g < groups.size(); ++g)
                stages.push_back({s, z, groups[g], g == 0, g + 1 == groups.size()});
        }
    }
    const int total = int(stages.size());
    const int columnGroups = (nx + kGroup - 1) / kGroup;
    int lanes = hasPerRow(m) ? 1 : laneCountFor(nx, ny, threads);
    lanes = std::max(1, std::min(lanes, columnGroups / kMinGroupsPerLane));
    lanesUsed = lanes;

    // Carry slots: lane t's last vector of row r in stage si lives in slot si % kCarryRing. A lane
    // starting stage si first waits until its neighbours have finished stage si - kCarryRing, so
    // a slot is never overwritten before it was read.
    constexpr int kCarryRing = 8;
    std::vector<Carry> carries(lanes > 1 ? size_t(lanes) * kCarryRing * size_t(ny) : 0);
    std::unique_ptr<Progress[]> progress(new Progress[size_t(lanes)]);
    std::atomic<bool> stop{false};
    std::exception_ptr error;
    std::mutex errorMutex;

    // lane t owns the groups [firstGroup(t), firstGroup(t + 1))
    auto firstGroup = [&](int t) { return int((int64_t(t) * columnGroups) / lanes); };
    auto laneBody = [&](int t, typename Io::Lane& ls) {
        const int g0 = ls.g0, g1 = ls.g1;
        std::vector<float> yz(size_t(columnGroups) * kGroup);
        for (int si = 0; si < total; ++si) {
            const Stage& st = stages[size_t(si)];
            if (t == 0 && interrupter && st.sliceStart && interrupter->wasInterrupted(int((100.0 * si) / total))) {
                stop.store(true, std::memory_order_relaxed);
                return;
            }
            if (si >= kCarryRing && lanes > 1) {
                const int64_t need = int64_t(si - kCarryRing + 1) * ny;
                if (t > 0 && !waitUntil(progress[t - 1].value, need, stop)) return;
                if (t + 1 < lanes && !waitUntil(progress[t + 1].value, need, stop)) return;
            }
            if (stop.load(std::memory_order_relaxed)) return;
            const SweepDef& sw = m.sweeps[st.sweep];
            const PassDef& p = sw.passes[st.group.first];
            const int vz = st.z - sw.zOrder;
            const bool haveVert = vz >= 0 && vz < nz;
            const SliceView sv{io.slice(st.z), haveVert ? io.slice(vz) : nullptr, nx, ny};
            const int up = p.xOrder > 0 ? t - 1 : t + 1;
            const bool hasUp = up >= 0 && up < lanes;
            const bool hasDown = p.xOrder > 0 ? t + 1 < lanes : t > 0;
            const size_t slot = size_t(si % kCarryRing) * size_t(ny);
            Carry* mySlot = hasDown ? carries.data() + size_t(t) * kCarryRing * size_t(ny) + slot : nullptr;
            const Carry* upSlot = hasUp ? carries.data() + size_t(up) * kCarryRing * size_t(ny) + slot : nullptr;
            int64_t upSeen = 0; // the upstream progress last read (it only grows)
            for (int r = 0; r < ny; ++r) {
                const int y = p.yOrder > 0 ? r : ny - 1 - r;
                if (st.sliceStart) {
                    if (r + kPrefetchRows < ny)
                        io.prefetch(ls, st.sweep, st.z, p.yOrder > 0 ? r + kPrefetchRows : ny - 1 - r - kPrefetchRows);
                    io.rowStart(ls, st.sweep, st.z, y);
                }
                const RowTask task = rowTask(p, sv, r, g0, g1);
                k.candidates(task, yz.data(), k.s, k.unit);
                if (st.sliceStart && haveVert) io.vertDone(ls, st.sweep, vz, y);
                Carry carry;
                if (hasUp) {
                    const int64_t need = int64_t(si) * ny + r + 1;
                    if (upSeen < need && !waitUntil(progress[up].value, need, stop, &upSeen)) return;
                    carry = upSlot[r];
                }
                k.chain(task, yz.data(), carry, k.s, k.unit);
                if (hasDown) mySlot[r] = carry;
                // perRow passes (one lane only): right after their pass, on the same row.
                for (int q = st.group.first + 1; q < st.group.end; ++q) {
                    const RowTask rt = rowTask(sw.passes[q], sv, r, g0, g1);
                    Carry c;
                    k.candidates(rt, yz.data(), k.s, k.unit);
                    k.chain(rt, yz.data(), c, k.s, k.unit);
                }
                if (st.sliceEnd) io.rowEnd(ls, st.sweep, st.z, y);
                // Published every few rows: a counter written on every row would bounce its cache
                // line between the cores once per row, which costs as much as the row itself.
                if (lanes > 1 && ((r + 1) % kPublishRows == 0 || r + 1 == ny))
                    progress[t].value.store(int64_t(si) * ny + r + 1, std::memory_order_release);
            }
        }
        io.finish(ls, stages.back().z);
    };

    std::vector<typename Io::Lane> laneStates;
    laneStates.reserve(size_t(lanes));
    for (int t = 0; t < lanes; ++t) laneStates.push_back(io.lane(firstGroup(t), firstGroup(t + 1)));
    auto lane = [&](int t) {
        try {
            laneBody(t, laneStates[size_t(t)]);
        } catch (...) {
            std::lock_guard<std::mutex> lock(errorMutex);
            if (!error) error = std::current_exception();
            stop.store(true, std::memory_order_relaxed);
        }
        io.cleanup(laneStates[size_t(t)]);
    };

    runLanes(lanes, lane);
    io.done(laneStates);
    if (error) std::rethrow_exception(error);
    if (stop.load()) {
        if (interrupter) interrupter->end();
        throw InterruptedError("vector distance transform interrupted");
    }
}

/// Storage policy of runFullGrid: the vector volume itself, in place. A row is put into the
/// grouped layout when the forward sweep first visits it and back into ClosestVector order when
/// the backward sweep has read it for the last time (as the vertical neighbour of the next slice;
/// the last slice after its last pass), so the reorder costs no pass over memory of its own. Rows
/// are never read in the other layout: only the first pass group of a sweep reads the vertical
/// neighbour (methodShapeOk). An interrupted or failed transform restores every row it regrouped.
struct InPlaceIo
{
    int nx, ny, nz;
    float* data;
    size_t rowFloats, sliceFloats;

    explicit InPlaceIo(VectorVolume& v)
        : nx(v.dims.x()), ny(v.dims.y()), nz(v.dims.z()), data(reinterpret_cast<float*>(v.data.data())),
          rowFloats(size_t(nx) * 4), sliceFloats(size_t(nx) * 4 * size_t(ny))
    {
    }

    struct alignas(64) Lane // one cache line or more each: lanes write their own only
    {
        int g0, g1;
        std::vector<uint8_t> grouped; // per row (z * ny + y): in the grouped layout now
    };
    Lane lane(int g0, int g1) { return Lane{g0, g1, std::vector<uint8_t>(size_t(nz) * size_t(ny), 0)}; }
    float* slice(int z) const { return data + size_t(z) * sliceFloats; }
    void reorderRow(Lane& l, int z, int y, bool toGroups) const
    {
        const size_t i = size_t(z) * size_t(ny) + size_t(y);
        reorderGroups(data + i * rowFloats, l.g0, l.g1, nx, toGroups);
        l.grouped[i] = toGroups;
    }
    void prefetch(Lane& l, int, int z, int y) const
    {
        // The first pass of a slice reads it from memory: every row is a new page, which the
        // hardware prefetchers do not cross, so fetch a few rows ahead.
        const char* b = reinterpret_cast<const char*>(slice(z) + size_t(y) * rowFloats + size_t(l.g0) * kGroup * 4);
        const size_t bytes = size_t(std::min(nx, l.g1 * kGroup) - l.g0 * kGroup) * 16;
        for (size_t o = 0; o < bytes; o += 64) LEVELFORGE_PREFETCH(b + o);
    }
    void rowStart(Lane& l, int sweep, int z, int y) const
    {
        if (sweep == 0) reorderRow(l, z, y, true);
    }
    void vertDone(Lane& l, int sweep, int vz, int y) const
    {
        if (sweep == 1) reorderRow(l, vz, y, false);
    }
    void rowEnd(Lane&, int, int, int) const {}
    void finish(Lane& l, int z) const
    {
        for (int y = 0; y < ny; ++y) reorderRow(l, z, y, false);
    }
    void cleanup(Lane& l) const
    {
        // Interrupted or failed: put this lane's columns back into ClosestVector order.
        for (size_t i = 0; i < l.grouped.size(); ++i)
            if (l.grouped[i]) reorderGroups(data + i * rowFloats, l.g0, l.g1, nx, false);
    }
    void done(std::vector<Lane>&) const {}
};

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
using v8s = int16_t __attribute__((vector_size(16)));
using v8b = uint8_t __attribute__((vector_size(8)));

/// The row conversions of MaskIo on groups [g0, g1) of one row (grouped layout, see MaskIo).
struct MaskRow
{
    float* row;           // the row in a slice buffer
    const uint8_t* mask;  // its mask row (fill)
    int16_t* packed;      // its 16-bit vectors (store, load)
    float* out;           // its distances (finish)
    int g0, g1, nx;
};

/// Eq. 8: (0, 0, 0, 0) at feature voxels, +inf elsewhere.
LEVELFORGE_AI void maskRowFill(const MaskRow& r)
{
    for (int g = r.g0; g < r.g1; ++g) {
        const int w = groupWidth(g, r.nx);
        float* c = r.row + size_t(g) * kGroup * 4;
        const uint8_t* mg = r.mask + size_t(g) * kGroup;
        if (w == kGroup) {
            v8b m8;
            std::memcpy(&m8, mg, sizeof(m8));
            const v8f v = __builtin_convertvector(m8, v8i) != 0 ? v8f{} : v8f{} + kInf;
            for (int a = 0; a < 4; ++a) store8(c + a * kGroup, v);
        } else {
            for (int a = 0; a < 4; ++a)
                for (int i = 0; i < w; ++i) c[a * w + i] = mg[i] ? 0.0f : kInf;
        }
    }
}

/// The row's final vectors as 16-bit integers (+inf as -32768).
LEVELFORGE_AI void maskRowStore(const MaskRow& r)
{
    for (int g = r.g0; g < r.g1; ++g) {
        const int w = groupWidth(g, r.nx);
        const float* c = r.row + size_t(g) * kGroup * 4;
        int16_t* pg = r.packed + size_t(g) * kGroup * 3;
        if (w == kGroup) {
            const v8i known = load8(c + 24) < kInf;
            for (int a = 0; a < 3; ++a) {
                const v8i xi = known ? __builtin_convertvector(known ? load8(c + 8 * a) : v8f{}, v8i) : -32768;
                const v8s xs = __builtin_convertvector(xi, v8s);
                std::memcpy(pg + a * kGroup, &xs, sizeof(xs));
            }
        } else {
            for (int i = 0; i < w; ++i)
                for (int a = 0; a < 3; ++a)
                    pg[a * w + i] = c[3 * w + i] < kInf ? int16_t(c[a * w + i]) : int16_t(-32768);
        }
    }
}

/// Loads the row's 16-bit vectors and recomputes d2 exactly as the passes compute it.
template<bool Unit>
LEVELFORGE_AI void maskRowLoad(const MaskRow& r, const Spacing& s)
{
    for (int g = r.g0; g < r.g1; ++g) {
        const int w = groupWidth(g, r.nx);
        float* c = r.row + size_t(g) * kGroup * 4;
        const int16_t* pg = r.packed + size_t(g) * kGroup * 3;
        if (w == kGroup) {
            v8f V[3];
            for (int a = 0; a < 3; ++a) {
                v8s xs;
                std::memcpy(&xs, pg + a * kGroup, sizeof(xs));
                const v8i xi = __builtin_convertvector(xs, v8i);
                V[a] = xi == -32768 ? v8f{} + kInf : __builtin_convertvector(xi, v8f);
                store8(c + a * kGroup, V[a]);
            }
            const v8f Xs = Unit ? V[0] : V[0] * s.sx, Ys = Unit ? V[1] : V[1] * s.sy, Zs = Unit ? V[2] : V[2] * s.sz;
            const v8f yz = Ys * Ys + Zs * Zs;
            store8(c + 24, Xs * Xs + yz);
        } else {
            for (int i = 0; i < w; ++i) {
                float v[3];
                for (int a = 0; a < 3; ++a) v[a] = pg[a * w + i] == -32768 ? kInf : float(pg[a * w + i]);
                for (int a = 0; a < 3; ++a) c[a * w + i] = v[a];
                c[3 * w + i] = vectorLengthSquared(v[0], v[1], v[2], openvdb::Vec3f(s.sx, s.sy, s.sz));
            }
        }
    }
}

/// sqrt(d2) of the row's final vectors into the output; returns how many are +inf.
LEVELFORGE_AI uint64_t maskRowFinish(const MaskRow& r)
{
    uint64_t unreached = 0;
    for (int g = r.g0; g < r.g1; ++g) {
        const int w = groupWidth(g, r.nx);
        const float* d2 = r.row + size_t(g) * kGroup * 4 + 3 * w;
        float* o = r.out + size_t(g) * kGroup;
#if defined(__SSE2__)
        if (w == kGroup) {
            const __m128 a = _mm_loadu_ps(d2), b = _mm_loadu_ps(d2 + 4), inf = _mm_set1_ps(kInf);
            _mm_storeu_ps(o, _mm_sqrt_ps(a));
            _mm_storeu_ps(o + 4, _mm_sqrt_ps(b));
            unreached += unsigned(__builtin_popcount(
                unsigned(_mm_movemask_ps(_mm_cmpeq_ps(a, inf)) | (_mm_movemask_ps(_mm_cmpeq_ps(b, inf)) << 4))));
            continue;
        }
#endif
        for (int i = 0; i < w; ++i) {
            o[i] = std::sqrt(d2[i]);
            unreached += d2[i] == kInf ? 1 : 0;
        }
    }
    return unreached;
}

/// op 0: fill, 1: store, 2: load, 3: finish (returns the unreached count).
uint64_t maskRowBase(int op, const MaskRow& r, const Spacing& s, bool unit)
{
    switch (op) {
    case 0: maskRowFill(r); return 0;
    case 1: maskRowStore(r); return 0;
    case 2: unit ? maskRowLoad<true>(r, s) : maskRowLoad<false>(r, s); return 0;
    default: return maskRowFinish(r);
    }
}

#ifdef LEVELFORGE_VDT_AVX
// The same conversions for AVX2 (8 lanes per instruction; no FMA, so d2 has the same bits).
__attribute__((target("avx2"))) uint64_t maskRowAvx2(int op, const MaskRow& r, const Spacing& s, bool unit)
{
    switch (op) {
    case 0: maskRowFill(r); return 0;
    case 1: maskRowStore(r); return 0;
    case 2: unit ? maskRowLoad<true>(r, s) : maskRowLoad<false>(r, s); return 0;
    default: return maskRowFinish(r);
    }
}
#endif
#pragma GCC diagnostic pop

/// An uninitialised buffer for an intermediate, cache-line aligned (so lanes' column ranges of a
/// row never share a line when rows are multiples of 64 bytes). From 4 MB on it is 2 MB-aligned
/// and advised for transparent huge pages where Linux offers them, so that its first touch
/// faults in 2 MB pages instead of 4 kB ones.
template<class T>
class PageBuffer
{
public:
    explicit PageBuffer(size_t n)
    {
        constexpr size_t kHuge = size_t(2) << 20;
        const size_t bytes = std::max<size_t>(1, n * sizeof(T));
        const size_t align = bytes >= 2 * kHuge ? kHuge : 64;
        const size_t rounded = (bytes + align - 1) / align * align;
        mData = static_cast<T*>(std::aligned_alloc(align, rounded));
        if (!mData) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (align == kHuge) madvise(mData, rounded, MADV_HUGEPAGE); // advice: failing changes only speed
#endif
    }
    ~PageBuffer() { std::free(mData); }
    PageBuffer(const PageBuffer&) = delete;
    PageBuffer& operator=(const PageBuffer&) = delete;
    T* get() const { return mData; }

private:
    T* mData = nullptr;
};

/// Storage policy of runFullGrid for distances from a binary mask (vectorDistanceTransform() on a
/// MaskVolume). The passes run on two slice buffers in the grouped layout, the slice and the
/// previous one in sweep order (work[z & 1]), so the eight passes over a slice stay in cache.
/// The forward sweep fills each row from the mask (Eq. 8) and stores the row's final vectors as
/// 16-bit integers: vectors to voxel-centre seeds have integer components, all below 32768 in
/// magnitude when no dimension exceeds 32767 (checked by the caller), +inf stored as -32768. The
/// backward sweep loads them back, recomputes d2 with the passes' own formula (the d2 the passes
/// stored, bit for bit) and writes sqrt(d2) of its final vectors. Memory traffic per voxel: 1 byte
/// in and 6 out in the forward sweep, 6 in and 4 out in the backward one, against 64 for the
/// in-place passes plus the 16-byte vector volume's initialisation and read-back.
struct MaskIo
{
    int nx, ny, nz;
    const uint8_t* mask;
    float* out;
    const Kernel& k; // spacing, unit flag and build
    size_t rowFloats, sliceFloats, rowShorts;
    PageBuffer<float> work;            // two slices, grouped layout (lane ranges on separate cache lines)
    PageBuffer<int16_t> packed;        // the forward sweep's vectors, grouped: x[8] y[8] z[8] per group
    uint64_t (*convert)(int, const MaskRow&, const Spacing&, bool);
    uint64_t unreached = 0;

    MaskIo(const MaskVolume& m, ScalarVolume& o, const Kernel& kernel)
        : nx(m.dims.x()), ny(m.dims.y()), nz(m.dims.z()), mask(m.data.data()), out(o.data.data()), k(kernel),
          rowFloats(size_t(nx) * 4),
          sliceFloats(size_t(nx) * 4 * size_t(ny)), rowShorts(size_t(nx) * 3), work(2 * sliceFloats),
          packed(rowShorts * size_t(ny) * size_t(nz))
    {
#ifdef LEVELFORGE_VDT_AVX
        convert = k.avx2 ? maskRowAvx2 : maskRowBase;
#else
        convert = maskRowBase;
#endif
    }

    struct alignas(64) Lane // one cache line each: lanes write their own only
    {
        int g0, g1;
        uint64_t unreached = 0;
    };
    Lane lane(int g0, int g1) const { return Lane{g0, g1, 0}; }
    float* slice(int z) { return work.get() + size_t(z & 1) * sliceFloats; }
    size_t rowIndex(int z, int y) const { return size_t(z) * size_t(ny) + size_t(y); }
    MaskRow maskRow(const Lane& l, int z, int y)
    {
        const size_t i = rowIndex(z, y);
        return MaskRow{slice(z) + size_t(y) * rowFloats, mask + i * size_t(nx), packed.get() + i * rowShorts,
                       out + i * size_t(nx), l.g0, l.g1, nx};
    }

    void prefetch(Lane& l, int sweep, int z, int y) const
    {
        const int x0 = l.g0 * kGroup, x1 = std::min(nx, l.g1 * kGroup);
        const char* b = sweep == 0 ? reinterpret_cast<const char*>(mask + rowIndex(z, y) * size_t(nx) + size_t(x0))
                                   : reinterpret_cast<const char*>(packed.get() + rowIndex(z, y) * rowShorts +
                                                                   size_t(x0) * 3);
        const size_t bytes = size_t(x1 - x0) * (sweep == 0 ? 1 : 6);
        for (size_t o = 0; o < bytes; o += 64) LEVELFORGE_PREFETCH(b + o);
    }
    void rowStart(Lane& l, int sweep, int z, int y) { convert(sweep == 0 ? 0 : 2, maskRow(l, z, y), k.s, k.unit); }
    void vertDone(Lane&, int, int, int) const {}
    void rowEnd(Lane& l, int sweep, int z, int y)
    {
        if (sweep == 0) convert(1, maskRow(l, z, y), k.s, k.unit);
        else l.unreached += convert(3, maskRow(l, z, y), k.s, k.unit);
    }
    void finish(Lane&, int) const {}
    void cleanup(Lane&) const {}
    void done(std::vector<Lane>& lanes)
    {
        for (const Lane& l : lanes) unreached += l.unreached;
    }
};

uint64_t countFinite(const std::vector<ClosestVector>& d)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, d.size(), 1 << 16), uint64_t(0),
        [&](const tbb::blocked_range<size_t>& r, uint64_t n) {
            for (size_t i = r.begin(); i != r.end(); ++i) n += d[i].d2 < kInf ? 1 : 0;
            return n;
        },
        [](uint64_t a, uint64_t b) { return a + b; });
}

} // namespace

const char* vectorTransformMethodName(VectorTransformMethod method)
{
    switch (method) {
    case VectorTransformMethod::EVDT: return "EVDT";
    case VectorTransformMethod::EVDTFullGrid: return "EVDTFullGrid";
    case VectorTransformMethod::VCVDT4: return "VCVDT4";
    case VectorTransformMethod::VCVDT8: return "VCVDT8";
    }
    return "unknown";
}

VectorVolume initVectorVolume(const MaskVolume& features)
{
    requireValidVolume(features, "initVectorVolume");
    VectorVolume v;
    v.dims = features.dims;
    v.spacing = features.spacing;
    v.origin = features.origin;
    v.data.resize(features.data.size());
    const ClosestVector zero{0.f, 0.f, 0.f, 0.f}, inf{kInf, kInf, kInf, kInf};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, v.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) v.data[i] = features.data[i] ? zero : inf;
    });
    return v;
}

void vectorDistanceTransform(VectorVolume& vectors, const VectorTransformOptions& options,
                             VectorTransformStats* stats)
{
    requireValidVolume(vectors, "vectorDistanceTransform");
    const auto t0 = std::chrono::steady_clock::now();
    const MethodDef& m = methodDef(options.method);
    const Spacing sp{float(vectors.spacing[0]), float(vectors.spacing[1]), float(vectors.spacing[2])};
    VectorTransformStats st;
    st.voxels = vectors.voxelCount();
    if (stats) st.seeds = countFinite(vectors.data);
    st.passesPerVoxel = m.sweeps[0].passCount + m.sweeps[1].passCount;
    if (options.interrupter) options.interrupter->start("vector distance transform");
    const Kernel kernel(sp);
    if (m.twoSlices) {
        const GroupedScope grouped(reinterpret_cast<float*>(vectors.data.data()), vectors.dims.x(),
                                   size_t(vectors.dims.y()) * size_t(vectors.dims.z()));
        runTwoSlices(vectors, m, kernel, options.interrupter);
        st.lanes = 1;
    } else {
        InPlaceIo io(vectors);
        runFullGrid(io, m, kernel, options.interrupter, options.threads, st.lanes);
    }
    if (options.interrupter) options.interrupter->end();
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (stats) {
        st.unreached = st.voxels - countFinite(vectors.data);
        *stats = st;
    }
}

ScalarVolume vectorDistanceTransform(const MaskVolume& features, const VectorTransformOptions& options,
                                     VectorTransformStats* stats)
{
    requireValidVolume(features, "vectorDistanceTransform");
    const MethodDef& m = methodDef(options.method);
    const int maxDim = std::max({features.dims.x(), features.dims.y(), features.dims.z()});
    const auto t0 = std::chrono::steady_clock::now();
    if (m.twoSlices || maxDim > 32767) {
        // Two-slice EVDT (its own two buffers), or vectors that might not fit 16 bits.
        VectorVolume v = initVectorVolume(features);
        vectorDistanceTransform(v, options, stats);
        ScalarVolume d = vectorLength(v);
        if (stats) stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return d;
    }
    const Spacing sp{float(features.spacing[0]), float(features.spacing[1]), float(features.spacing[2])};
    VectorTransformStats st;
    st.voxels = features.voxelCount();
    if (stats) {
        st.seeds = tbb::parallel_reduce(
            tbb::blocked_range<size_t>(0, features.data.size(), 1 << 16), uint64_t(0),
            [&](const tbb::blocked_range<size_t>& r, uint64_t n) {
                for (size_t i = r.begin(); i != r.end(); ++i) n += features.data[i] ? 1 : 0;
                return n;
            },
            [](uint64_t a, uint64_t b) { return a + b; });
    }
    st.passesPerVoxel = m.sweeps[0].passCount + m.sweeps[1].passCount;
    ScalarVolume out;
    out.dims = features.dims;
    out.spacing = features.spacing;
    out.origin = features.origin;
    out.data.resize(features.data.size());
    if (options.interrupter) options.interrupter->start("vector distance transform");
    const Kernel kernel(sp);
    MaskIo io(features, out, kernel);
    runFullGrid(io, m, kernel, options.interrupter, options.threads, st.lanes);
    if (options.interrupter) options.interrupter->end();
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    st.unreached = io.unreached;
    if (stats) *stats = st;
    return out;
}

namespace vector_transform_internal {

bool avx2KernelAvailable()
{
#ifdef LEVELFORGE_VDT_AVX
    return cpuHasAvx2();
#else
    return false;
#endif
}

void setAvx2KernelEnabled(bool enabled) { gAvx2KernelEnabled.store(enabled, std::memory_order_relaxed); }

} // namespace vector_transform_internal

ScalarVolume vectorLength(const VectorVolume& vectors)
{
    requireValidVolume(vectors, "vectorLength");
    ScalarVolume out;
    out.dims = vectors.dims;
    out.spacing = vectors.spacing;
    out.origin = vectors.origin;
    out.data.resize(vectors.data.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, out.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) out.data[i] = std::sqrt(vectors.data[i].d2);
    });
    return out;
}

} // namespace levelforge
