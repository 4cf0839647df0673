// SPDX-License-Identifier: Apache-2.0
// The vector distance transforms on a vector volume (Satherley & Jones VCVDT, Mullikin EVDT):
// the API, the in-place route of the full-grid methods (InPlaceIo) and the two-slice EVDT.
// See include/levelforge/volume/VectorDistanceTransform.h for the methods; the pass tables are
// in VectorDistanceTransformInternal.h, the row kernel in VcvdtKernels.cc, the column lanes in
// VcvdtFullGrid.h and the mask entry in VcvdtMaskEntry.cc.
#include "volume/DenseVolumeHelpers.h"

#include <levelforge/volume/VectorDistanceTransform.h>

#include "detail/Timer.h"
#include "volume/VcvdtFullGrid.h"
#include "volume/VcvdtKernels.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

namespace levelforge {

namespace {

using namespace vector_transform_internal;

// ---------------------------------------------------------------------------------------------
// The grouped working layout (VcvdtKernels.h) on the volume itself: rows are reordered IN PLACE
// into groups of 8 voxels, and the reorder is undone before vectorDistanceTransform() returns
// (also on interruption).

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
    VectorVolume v = volume_internal::like<ClosestVector>(features);
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
    const auto t0 = detail::Clock::now();
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
    st.seconds = detail::secondsSince(t0);
    if (stats) {
        st.unreached = st.voxels - countFinite(vectors.data);
        *stats = st;
    }
}

ScalarVolume vectorLength(const VectorVolume& vectors)
{
    requireValidVolume(vectors, "vectorLength");
    ScalarVolume out = volume_internal::like<float>(vectors);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, out.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) out.data[i] = std::sqrt(vectors.data[i].d2);
    });
    return out;
}

} // namespace levelforge
