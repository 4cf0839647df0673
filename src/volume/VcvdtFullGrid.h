// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the vector distance transforms: the full-grid methods (VCVDT4, VCVDT8,
///        EVDTFullGrid) as a template over a storage policy, run by column lanes. The in-place
///        route (VectorDistanceTransform.cc, InPlaceIo) and the mask entry (VcvdtMaskEntry.cc,
///        MaskIo) instantiate it.
#pragma once

#include "detail/Lanes.h"
#include "volume/VcvdtKernels.h"

#include <levelforge/core/Exceptions.h>

#include <openvdb/util/NullInterrupter.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <exception>
#include <memory>
#include <mutex>
#include <vector>

namespace levelforge::vector_transform_internal {

/// Fewest groups (of 8 columns) a lane gets; narrower volumes use fewer lanes.
constexpr int kMinGroupsPerLane = 4;
/// Rows a lane finishes between two publications of its progress.
constexpr int kPublishRows = 16;
/// Rows the first pass of a slice prefetches ahead.
constexpr int kPrefetchRows = 4;

/// The element-wise candidates of a pass: vertical (offset oz) and previous row (offset oy).
struct PassShape
{
    bool vert = false, row = false;
    float oy = 0, oz = 0;
};

/// The candidates a pass lists before its in-row neighbour.
inline PassShape shapeOf(const PassDef& p)
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

/// Geometry of one slice on the grouped layout.
struct SliceView
{
    float* slice;
    const float* vertSlice; // the previous slice in sweep order, or null
    int nx, ny;
};

/// The task of pass p, row r (in pass order), groups [g0, g1).
inline RowTask rowTask(const PassDef& p, const SliceView& v, int r, int g0, int g1)
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

/// The pass groups of a sweep, in order.
inline std::vector<PassGroup> groupsOf(const SweepDef& sw)
{
    std::vector<PassGroup> g;
    for (int p = 0; p < sw.passCount; ++p) {
        if (sw.passes[p].perRow) g.back().end = p + 1;
        else g.push_back({p, p + 1});
    }
    return g;
}

/// Whether a method has perRow passes (EVDT's F2/B2).
inline bool hasPerRow(const MethodDef& m)
{
    for (const auto& sw : m.sweeps)
        for (int p = 0; p < sw.passCount; ++p)
            if (sw.passes[p].perRow) return true;
    return false;
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
    int lanes = hasPerRow(m) ? 1 : detail::laneCountFor(nx, ny, threads);
    lanes = std::max(1, std::min(lanes, columnGroups / kMinGroupsPerLane));
    lanesUsed = lanes;

    // Carry slots: lane t's last vector of row r in stage si lives in slot si % kCarryRing. A lane
    // starting stage si first waits until its neighbours have finished stage si - kCarryRing, so
    // a slot is never overwritten before it was read.
    constexpr int kCarryRing = 8;
    std::vector<Carry> carries(lanes > 1 ? size_t(lanes) * kCarryRing * size_t(ny) : 0);
    std::unique_ptr<detail::LaneProgress[]> progress(new detail::LaneProgress[size_t(lanes)]);
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
                if (t > 0 && !detail::waitUntil(progress[t - 1].value, need, stop)) return;
                if (t + 1 < lanes && !detail::waitUntil(progress[t + 1].value, need, stop)) return;
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
                    if (upSeen < need && !detail::waitUntil(progress[up].value, need, stop, &upSeen)) return;
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

    try {
        detail::runLanes(lanes, lane, &stop);
    } catch (const detail::LaneStartError&) {
        // no lane ran: release every lane's buffers, then report
        for (auto& st : laneStates) io.cleanup(st);
        io.done(laneStates);
        throw;
    }
    io.done(laneStates);
    if (error) std::rethrow_exception(error);
    if (stop.load()) {
        if (interrupter) interrupter->end();
        throw InterruptedError("vector distance transform interrupted");
    }
}

} // namespace levelforge::vector_transform_internal
