// SPDX-License-Identifier: Apache-2.0
// The ADF mesh builder (Yin, Liu, Wu 2011 on the VDB tile hierarchy; see AdaptiveDistanceField.h):
// the mesh in spatial order, voxelization and triangle lists (§4.1), the octree M' (§4.2), the
// samples through the value pipeline with the mesh provider, Frisken's refinement mode and the
// stated bounds.
#include "detail/ProgressCheck.h"
#include "adf/AdfInternal.h"
#include "adf/AdfMeshProvider.h"

#include "detail/Timer.h"
#include "detail/VoxelBudget.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/GridSpec.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/core/Progress.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/mesh/TriangleListTree.h>

#include <openvdb/tools/Morphology.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace levelforge {

using namespace adf_internal;

namespace {

/// 3 × 10 bits interleaved (x highest).
inline uint32_t mortonCode(uint32_t x, uint32_t y, uint32_t z)
{
    auto spread = [](uint32_t v) {
        v &= 0x3ff;
        v = (v | v << 16) & 0x030000ffu;
        v = (v | v << 8) & 0x0300f00fu;
        v = (v | v << 4) & 0x030c30c3u;
        v = (v | v << 2) & 0x09249249u;
        return v;
    };
    return spread(x) << 2 | spread(y) << 1 | spread(z);
}

/// The indices 0..n-1 ordered by key (stable), by a two-pass 16-bit radix sort.
std::vector<uint32_t> orderByKey(const std::vector<uint32_t>& key)
{
    const size_t n = key.size();
    std::vector<uint32_t> a(n), b(n);
    std::iota(a.begin(), a.end(), 0u);
    for (int shift = 0; shift < 32; shift += 16) {
        std::vector<uint32_t> count(65537, 0u);
        for (uint32_t i : a) ++count[((key[i] >> shift) & 0xffffu) + 1];
        for (size_t d = 1; d < count.size(); ++d) count[d] += count[d - 1];
        for (uint32_t i : a) b[count[(key[i] >> shift) & 0xffffu]++] = i;
        a.swap(b);
    }
    return a;
}

/// The mesh with its vertices and triangles in Morton order of their positions (blocks of 4
/// cells of size `cell`; beyond 1024 blocks per axis the order coarsens), each triangle's vertex
/// order kept: the voxelization and the per-leaf gathers then read nearby memory. Distances do
/// not depend on the order; which of several equally near triangles is reported, and so the
/// certified samples beyond the gather radius, may. `b`: the mesh's bounds (TriangleMesh::bounds).
TriangleMesh spatiallyOrdered(const TriangleMesh& mesh, const BBoxd& b, double cell)
{
    const double inv = 1.0 / (4.0 * cell);
    auto key = [&](const Vec3d& p) {
        uint32_t c[3];
        for (int k = 0; k < 3; ++k) {
            const double v = (p[k] - b.min()[k]) * inv; // unused vertices may lie anywhere, or be NaN
            c[k] = v >= 0.0 ? uint32_t(std::min(v, 1023.0)) : 0u;
        }
        return mortonCode(c[0], c[1], c[2]);
    };
    TriangleMesh out;
    out.source = mesh.source;
    std::vector<uint32_t> vkey(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, vkey.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) vkey[i] = key(mesh.points[i]);
    });
    const std::vector<uint32_t> vorder = orderByKey(vkey);
    std::vector<uint32_t> newIndex(vorder.size());
    out.points.resize(vorder.size());
    for (size_t i = 0; i < vorder.size(); ++i) {
        newIndex[vorder[i]] = uint32_t(i);
        out.points[i] = mesh.points[vorder[i]];
    }
    std::vector<uint32_t> tkey(mesh.triangles.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tkey.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            tkey[t] = key((mesh.points[tri[0]] + mesh.points[tri[1]] + mesh.points[tri[2]]) / 3.0);
        }
    });
    const std::vector<uint32_t> torder = orderByKey(tkey);
    out.triangles.resize(torder.size());
    for (size_t t = 0; t < torder.size(); ++t) {
        const Vec3I& tri = mesh.triangles[torder[t]];
        out.triangles[t] = Vec3I(newIndex[tri[0]], newIndex[tri[1]], newIndex[tri[2]]);
    }
    return out;
}

} // namespace

AdaptiveDistanceField meshToAdaptiveDistanceField(const TriangleMesh& inputMesh, const AdaptiveDistanceFieldOptions& options,
                                                  AdaptiveDistanceFieldStats* statsOut)
{
    openvdb::initialize();
    AdaptiveDistanceFieldStats stats;
    auto* interrupter = options.interrupter;
    if (!std::isfinite(options.paddingVoxels) || options.paddingVoxels < 0)
        throw InvalidArgumentError("ADF padding must be a finite number of voxels >= 0");
    if (!std::isfinite(options.toleranceVoxels) || options.toleranceVoxels < 0)
        throw InvalidArgumentError("ADF tolerance must be a finite number of voxels >= 0 (0 = no refinement)");
    requireUsableMesh(inputMesh);
    const double h = resolveVoxelSize(inputMesh, options);
    stats.voxelSize = h;
    const BBoxd bounds = inputMesh.bounds();
    for (int k = 0; k < 3; ++k) {
        const double lo = bounds.min()[k] / h - 1024, hi = bounds.max()[k] / h + 1024;
        if (!(std::abs(lo) < 1.0e9 && std::abs(hi) < 1.0e9))
            throw ResourceLimitError("voxel size is too small for this mesh: index coordinates would exceed 1e9");
    }
    if (interrupter) interrupter->start("mesh to ADF");
    const TriangleMesh mesh = spatiallyOrdered(inputMesh, bounds, h);

    // ---- voxelization + triangle lists (cell space = index space: cell c = [c, c+1)³)
    const auto t0 = detail::Clock::now();
    std::vector<Vec3d> cellPts(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cellPts.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) cellPts[i] = mesh.points[i] / h;
    });
    // the non-degenerate triangles, by PseudoNormals' own test (a zero or non-finite normal
    // length), so that the pseudonormals can be built while the lists are
    std::vector<uint8_t> degenerate(mesh.triangles.size(), 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, degenerate.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            const Vec3d& a = mesh.points[tri[0]];
            const Vec3d& b = mesh.points[tri[1]];
            const Vec3d& c = mesh.points[tri[2]];
            const double len = (b - a).cross(c - a).length();
            degenerate[t] = !(len > 0.0) || !std::isfinite(len);
        }
    });
    std::vector<uint32_t> use;
    use.reserve(mesh.triangles.size());
    for (uint32_t t = 0; t < mesh.triangles.size(); ++t)
        if (!degenerate[t]) use.push_back(t);
    if (use.empty()) throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) + ": every triangle is degenerate");
    stats.triangles = use.size();
    // domain guard before the voxelization (the bounding box decides the domain)
    {
        uint64_t dense = 1;
        for (int k = 0; k < 3; ++k) {
            const double ext = (bounds.max()[k] - bounds.min()[k]) / h + 2.0 * std::max(9.0, options.paddingVoxels) + 256;
            dense = uint64_t(double(dense) * ext);
        }
        // the ADF refines only near the surface: half the dense box is the budget's estimate
        detail::checkVoxelBudget({"mesh to ADF", "the ADF domain",
                                  "half its dense box of " + std::to_string(dense) + " finest voxels",
                                  0.5 * double(dense), 0.0, options.maxVoxels, "use a larger voxel size"});
    }
    // pseudonormals (partly serial) concurrently with the voxelization
    std::unique_ptr<PseudoNormals> normalsPtr;
    tbb::task_group normalsTask;
    normalsTask.run([&] { normalsPtr.reset(new PseudoNormals(mesh)); });
    std::unique_ptr<TriangleListTree> listsPtr;
    try {
        listsPtr.reset(new TriangleListTree(TriangleListTree::build(cellPts, mesh.triangles, use, nullptr, interrupter)));
    } catch (...) {
        normalsTask.wait();
        throw;
    }
    normalsTask.wait();
    const PseudoNormals& normals = *normalsPtr;
    const TriangleListTree& lists = *listsPtr;
    for (uint32_t t : use)
        if (normals.isDegenerate(t)) throw Error("ADF: degeneracy test disagrees with the pseudonormals"); // never happens
    stats.boundaryCells = lists.cellCount();
    stats.secondsVoxelize = detail::secondsSince(t0);
    progress_internal::check(interrupter, 20);

    // ---- octree: M' = M dilated by one cell; leaves, internal-1 nodes, tiles
    const auto t1 = detail::Clock::now();
    Layout base;
    {
        openvdb::MaskTree mp(lists.tree(), false, openvdb::TopologyCopy());
        openvdb::tools::dilateActiveValues(mp, 1, openvdb::tools::NN_FACE_EDGE_VERTEX, openvdb::tools::IGNORE_TILES);
        for (auto it = mp.cbeginLeaf(); it; ++it) {
            base.leafOrigins.push_back(it->origin());
            base.leafMasks.push_back(it->getValueMask());
        }
        CoordBBox mbox;
        lists.tree().evalActiveVoxelBoundingBox(mbox);
        makeDomain(base, mbox, options.paddingVoxels);
    }
    const Coord dim = base.domain.dim();
    const double domainVoxels = double(dim.x() - 1) * double(dim.y() - 1) * double(dim.z() - 1);
    if (options.maxVoxels && domainVoxels > double(options.maxVoxels)) {
        std::ostringstream os;
        os << "the ADF domain spans " << uint64_t(domainVoxels) << " finest voxels, more than the limit of " << options.maxVoxels;
        throw ResourceLimitError(os.str());
    }
    stats.domainVoxels = uint64_t(domainVoxels);
    stats.secondsOctree = detail::secondsSince(t1);

    MeshProvider provider(mesh, cellPts, lists, normals, h);
    const float background = float(std::sqrt(3.0) * double(dim.x() + dim.y() + dim.z()) * h);
    std::vector<Coord> forcedLeaves, forcedL2;
    FloatTree::Ptr tree;
    Layout layout;
    PipelineResult pr;
    std::array<double, kAdfLevels> bound{{-1, -1, -1, -1, -1}};
    for (int iteration = 0;; ++iteration) {
        const auto t2 = detail::Clock::now();
        layout = base;
        LeafMask full;
        full.setOn();
        for (const Coord& o : forcedLeaves) { layout.leafOrigins.push_back(o); layout.leafMasks.push_back(full); }
        layout.subdividedL2 = forcedL2;
        layout.finish();
        tree = createTree(layout, background);
        stats.secondsOctree += detail::secondsSince(t2);
        for (auto& s : provider.mScratch) { s.type1 = s.type2 = s.type3 = s.type2Wide = 0; s.type2MaxBound = 0; }
        provider.setDomain(layout.domain);
        pr = fillValues(*tree, layout, provider, interrupter);
        progress_internal::check(interrupter, 80);
        if (options.toleranceVoxels <= 0 || iteration >= 8) break;
        std::vector<std::pair<int, Coord>> failing;
        const auto t3 = detail::Clock::now();
        checkBounds(*tree, layout, provider, false, 1, options.toleranceVoxels * h, &failing, interrupter);
        stats.secondsBounds += detail::secondsSince(t3);
        if (failing.empty()) break;
        for (const auto& f : failing) {
            if (f.first == 4) forcedL2.push_back(f.second);
            else forcedLeaves.push_back(f.second);
            ++stats.refinedTiles;
        }
    }
    for (const MeshScratch& s : provider.mScratch) {
        stats.type1 += s.type1;
        stats.type2 += s.type2;
        stats.type3 += s.type3;
        stats.type2Wide += s.type2Wide;
        stats.type2MaxBoundVoxels = std::max(stats.type2MaxBoundVoxels, s.type2MaxBound);
    }
    stats.hanging = pr.hanging;
    stats.leaves = layout.leafOrigins.size();
    stats.level1Tiles = pr.level1Tiles;
    stats.level2Tiles = pr.level2Tiles;
    // Table 1 split: the leaf pass computes type-1 and type-2 together; split by count.
    const double leafSec = pr.secondsLeaves;
    const double n12 = double(stats.type1 + stats.type2);
    stats.secondsType1 = n12 > 0 ? leafSec * double(stats.type1) / n12 : 0;
    stats.secondsType2 = leafSec - stats.secondsType1;
    stats.secondsType3 = pr.secondsTiles + provider.secondsSignFill;
    stats.secondsFinish = pr.secondsHanging;

    if (options.computeBounds) {
        const auto t4 = detail::Clock::now();
        const Bounds b =
            checkBounds(*tree, layout, provider, true, std::max(1, options.boundStride), 0.0, nullptr, interrupter);
        bound = b.cells;
        stats.levelTestPointVoxels = b.testPoints;
        stats.secondsBounds += detail::secondsSince(t4);
    }
    stats.levelBoundVoxels = bound;
    {
        // cells of sizes 1, 2, 4 inside the leaves, from their masks
        for (const LeafMask& m : layout.leafMasks) LeafCellSizes(m).count(stats.cells[0], stats.cells[1], stats.cells[2]);
        stats.cells[3] = pr.cells[3];
        stats.cells[4] = pr.cells[4];
    }

    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
    grid->setName(options.gridName);
    stampAdfMetadata(*grid, layout.domain, bound);
    grid->insertMeta(meta::kSource, openvdb::StringMetadata(mesh.source));
    grid->insertMeta(meta::kMethod, openvdb::StringMetadata("yin2011-adf"));
    stats.memoryBytes = tree->memUsage();
    if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return AdaptiveDistanceField(grid);
}

} // namespace levelforge
