// SPDX-License-Identifier: Apache-2.0
// The mask entry of the vector distance transforms: vectorDistanceTransform(const MaskVolume&)
// runs the full-grid methods on two slice buffers fed from the mask, keeps a 16-bit integer
// vector per voxel between the sweeps and writes the distances (see VectorDistanceTransform.h).
#include "volume/DenseVolumeHelpers.h"

#include <levelforge/volume/VectorDistanceTransform.h>

#include "detail/PageBuffer.h"
#include "detail/Timer.h"
#include "volume/VcvdtFullGrid.h"
#include "volume/VcvdtKernels.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace levelforge {

namespace {

using namespace vector_transform_internal;
using detail::PageBuffer;

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

} // namespace

ScalarVolume vectorDistanceTransform(const MaskVolume& features, const VectorTransformOptions& options,
                                     VectorTransformStats* stats)
{
    requireValidVolume(features, "vectorDistanceTransform");
    const MethodDef& m = methodDef(options.method);
    const int maxDim = std::max({features.dims.x(), features.dims.y(), features.dims.z()});
    const auto t0 = detail::Clock::now();
    if (m.twoSlices || maxDim > 32767) {
        // Two-slice EVDT (its own two buffers), or vectors that might not fit 16 bits.
        VectorVolume v = initVectorVolume(features);
        vectorDistanceTransform(v, options, stats);
        ScalarVolume d = vectorLength(v);
        if (stats) stats->seconds = detail::secondsSince(t0);
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
    ScalarVolume out = volume_internal::like<float>(features);
    if (options.interrupter) options.interrupter->start("vector distance transform");
    const Kernel kernel(sp);
    MaskIo io(features, out, kernel);
    runFullGrid(io, m, kernel, options.interrupter, options.threads, st.lanes);
    if (options.interrupter) options.interrupter->end();
    st.seconds = detail::secondsSince(t0);
    st.unreached = io.unreached;
    if (stats) *stats = st;
    return out;
}

} // namespace levelforge
