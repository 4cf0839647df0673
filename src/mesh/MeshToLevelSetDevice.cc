// SPDX-License-Identifier: Apache-2.0
// The main road's distance stage on a Vulkan device (MeshToLevelSetOptions::device): the CPU
// lists each band leaf's candidate triangles, the device finds every voxel's closest one in
// double precision (src/gpu/shaders/leaf_distance.comp), and the CPU finishes the leaf exactly
// as computeLeaf() does (closest point, sign, band test) from that one triangle. Two batches are
// in flight: while the device computes batch k, the CPU finishes batch k - 1 and lists k + 1.
#include "mesh/MeshToLevelSetInternal.h"
#include "gpu/VulkanLeafDistance.h"

#include <levelforge/core/TriangleDistance.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <cmath>
#include <mutex>
#include <sstream>

namespace levelforge::meshtols_internal {

namespace {

/// Every triangle of a hierarchy cluster whose box comes within the band limit (+ margin) of
/// the leaf's voxel-centre box, ascending. A superset of the triangles within the limit of
/// any of the leaf's voxels (a triangle's pieces lie in its clusters' boxes).
void leafCandidates(const Context& ctx, const Coord& origin, std::vector<uint32_t>& stack, std::vector<uint32_t>& out)
{
    out.clear();
    const auto& nodes = ctx.hierarchy.nodes();
    if (nodes.empty()) return;
    const Vec3d lo(origin.x() + 0.5, origin.y() + 0.5, origin.z() + 0.5), hi = lo + Vec3d(7.0);
    const double reach = ctx.limit + ctx.margin, reach2 = reach * reach;
    if (boxBoxDistanceSqr(nodes[0], lo, hi) >= reach2) return;
    stack.clear();
    stack.push_back(0);
    while (!stack.empty()) {
        const HierarchyNode& n = nodes[stack.back()];
        stack.pop_back();
        if (n.isLeaf()) {
            const TriangleCluster& c = ctx.hierarchy.clusters()[n.left];
            out.insert(out.end(), c.ids, c.ids + c.count);
            continue;
        }
        if (boxBoxDistanceSqr(nodes[n.right], lo, hi) < reach2) stack.push_back(n.right);
        if (boxBoxDistanceSqr(nodes[n.left], lo, hi) < reach2) stack.push_back(n.left);
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
}

/// The same from the device's signed squared distances (pseudonormal signs, no closest points):
/// d = sqrt(|d2|), inside where the sign bit is set; what computeLeaf() computes from the same
/// triangle, feature and normal, bit for bit.
LeafResult finishSignedFromDevice(const Context& ctx, const Coord& origin, Scratch& s, const uint32_t* tri, const double* sd2)
{
    std::unique_ptr<FloatLeaf> leaf;
    const float bg = ctx.background;
    uint64_t active = 0, found = 0;
    for (uint32_t v = 0; v < 512; ++v) {
        if (tri[v] == kNone) continue;
        ++found;
        if (!leaf) leaf.reset(new FloatLeaf(origin, bg, false));
        const bool inside = std::signbit(sd2[v]);
        const double d = std::sqrt(std::abs(sd2[v]));
        if (inside ? d < ctx.intW : d < ctx.extW) {
            leaf->setValueOn(v, float((inside ? -d : d) * ctx.voxelSize));
            ++active;
        } else {
            leaf->setValueOff(v, inside ? -bg : bg);
        }
    }
    s.candidateVoxels += found ? 512 : 0;
    s.evaluations += found;
    s.activeVoxels += active;
    LeafResult res;
    if (active) res.sdf = std::move(leaf);
    return res;
}

} // namespace

LeafResult finishFromClosest(const Context& ctx, const Coord& origin, Scratch& s, bool wantClosest, const uint32_t* tri,
                             const TriangleClosestPoint* cps)
{
    LeafResult res;
    res.sdf.reset(new FloatLeaf(origin, ctx.background, false));
    if (wantClosest) {
        res.cp.reset(new Vec3fLeaf(origin, openvdb::Vec3f(0.0f), false));
        res.tri.reset(new Int32Leaf(origin, -1, false));
    }
    const bool pseudo = ctx.sign == SignMode::Pseudonormal;
    if (!pseudo) std::fill(s.vd, s.vd + 512, -1.0);
    const float bg = ctx.background;
    uint64_t active = 0, found = 0;
    for (uint32_t v = 0; v < 512; ++v) {
        const uint32_t t = tri[v];
        if (t == kNone) continue;
        ++found;
        const Vec3d p(origin.x() + int(v >> 6) + 0.5, origin.y() + int((v >> 3) & 7u) + 0.5, origin.z() + int(v & 7u) + 0.5);
        const Vec3I& T = ctx.mesh.triangles[t];
        const TriangleClosestPoint cp =
            cps ? cps[v] : closestPointOnTriangle(p, ctx.cellPts[T[0]], ctx.cellPts[T[1]], ctx.cellPts[T[2]]);
        if (!cps) ++s.evaluations;
        const double d = std::sqrt(cp.distanceSqr);
        if (!pseudo) {
            s.vd[v] = d;
            if (wantClosest) {
                s.vcp[v] = openvdb::Vec3f(cp.point - p);
                s.vtri[v] = int32_t(t);
            }
            continue;
        }
        const bool inside = LazyPseudoNormals::insideOf(p, cp.point, cachedNormal(ctx.normals, s, ctx.mesh, t, cp.feature));
        if (inside ? d < ctx.intW : d < ctx.extW) {
            res.sdf->setValueOn(v, float((inside ? -d : d) * ctx.voxelSize));
            if (wantClosest) {
                res.cp->setValueOn(v, openvdb::Vec3f(cp.point - p));
                res.tri->setValueOn(v, int32_t(t));
            }
            ++active;
        } else {
            res.sdf->setValueOff(v, inside ? -bg : bg);
        }
    }
    s.candidateVoxels += found ? 512 : 0;
    if (found == 0) return LeafResult{};
    if (!pseudo) return finishLeaf(ctx, s, res, wantClosest);
    s.activeVoxels += active;
    if (active == 0) return LeafResult{};
    return res;
}


bool useDevice(const MeshToLevelSetOptions& o, size_t leaves, std::string& note)
{
    if (o.device == ComputeDevice::Cpu) return false;
    if (o.device == ComputeDevice::Vulkan) return true;
    if (leaves < o.deviceMinLeaves) return false; // small work: the CPU, no note
    std::string why;
    if (autoUsesVulkan(why)) return true;
    note = "device auto: " + why + "; the CPU was used";
    return false;
}

void deviceDistances(const Context& ctx, const MeshToLevelSetOptions& o, const std::vector<Coord>& cand,
                     std::vector<LeafResult>& out, bool wantClosest, tbb::enumerable_thread_specific<Scratch>& scratch,
                     MeshToLevelSetStats& stats)
{
    openvdb::util::NullInterrupter* interrupter = o.interrupter;
    const size_t nt = ctx.mesh.triangles.size(), nv = ctx.mesh.points.size();
    gpu_internal::LeafDeviceInput input;
    input.triangles = nt;
    input.vertices = nv;
    input.fillCorners = [&](double* corners) {
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 4096), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t t = r.begin(); t != r.end(); ++t)
                for (int k = 0; k < 3; ++k)
                    for (int j = 0; j < 3; ++j) corners[9 * t + 3 * size_t(k) + size_t(j)] = ctx.cellPts[ctx.mesh.triangles[t][k]][j];
        });
    };
    // pseudonormal signs on the device (the normals LazyPseudoNormals would compute, once each)
    const bool signsOnDevice = ctx.sign == SignMode::Pseudonormal && !wantClosest;
    if (signsOnDevice) {
        input.fillNormals = [&](double* triN, double* vertN, uint32_t* triV) {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, nv, 2048), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t v = r.begin(); v != r.end(); ++v) {
                    const Vec3d n = ctx.normals.vertexNormal(uint32_t(v));
                    for (int j = 0; j < 3; ++j) vertN[3 * v + size_t(j)] = n[j];
                }
            });
            tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 2048), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t t = r.begin(); t != r.end(); ++t) {
                    const Vec3d n[4] = {ctx.normals.faceNormal(uint32_t(t)), ctx.normals.edgeNormal(uint32_t(t), 0),
                                        ctx.normals.edgeNormal(uint32_t(t), 1), ctx.normals.edgeNormal(uint32_t(t), 2)};
                    for (int f = 0; f < 4; ++f)
                        for (int j = 0; j < 3; ++j) triN[12 * t + 3 * size_t(f) + size_t(j)] = n[f][j];
                    for (int k = 0; k < 3; ++k) triV[3 * t + size_t(k)] = uint32_t(ctx.mesh.triangles[t][k]);
                }
            });
        };
    }
    gpu_internal::LeafDistanceDevice dev(input);
    stats.device = "vulkan: " + dev.deviceName();
    const uint64_t budget = dev.slotBudget(o.deviceMemoryBudget);
    constexpr size_t kChunk = 4096;
    constexpr uint64_t kLeafBytes = 512 * (sizeof(uint32_t) + sizeof(double)) + 8 * sizeof(int32_t);
    std::vector<std::vector<uint32_t>> lists(kChunk);
    tbb::enumerable_thread_specific<std::vector<uint32_t>> stacks;
    size_t next = 0;
    size_t done = 0;
    auto stopAsked = [&]() { return interrupter && interrupter->wasInterrupted(20 + int(75.0 * double(done) / double(std::max<size_t>(cand.size(), 1)))); };

    // Lists leaves from `next` on into b until the slot budget is reached (at least one leaf).
    // Lists leaves from `next` on into b until the slot budget is reached (at least one leaf):
    // chunks of leaves listed in parallel, then appended with one parallel copy per chunk.
    auto prepare = [&](gpu_internal::LeafBatch& b) {
        b.clear();
        uint64_t bytes = 0;
        std::vector<size_t> at;
        while (next < cand.size()) {
            const size_t n = std::min(kChunk, cand.size() - next);
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 8), [&](const tbb::blocked_range<size_t>& r) {
                auto& st = stacks.local();
                for (size_t i = r.begin(); i != r.end(); ++i) leafCandidates(ctx, cand[next + i], st, lists[i]);
            });
            size_t taken = 0, total = b.cands.size();
            at.assign(n, 0);
            for (; taken < n; ++taken) {
                const std::vector<uint32_t>& l = lists[taken];
                if (l.empty()) continue; // nothing within reach: no output leaf
                const uint64_t need = kLeafBytes + 4 * l.size();
                if (b.count() > 0 && bytes + need > budget) break;
                const Coord& c = cand[next + taken];
                b.leaves.insert(b.leaves.end(), {c.x(), c.y(), c.z(), int32_t(total), int32_t(l.size()), 0, 0, 0});
                b.slots.push_back(next + taken);
                at[taken] = total;
                total += l.size();
                bytes += need;
            }
            b.cands.resize(total);
            tbb::parallel_for(tbb::blocked_range<size_t>(0, taken, 16), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i != r.end(); ++i)
                    if (!lists[i].empty()) std::copy(lists[i].begin(), lists[i].end(), b.cands.begin() + std::ptrdiff_t(at[i]));
            });
            next += taken;
            if (taken < n) break;
        }
    };
    auto finishBatch = [&](gpu_internal::LeafBatch& b, int slotIndex) {
        const uint32_t* tri = dev.triangles(slotIndex);
        const double* sd2 = dev.distances(slotIndex);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, b.count(), 4), [&](const tbb::blocked_range<size_t>& r) {
            Scratch& s = scratch.local();
            for (size_t j = r.begin(); j != r.end(); ++j) {
                const Coord origin(b.leaves[8 * j], b.leaves[8 * j + 1], b.leaves[8 * j + 2]);
                out[b.slots[j]] = signsOnDevice ? finishSignedFromDevice(ctx, origin, s, tri + 512 * j, sd2 + 512 * j)
                                                : finishFromClosest(ctx, origin, s, wantClosest, tri + 512 * j, nullptr);
            }
        });
        done = b.slots.empty() ? done : b.slots.back() + 1;
    };

    gpu_internal::LeafBatch batch[2];
    int slot = 0;
    bool inFlight[2] = {false, false};
    bool stopped = false;
    for (;;) {
        prepare(batch[slot]);
        const bool have = batch[slot].count() > 0;
        if (have) {
            dev.start(slot, batch[slot], ctx.limit2);
            inFlight[slot] = true;
        }
        const int prev = 1 - slot;
        if (inFlight[prev]) {
            inFlight[prev] = false;
            if (!dev.finish(prev, stopAsked)) { stopped = true; break; }
            finishBatch(batch[prev], prev);
        }
        if (!have) break;
        if (stopAsked()) { stopped = true; break; }
        slot = prev;
    }
    if (stopped) {
        for (int k = 0; k < 2; ++k)
            if (inFlight[k]) dev.finish(k, {});
        throw InterruptedError("interrupted while computing distances");
    }
    const gpu_internal::LeafDeviceStats& ds = dev.stats();
    stats.deviceBatches = ds.batches;
    stats.devicePairs = ds.pairs;
    stats.deviceBytesUp = ds.bytesUp;
    stats.deviceBytesDown = ds.bytesDown;
    stats.devicePeakBytes = ds.peakDeviceBytes;
    stats.secondsDeviceWait = ds.secondsWait;
    stats.secondsDeviceCopy = ds.secondsCopy;
}

} // namespace levelforge::meshtols_internal
