// SPDX-License-Identifier: Apache-2.0
// Private to the main road (src/mesh/MeshToLevelSet*.cc): the per-thread scratch, the work
// poller, the conversion context, and the sign stage's entry points (MeshToLevelSetSign.cc).
#pragma once

#include "detail/Timer.h"
#include "mesh/LazyPseudoNormals.h"
#include "mesh/TriangleHierarchy.h"

#include <levelforge/core/TriangleDistance.h>
#include <levelforge/mesh/FastWindingNumber.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <tbb/enumerable_thread_specific.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace levelforge {


namespace meshtols_internal {

using openvdb::Coord;
using FloatLeaf = openvdb::FloatTree::LeafNodeType;
using Vec3fLeaf = openvdb::Vec3fTree::LeafNodeType;
using Int32Leaf = openvdb::Int32Tree::LeafNodeType;
using detail::Clock;
using detail::secondsSince;
using namespace mesh_internal;

constexpr uint32_t kNone = kNoTriangle;
constexpr size_t kMaxFlat = 4096;   // clusters a leaf lists flat, at most
constexpr size_t kMaxFrontier = 32; // subtrees a leaf's voxels start their search from, when more
constexpr size_t kMaxLeafTriangles = 128; // triangles near a leaf that flatLeafDistances() takes, at most

/// A triangle near a leaf, in single precision relative to the leaf's first voxel centre, for
/// flatLeafDistances(): its plane (unit normal, offset), corners, edges e[k] = a[k+1] − a[k],
/// edge-line normals m[k] = e[k] × n, 1/|e[k]|² (0 for a zero-length edge), and the voxel rows
/// (x0..x1, y0..y1) within the band's reach of its box.
struct LeafTriangle
{
    float n[3], off;
    float a[3][3], e[3][3], m[3][3], inv[3];
    uint32_t id;
    int x0, x1, y0, y1;
};

/// Per-thread scratch reused for every leaf: no per-voxel allocation.
struct Scratch
{
    std::vector<uint32_t> front, next;             // the leaf's frontier of hierarchy nodes
    std::vector<std::pair<double, uint32_t>> order; // frontier sorted by distance to the leaf centre
    bool flat = false;                              // the frontier is clusters only
    // flatLeafDistances(): the leaf's triangles, their bounds per voxel (512 floats each), the
    // smallest bound per voxel, and each voxel's closest triangle and point
    std::vector<uint32_t> leafIds;
    std::vector<LeafTriangle> leafTris;
    std::vector<float> leafLb;
    std::vector<uint8_t> leafRows; // per triangle and row of 8 voxels: the voxels to evaluate exactly
    // pseudonormals asked for lately (direct-mapped by triangle and feature): neighbouring voxels
    // mostly share their closest feature, and a vertex normal costs an acos per incident triangle
    struct CachedNormal
    {
        uint64_t key = ~uint64_t(0);
        Vec3d n;
    };
    static constexpr int kNormalCacheBits = 9;
    CachedNormal normalCache[1u << kNormalCacheBits];
    float leafMin[512], leafThr[512];
    double leafBest2[512];
    uint32_t leafTri[512];
    TriangleClosestPoint leafCp[512];
    std::vector<uint32_t> near;                     // per voxel: the frontier entries within reach
    std::vector<float> fd2;                         // per voxel: their squared distances
    // The frontier's boxes and an 8-ary tree over them: level 0 holds the entries' boxes, level
    // k + 1 the union of 8 consecutive boxes of level k, up to a level of at most 8 boxes. Each
    // level is 6 SoA arrays of `stride` floats (a multiple of 8, padded with far boxes),
    // relative to the leaf centre.
    struct Level
    {
        std::vector<float> box;
        size_t count = 0, stride = 0;
    };
    std::vector<Level> levels;
    size_t nLevels = 0;
    std::vector<std::pair<uint32_t, double>> stack; // traversal stack: node, its box distance²
    uint64_t evaluations = 0, boundTests = 0, nodeTests = 0, candidateVoxels = 0, activeVoxels = 0, leafPasses = 0;
    // A 2×2×2 block's triangles, as its centre's search lists them (SoA, padded to a multiple of
    // 8 with far entries): per triangle the terms of two lower bounds of its distance to a voxel
    // of the block (the separating plane's distance at the centre less its rounding allowance,
    // and the centre's distance less √3/2), the plane's unit normal, the triangle index; then a
    // voxel's bounds and the triangles they leave to evaluate, nearest bound first.
    std::vector<float> btPlane, btBall, btX, btY, btZ, btLb;
    std::vector<uint32_t> btId, btCluster; // the triangle, the cluster that listed it
    size_t btCount = 0; // entries in use
    uint32_t btLanes = 0; // triangles a block found but did not list (clusters only)
    bool btClustersOnly = false; // the block lists clusters only
    // where triangles are split into pieces (several clusters hold them): per triangle, the
    // block that listed it last (a block lists a triangle once)
    std::vector<uint32_t> btSeen;
    // The same block's clusters (key: their smallest bound at the centre) and their boxes (6 SoA
    // arrays of blockStride floats relative to the centre), for blocks listing too many triangles
    std::vector<std::pair<float, uint32_t>> blockList;
    std::vector<float> blockBox, blockD2;
    size_t blockStride = 0;
    uint32_t btBlock = 0;
    void growBlockTriangles(size_t n)
    {
        n = std::max(n, 2 * btId.size());
        for (auto* a : {&btPlane, &btBall, &btX, &btY, &btZ, &btLb}) a->resize(n);
        btId.resize(n);
        btCluster.resize(n);
    }
    std::vector<std::pair<float, uint32_t>> btCand;
    struct WorkPoller* poller = nullptr; // polls the interrupter by work done (null: none)
    uint64_t reported = 0;               // evaluations already handed to the poller
    // Winding / unsigned: the leaf's voxels before their sign is known (distance in voxels, -1
    // where nothing is within reach; closest-point offset and triangle), the groups of voxels
    // with no surface between them, and the signs.
    double vd[512];
    openvdb::Vec3f vcp[512];
    int32_t vtri[512];
    uint8_t inside[512];
    int32_t hopsRep[512];
    uint8_t inGroup[512] = {};
    std::vector<uint32_t> group2, groupStart, groupRep, groupVoxels, tris, undecided;
    std::vector<Vec3d> points;
    std::vector<double> values;
    // the local exact tier: the triangles near the leaf, the boundary of their union (a, b,
    // signed current), the half-edges it is made from
    std::vector<uint32_t> nearTris, rest;
    struct NearEdge { Vec3d a, b; double current; };
    std::vector<NearEdge> nearEdges;
    std::vector<std::pair<std::array<double, 6>, int>> halfEdges;
    uint64_t windingEvaluations = 0, windingGroups = 0, windingIndividual = 0;
};

/// The pseudonormal of feature f of triangle t, through the scratch's cache: the same vector
/// bit for bit as LazyPseudoNormals::normal(). Keyed by what the normal depends on — the vertex
/// for a vertex, the two end points for an edge, the triangle for a face — so that the triangles
/// of a fan share one entry (a voxel beyond a convex vertex may find any of them closest).
inline const Vec3d& cachedNormal(const LazyPseudoNormals& normals, Scratch& s, const TriangleMesh& mesh, uint32_t t,
                                 TriangleFeature f)
{
    const Vec3I& tri = mesh.triangles[t];
    uint64_t key;
    switch (f) {
    case TriangleFeature::Vertex0: key = (uint64_t(uint32_t(tri[0])) << 2) | 1u; break;
    case TriangleFeature::Vertex1: key = (uint64_t(uint32_t(tri[1])) << 2) | 1u; break;
    case TriangleFeature::Vertex2: key = (uint64_t(uint32_t(tri[2])) << 2) | 1u; break;
    case TriangleFeature::Edge01:
    case TriangleFeature::Edge12:
    case TriangleFeature::Edge20: {
        if (normals.isDegenerate(t)) { // its edges have no normal (zero): keyed by the triangle
            key = (uint64_t(t) << 2) | 3u;
            break;
        }
        const int k = f == TriangleFeature::Edge01 ? 0 : (f == TriangleFeature::Edge12 ? 1 : 2);
        const uint64_t a = uint32_t(tri[k]), b = uint32_t(tri[(k + 1) % 3]);
        // both end points in 62 bits: exact for meshes of up to 2^31 points
        key = (((std::min(a, b) << 31) | std::max(a, b)) << 2) | 2u;
        break;
    }
    default: key = uint64_t(t) << 2; break;
    }
    Scratch::CachedNormal& e = s.normalCache[(key * 0x9E3779B97F4A7C15ull) >> (64 - Scratch::kNormalCacheBits)];
    if (e.key != key) {
        e.key = key;
        e.n = normals.normal(t, f);
    }
    return e.n;
}

/// Polls the interrupter by work done, not by time: once for every kEvaluationsPerPoll exact
/// evaluations of all threads together (well under a millisecond of work each), also from
/// inside a leaf, so that no leaf, however many triangles it sees, runs long unpolled. Threads
/// hand over their counts in steps of kReportStep (one atomic add per step).
struct WorkPoller
{
    static constexpr uint64_t kEvaluationsPerPoll = 8192;
    static constexpr uint64_t kReportStep = 1024;
    openvdb::util::NullInterrupter* interrupter = nullptr;
    size_t leaves = 1;
    std::atomic<size_t> done{0};    // leaves finished
    std::atomic<uint64_t> work{0};  // evaluations reported
    std::atomic<uint64_t> polls{0}; // polls made
    std::atomic<bool> stop{false};

    int percent() const { return 20 + int(75.0 * double(done.load(std::memory_order_relaxed)) / double(leaves)); }
    void poll()
    {
        if (interrupter->wasInterrupted(percent())) stop.store(true, std::memory_order_relaxed);
    }
    /// Reports the scratch's new evaluations and makes the polls they are owed.
    void report(Scratch& s)
    {
        const uint64_t delta = s.evaluations - s.reported;
        if (delta == 0) return;
        s.reported = s.evaluations;
        const uint64_t owed = (work.fetch_add(delta, std::memory_order_relaxed) + delta) / kEvaluationsPerPoll;
        uint64_t p = polls.load(std::memory_order_relaxed);
        while (p < owed)
            if (polls.compare_exchange_weak(p, p + 1, std::memory_order_relaxed)) { poll(); ++p; }
    }
    bool stopped() const { return stop.load(std::memory_order_relaxed); }
};

struct Context
{
    const TriangleMesh& mesh;
    const std::vector<Vec3d>& cellPts; // mesh points in cell space
    const TriangleHierarchy& hierarchy;
    const LazyPseudoNormals& normals;
    double voxelSize;
    double extW, intW, limit, limit2;
    double margin; // cells: covers the single-precision rounding of the cluster bounds
    float background;
    SignMode sign = SignMode::Pseudonormal; // never Auto here
    const FastWindingNumber* fwn = nullptr; // Winding
    bool deferWinding = false; // Winding without boundary current: signs after all leaves
};


/// Winding signs of a mesh without boundary current, deferred until every leaf is known: the
/// leaf's groups of voxels (no surface between them) and a lower bound of each voxel's distance
/// (voxels; −1 where nothing was within reach), for joining groups across the leaf's faces.
struct DeferredWinding
{
    uint16_t group[512];
    float lower[512];
    uint8_t band[512]; // bit 0: d < exterior width, bit 1: d < interior width (from the double d)
    uint16_t groups = 0;
};

struct LeafResult
{
    std::unique_ptr<FloatLeaf> sdf;
    std::unique_ptr<Vec3fLeaf> cp;
    std::unique_ptr<Int32Leaf> tri;
    std::unique_ptr<DeferredWinding> deferred; // winding, w piecewise constant: signs still to come
};

/// Winding: voxels closer than this to the surface (voxels) lie on it to rounding: value +0, no
/// sign, no estimate.
constexpr double kOnSurface = 1e-9;

/// Fills the output leaf of `res` with the winding (or unsigned) values of the distances in `s`
/// (see MeshToLevelSetSign.cc); an empty result when no voxel had a triangle within reach.
LeafResult finishLeaf(const Context& ctx, Scratch& s, LeafResult& res, bool wantClosest);

/// The leaf's closest triangles when few triangles come near it (Scratch::flat, at most
/// kMaxLeafTriangles within reach): single-precision distances of all 512 voxels to each of them
/// in one vectorised pass, then exact evaluation of those within twice the margin of the
/// smallest, ties to the smaller index, so the same triangle, point and distance as the search
/// per voxel of computeLeaf(). tri[v] = kNone where no triangle is within the band limit.
/// Returns false (nothing written) when the leaf is not such a leaf.
bool flatLeafDistances(const Context& ctx, const Coord& origin, Scratch& s, uint32_t* tri, TriangleClosestPoint* cps);

/// The builds of flatLeafDistances()' vector passes, narrowest first.
enum class FlatLeafIsa { Baseline = 0, Avx2 = 1 };

/// Test hooks (tests/mesh/TestFlatLeafDistances.cc): the most triangles flatLeafDistances() takes
/// (kMaxLeafTriangles by default, 0 turns it off) and the widest build of its vector passes it
/// may use (Avx2 by default: the widest the CPU has); which build it then uses. Not for use
/// while a conversion runs.
void setFlatLeafOptionsForTesting(size_t maxTriangles, FlatLeafIsa widest);
FlatLeafIsa flatLeafIsaForTesting();

/// computeLeaf()'s per-voxel tail from each voxel's closest triangle (kNone: none within the
/// limit): the sign, the band test, the output leaves. With `cps` the closest points are given;
/// without, they are evaluated again (MeshToLevelSetDevice.cc).
LeafResult finishFromClosest(const Context& ctx, const Coord& origin, Scratch& s, bool wantClosest, const uint32_t* tri,
                             const TriangleClosestPoint* cps);

/// The deferred winding signs of every leaf (Winding without boundary current).
void resolveDeferred(const Context& ctx, const std::vector<Coord>& origins, std::vector<LeafResult>& leaves,
                     bool wantClosest, uint64_t& evaluations, uint64_t& activeVoxels);

/// Whether the distance stage runs on a Vulkan device (MeshToLevelSetOptions::device); for
/// Auto, why not in `note` (MeshToLevelSetDevice.cc).
bool useDevice(const MeshToLevelSetOptions& options, size_t candidateLeaves, std::string& note);

/// The distance stage on the Vulkan device: fills `out` (one entry per candidate leaf) exactly as
/// computeLeaf() would. Throws DeviceError, InterruptedError.
void deviceDistances(const Context& ctx, const MeshToLevelSetOptions& options, const std::vector<Coord>& cand,
                     std::vector<LeafResult>& out, bool wantClosest, tbb::enumerable_thread_specific<Scratch>& scratch,
                     MeshToLevelSetStats& stats);

/// The sign mode a conversion uses, and why (Auto: validateMesh()'s verdict).
SignMode resolveSignMode(const TriangleMesh& mesh, const MeshToLevelSetOptions& options, std::string& reason);

} // namespace meshtols_internal
} // namespace levelforge
