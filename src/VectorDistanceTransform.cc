// levelforge — dense vector distance transforms (Satherley & Jones VCVDT, Mullikin EVDT).
// See include/levelforge/VectorDistanceTransform.h for the method and the pass tables.
#include <levelforge/VectorDistanceTransform.h>

#include <levelforge/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>
#include <sstream>
#include <thread>
#include <vector>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define LEVELFORGE_CPU_RELAX() _mm_pause()
#else
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

    std::vector<std::thread> threads;
    threads.reserve(size_t(lanes - 1));
    for (int t = 1; t < lanes; ++t) threads.emplace_back(lane, t);
    lane(0);
    for (auto& th : threads) th.join();
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


/// One pass over x = x..xEnd (exclusive, step xs) of one row. `row` is updated in place;
/// `prevRow` is the previous row in pass order (already final for this pass) or null;
/// `vertRow` the same row of the previous slice in sweep order, or null. havePrev: the voxel
/// before x in this row (x - xs) is in the volume and already final for this pass.
/// Candidate order: vertical, previous row, previous voxel (the table order).
template<bool Vert, bool Row, bool Unit>
inline __attribute__((always_inline)) void passSpanT(ClosestVector* row, const ClosestVector* prevRow, const ClosestVector* vertRow, int x,
              const int xEnd, const int xs, const bool havePrev, const float oy, const float oz,
              const Spacing& s)
{
    // Unit spacing: x * 1.0f == x exactly, so skipping the multiplications changes no bit.
    const float sx = Unit ? 1.0f : s.sx, sy = Unit ? 1.0f : s.sy, sz = Unit ? 1.0f : s.sz;
    const float ox = float(-xs);
    // Chain carry: the previous voxel's vector and its Y*Y + Z*Z (unchanged by an x step).
    float px = kInf, py = kInf, pz = kInf, pyz = kInf;
    if (havePrev) {
        const ClosestVector& p = row[x - xs];
        px = p.x;
        py = p.y;
        pz = p.z;
        const float Y = py * sy, Z = pz * sz;
        pyz = Y * Y + Z * Z;
    }
    for (; x != xEnd; x += xs) {
        ClosestVector c = row[x];
        float yz;
        {
            const float Y = c.y * sy, Z = c.z * sz;
            yz = Y * Y + Z * Z;
        }
        if constexpr (Vert) {
            const ClosestVector n = vertRow[x];
            const float nz = n.z + oz;
            const float X = n.x * sx, Y = n.y * sy, Z = nz * sz;
            const float nyz = Y * Y + Z * Z;
            const float d2 = X * X + nyz;
            if (d2 < c.d2) {
                c = ClosestVector{n.x, n.y, nz, d2};
                yz = nyz;
            }
        }
        if constexpr (Row) {
            const ClosestVector n = prevRow[x];
            const float ny = n.y + oy;
            const float X = n.x * sx, Y = ny * sy, Z = n.z * sz;
            const float nyz = Y * Y + Z * Z;
            const float d2 = X * X + nyz;
            if (d2 < c.d2) {
                c = ClosestVector{n.x, ny, n.z, d2};
                yz = nyz;
            }
        }
        {
            const float cx = px + ox;
            const float X = cx * sx;
            const float d2 = X * X + pyz;
            if (d2 < c.d2) {
                c = ClosestVector{cx, py, pz, d2};
                yz = pyz;
            }
        }
        row[x] = c;
        px = c.x;
        py = c.y;
        pz = c.z;
        pyz = yz;
    }
}

template<bool Vert, bool Row>
void passSpanBase(ClosestVector* row, const ClosestVector* prevRow, const ClosestVector* vertRow, int x,
                  const int xEnd, const int xs, const bool havePrev, const float oy, const float oz,
                  const Spacing& s)
{
    if (s.sx == 1.0f && s.sy == 1.0f && s.sz == 1.0f)
        passSpanT<Vert, Row, true>(row, prevRow, vertRow, x, xEnd, xs, havePrev, oy, oz, s);
    else
        passSpanT<Vert, Row, false>(row, prevRow, vertRow, x, xEnd, xs, havePrev, oy, oz, s);
}

#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
#define LEVELFORGE_VDT_AVX 1
// The same kernel compiled for AVX2 (VEX three-operand encoding: no register copies; the
// arithmetic is the same scalar IEEE single precision, and FMA is NOT enabled, so no
// multiply-add is contracted: the results are bit-identical).
template<bool Vert, bool Row>
__attribute__((target("avx2"))) void passSpanAvx2(ClosestVector* row, const ClosestVector* prevRow,
                                                  const ClosestVector* vertRow, int x, const int xEnd, const int xs,
                                                  const bool havePrev, const float oy, const float oz, const Spacing& s)
{
    if (s.sx == 1.0f && s.sy == 1.0f && s.sz == 1.0f)
        passSpanT<Vert, Row, true>(row, prevRow, vertRow, x, xEnd, xs, havePrev, oy, oz, s);
    else
        passSpanT<Vert, Row, false>(row, prevRow, vertRow, x, xEnd, xs, havePrev, oy, oz, s);
}

bool cpuHasAvx2()
{
    static const bool has = __builtin_cpu_supports("avx2");
    return has;
}
#endif

std::atomic<bool> gAvx2KernelEnabled{true}; // testing hook (vector_transform_internal)

template<bool Vert, bool Row>
inline void passSpan(ClosestVector* row, const ClosestVector* prevRow, const ClosestVector* vertRow, int x,
                     const int xEnd, const int xs, const bool havePrev, const float oy, const float oz,
                     const Spacing& s)
{
#ifdef LEVELFORGE_VDT_AVX
    if (cpuHasAvx2() && gAvx2KernelEnabled.load(std::memory_order_relaxed))
        return passSpanAvx2<Vert, Row>(row, prevRow, vertRow, x, xEnd, xs, havePrev, oy, oz, s);
#endif
    passSpanBase<Vert, Row>(row, prevRow, vertRow, x, xEnd, xs, havePrev, oy, oz, s);
}

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

/// Runs pass `p` on row r (pass order) of a slice, pass-order x indices [cb, ce).
void runPassRow(const PassDef& p, ClosestVector* slice, const ClosestVector* vertSlice, int nx, int ny,
                int r, int cb, int ce, const Spacing& sp)
{
    const PassShape sh = shapeOf(p);
    const int y = p.yOrder > 0 ? r : ny - 1 - r;
    ClosestVector* row = slice + size_t(y) * size_t(nx);
    const ClosestVector* prevRow =
        (sh.row && r > 0) ? slice + size_t(y - p.yOrder) * size_t(nx) : nullptr;
    const ClosestVector* vertRow = (sh.vert && vertSlice) ? vertSlice + size_t(y) * size_t(nx) : nullptr;
    const int xs = p.xOrder;
    const int x0 = xs > 0 ? cb : nx - 1 - cb;
    const int x1 = xs > 0 ? ce : nx - 1 - ce;
    const bool havePrev = cb > 0;
    if (vertRow && prevRow) passSpan<true, true>(row, prevRow, vertRow, x0, x1, xs, havePrev, sh.oy, sh.oz, sp);
    else if (vertRow) passSpan<true, false>(row, prevRow, vertRow, x0, x1, xs, havePrev, sh.oy, sh.oz, sp);
    else if (prevRow) passSpan<false, true>(row, prevRow, vertRow, x0, x1, xs, havePrev, sh.oy, sh.oz, sp);
    else passSpan<false, false>(row, prevRow, vertRow, x0, x1, xs, havePrev, sh.oy, sh.oz, sp);
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

/// All passes of one slice (serial), for the two-slice EVDT.
void runSliceSerial(const SweepDef& sw, ClosestVector* slice, const ClosestVector* vertSlice, int nx, int ny,
                    const Spacing& sp)
{
    for (const PassGroup& g : groupsOf(sw)) {
        for (int r = 0; r < ny; ++r)
            for (int p = g.first; p < g.end; ++p) runPassRow(sw.passes[p], slice, vertSlice, nx, ny, r, 0, nx, sp);
    }
}

void checkInterrupt(openvdb::util::NullInterrupter* interrupter, int percent)
{
    if (interrupter && interrupter->wasInterrupted(percent)) {
        interrupter->end();
        throw InterruptedError("vector distance transform interrupted");
    }
}

void runTwoSlices(VectorVolume& v, const MethodDef& m, const Spacing& sp,
                  openvdb::util::NullInterrupter* interrupter)
{
    const int nx = v.dims.x(), ny = v.dims.y(), nz = v.dims.z();
    const size_t nxy = size_t(nx) * size_t(ny);
    std::vector<ClosestVector> result(v.data.size());
    std::vector<ClosestVector> prev(nxy), cur(nxy);
    for (int s = 0; s < 2; ++s) {
        const SweepDef& sw = m.sweeps[s];
        for (int i = 0; i < nz; ++i) {
            checkInterrupt(interrupter, int((100.0 * (s * nz + i)) / (2.0 * nz)));
            const int z = sw.zOrder > 0 ? i : nz - 1 - i;
            const ClosestVector* in = v.data.data() + size_t(z) * nxy;
            std::copy(in, in + nxy, cur.begin());
            runSliceSerial(sw, cur.data(), i > 0 ? prev.data() : nullptr, nx, ny, sp);
            ClosestVector* out = result.data() + size_t(z) * nxy;
            if (s == 0) {
                std::copy(cur.begin(), cur.end(), out);
            } else {
                for (size_t k = 0; k < nxy; ++k)
                    if (cur[k].d2 < out[k].d2) out[k] = cur[k];
            }
            std::swap(prev, cur);
        }
    }
    v.data.swap(result);
}

void runFullGrid(VectorVolume& v, const MethodDef& m, const Spacing& sp,
                 openvdb::util::NullInterrupter* interrupter, int threads, int& lanesUsed)
{
    const int nx = v.dims.x(), ny = v.dims.y(), nz = v.dims.z();
    const size_t nxy = size_t(nx) * size_t(ny);
    struct Stage
    {
        int sweep, z, first, end;
        bool sliceStart;
    };
    std::vector<Stage> stages;
    for (int s = 0; s < 2; ++s) {
        const SweepDef& sw = m.sweeps[s];
        const auto groups = groupsOf(sw);
        for (int i = 0; i < nz; ++i) {
            const int z = sw.zOrder > 0 ? i : nz - 1 - i;
            for (size_t g = 0; g < groups.size(); ++g)
                stages.push_back({s, z, groups[g].first, groups[g].end, g == 0});
        }
    }
    const bool perRow = hasPerRow(m);
    const int lanes = perRow ? 1 : laneCountFor(nx, ny, threads);
    const int chunks = perRow ? 1 : wavefrontChunks(nx, lanes);
    lanesUsed = lanes;
    ClosestVector* data = v.data.data();

    auto work = [&](int si, int r, int c) {
        const Stage& st = stages[size_t(si)];
        const SweepDef& sw = m.sweeps[st.sweep];
        ClosestVector* slice = data + size_t(st.z) * nxy;
        const int vz = st.z - sw.zOrder;
        const ClosestVector* vertSlice = (vz >= 0 && vz < nz) ? data + size_t(vz) * nxy : nullptr;
        const int cb = int((int64_t(c) * nx) / chunks), ce = int((int64_t(c + 1) * nx) / chunks);
        runPassRow(sw.passes[st.first], slice, vertSlice, nx, ny, r, cb, ce, sp);
        for (int p = st.first + 1; p < st.end; ++p) runPassRow(sw.passes[p], slice, vertSlice, nx, ny, r, 0, nx, sp);
    };
    const int total = int(stages.size());
    auto begin = [&](int si) {
        if (!interrupter || !stages[size_t(si)].sliceStart) return true;
        return !interrupter->wasInterrupted(int((100.0 * si) / total));
    };
    if (!runRowWavefront(total, ny, chunks, 0, lanes, work, begin)) {
        if (interrupter) interrupter->end();
        throw InterruptedError("vector distance transform interrupted");
    }
}

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
    if (m.twoSlices) {
        runTwoSlices(vectors, m, sp, options.interrupter);
        st.lanes = 1;
    } else {
        runFullGrid(vectors, m, sp, options.interrupter, options.threads, st.lanes);
    }
    if (options.interrupter) options.interrupter->end();
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (stats) {
        st.unreached = st.voxels - countFinite(vectors.data);
        *stats = st;
    }
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
