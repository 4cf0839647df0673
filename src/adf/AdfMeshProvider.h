// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/adf/: the sample provider of the mesh builder (Yin, Liu, Wu 2011 §5.2,
///        §6, §7.2): type-1/2 samples from the triangle lists gathered per leaf, type-3 samples
///        from the nearest boundary-cell centre, signs, and the bound check of the finished
///        reconstruction (Frisken's test points).
///
/// The member functions live next to what they do: the nearest-triangle search of a leaf
/// region in AdfLeafSearch.h (inlined into its callers), the per-leaf sample pass and its AVX2
/// build in AdfLeafPass.cc, the tile samples and signs in AdfMeshProvider.cc, the bound check
/// in AdfBounds.cc.
#pragma once

#include "adf/AdfCentreBvh.h"
#include "adf/AdfInternal.h"
#include "adf/AdfLatticeEdt.h"

#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/mesh/TriangleListTree.h>

#include <openvdb/openvdb.h>
#include <openvdb/tree/ValueAccessor.h>
#include <openvdb/util/NullInterrupter.h>

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

namespace levelforge {
namespace adf_internal {

/// A gathered triangle: cell-space vertices (double) and its mesh id.
struct PreparedTri { Vec3d a, b, c; uint32_t id; };
/// Its bounding box (the first, exact filter of the nearest search), computed once per gathered
/// triangle and copied into the RefQuads of the cells that list it. In float relative to the
/// leaf centre (w = 0), tested with a kPlaneSlack slack per axis.
struct alignas(16) TriBox { float lo[4], hi[4]; };
/// Lower-bound planes of a gathered triangle, relative to the leaf centre: the unit normal and
/// the three in-plane outward edge normals (n, -n·a; m_k, -m_k·v_k). For a point p,
/// dist² >= plane(p)² + max(0, edge_k(p))², exact in the face and edge regions (all zero, i.e.
/// no bound, for slivers whose normal is not accurate).
/// Stored in float, transposed (x, y, z, w of the plane and the three edge lines) so that one
/// SSE step evaluates all four. `err` bounds the float rounding of the four values for points
/// within 32 cells of the leaf centre: 1e-5 + 2e-7 × the largest |w| (coefficients and the sum
/// round at 6e-8 of their magnitude); the bound is taken as max(0, |plane| - err) and
/// max(0, edge - err).
struct alignas(16) TriPlanes { float x[4], y[4], z[4], w[4]; float err = 0.0f; };
/// Four references of a cell's triangle list with their boxes (as TriBox), transposed so that
/// one SSE step tests four: lanes beyond the list hold an empty box (lo = +1e30, never passes).
struct alignas(16) RefQuad { float lx[4], ly[4], lz[4], hx[4], hy[4], hz[4]; uint32_t t[4]; };
inline constexpr RefQuad kPadQuad{{1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f},
                           {1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f}, {1e30f, 1e30f, 1e30f, 1e30f},
                           {0u, 0u, 0u, 0u}};
/// Float rounding of the query point and of the box subtraction for boxes near the centre.
inline constexpr double kPlaneSlack = 1e-4; // cells

/// Cells p + o, o in [-R, R-1+extra]³, sorted by their minimum squared distance from p
/// (a lattice point, extra = 0) or from any point of the unit cell [p, p+1) (extra = 1).
struct OffsetTable
{
    std::vector<Coord> off;
    std::vector<int> d2;
    std::vector<double> d2d;    ///< d2 as double
    std::vector<int32_t> delta; ///< linear index offset in the gathered region
    OffsetTable(int R, int extra, int region)
    {
        auto a = [&](int o) { return extra ? (o >= 1 ? o - 1 : (o <= -1 ? -o - 1 : 0)) : (o >= 0 ? o : -o - 1); };
        std::vector<std::pair<int, Coord>> v;
        for (int x = -R; x <= R - 1 + extra; ++x)
            for (int y = -R; y <= R - 1 + extra; ++y)
                for (int z = -R; z <= R - 1 + extra; ++z) v.push_back({a(x) * a(x) + a(y) * a(y) + a(z) * a(z), Coord(x, y, z)});
        std::stable_sort(v.begin(), v.end(), [](const auto& l, const auto& r) { return l.first < r.first; });
        for (auto& e : v) {
            d2.push_back(e.first);
            d2d.push_back(double(e.first));
            off.push_back(e.second);
            delta.push_back((e.second.x() * region + e.second.y()) * region + e.second.z());
        }
    }
};

inline constexpr int kGather = 4;             // the leaf's region: [o-4, o+12)³
inline constexpr int kRegion = 8 + 2 * kGather;

/// Per-thread scratch of the mesh provider: the gathered lists of one leaf region.
struct MeshScratch
{
    std::vector<int32_t> cellSlot;       // region cell -> range index or -1
    std::vector<uint32_t> rangeBegin;    // per marked cell: [begin, end) into quads
    std::vector<RefQuad> quads;          // the cells' lists (local triangle ids and boxes), 4 per quad
    std::vector<PreparedTri> tris;
    std::vector<TriBox> boxes;
    std::vector<TriPlanes> planes;       // computed on first use (planeReady)
    std::vector<uint8_t> planeReady;
    std::vector<uint32_t> stamp;
    std::vector<uint32_t> hashKey;       // gather: triangle id + 1 (0 = empty)
    std::vector<uint32_t> hashLocal;     // gather: its local id
    std::vector<std::pair<int, uint32_t>> cells; // gather: (region index, ordinal)
    uint32_t stampValue = 0, lastTri = kNone;
    Vec3d centre{0.0};                   // leaf centre (the planes' origin)
    double margin = 0;                   // rounding margin of the plane bounds (cells)
    Vec3d hint{1e300};
    uint64_t type1 = 0, type2 = 0, type3 = 0, type2Wide = 0;
    double type2MaxBound = 0;
};

struct Nearest { double d2 = std::numeric_limits<double>::infinity(); uint32_t tri = kNone; TriangleClosestPoint cp{}; };

// The leaf pass is compiled twice, for the baseline and for AVX2 (chosen at run time); its
// helpers are inlined into both.
#if defined(__GNUC__) && (defined(__x86_64__) || defined(_M_X64))
#define LF_ADF_AVX2 1
#define LF_HOT inline __attribute__((always_inline))
#else
#define LF_HOT inline
#endif

class MeshProvider : public SampleProvider
{
public:
    MeshProvider(const TriangleMesh& mesh, const std::vector<Vec3d>& cellPts, const TriangleListTree& lists,
                 const PseudoNormals& normals, double h);
    ~MeshProvider() override;

    // --- the nearest-triangle search of a leaf region (AdfLeafSearch.h) --------------------
    /// Gathers the lists of the leaf region [o-4, o+12)³ (the cells the mReal table reaches
    /// from the leaf's cells); `latticeOnly` leaves out the last layer, which the mLattice table
    /// never reaches from the leaf's lattice points (their cells end at o+10).
    LF_HOT void gather(const Coord& o, MeshScratch& s, bool latticeOnly) const;
    /// The lower-bound planes of gathered triangle t (see TriPlanes).
    LF_HOT static void preparePlanes(MeshScratch& s, uint32_t t);
    /// (sqrt(d2) + margin)²: a triangle whose plane bound exceeds it cannot come closer than d2.
    LF_HOT static double boundLimit(double d2, double margin);
    /// Nearest gathered triangle to q (index space); `base` = the lattice point (local to the
    /// region's corner o-4) the offsets are relative to. Exact when the result is <= kGather.
    LF_HOT Nearest nearest(const Vec3d& q, const Coord& baseLocal, const OffsetTable& table, MeshScratch& s) const;

    /// Signed distance (world) from the gathered triangles, with its certificate (voxels): exact
    /// when the nearest gathered triangle is within kGather cells (every closer triangle would
    /// be listed in the region). Otherwise the true distance lies in [max(kGather, e - √3/2),
    /// min(d̃, e + √3/2)] with e the distance to the nearest boundary-cell centre (every
    /// surface point lies in a boundary cell, within √3/2 of its centre); the midpoint is
    /// returned. The sign is the pseudonormal's at the nearest gathered point: the segment to it
    /// stays in the (convex) region, so it crosses no triangle first.
    double certified(const Nearest& nb, const Vec3d& q, MeshScratch& s, double& cert) const
    {
        const double dt = std::sqrt(nb.d2);
        const double sgn = mNormals.isInside(s.tris[nb.tri].id, nb.cp, q) ? -1.0 : 1.0;
        if (dt <= double(kGather)) { cert = 0; return sgn * dt * mH; }
        ++s.type2Wide;
        const double e = std::sqrt(mBvh.nearest2(q, s.hint)), r3 = std::sqrt(3.0) / 2;
        const double lo = std::max(double(kGather), e - r3), hi = std::min(dt, e + r3);
        cert = std::max(0.0, 0.5 * (hi - lo));
        return sgn * 0.5 * (lo + hi) * mH;
    }

    /// Type-3 estimator (world, signed by the flood-filled type-1 band at lattice point `signAt`).
    double estimate(const Vec3d& q, const Coord& signAt, Vec3d& hint) const
    {
        const double d = std::sqrt(mBvh.nearest2(q, hint)) * mH;
        return insideAt(signAt) ? -d : d;
    }

    bool insideAt(const Coord& p) const
    {
        auto& acc = mT1Acc.local();
        if (!acc) acc.reset(new openvdb::tree::ValueAccessor<const FloatTree, false>(*mType1));
        return acc->getValue(p) < 0.0f;
    }

    // --- the per-leaf sample pass (AdfLeafPass.cc) ------------------------------------------
    void leafSamples(size_t, FloatLeaf& leaf, const uint8_t* isFree, float* out) override;
    void leafSamplesBase(FloatLeaf& leaf, const uint8_t* isFree, float* out);
#if defined(LF_ADF_AVX2)
    /// The same code compiled for AVX2 (VEX encoding; FMA is not enabled, so nothing is
    /// contracted and every value is bit-identical to the base build's).
    __attribute__((target("avx2"))) void leafSamplesAvx2(FloatLeaf& leaf, const uint8_t* isFree, float* out);
#endif
    LF_HOT void leafSamplesImpl(FloatLeaf& leaf, const uint8_t* isFree, float* out);

    // --- tile samples and signs (AdfMeshProvider.cc) ----------------------------------------
    /// The domain whose 8-spaced lattice the tile samples lie on (set before fillValues).
    void setDomain(const CoordBBox& domain);
    void afterLeaves(FloatTree& adfTree) override;
    void fixDeferred(FloatTree& adfTree);
    double tileSample(const Coord& p) override;

    // --- bounds (Frisken test points; AdfBounds.cc) -----------------------------------------
    /// Reference value of the sample function at a point of a leaf cell, world, with its own
    /// bound (world).
    double leafReference(const Vec3d& q, const Coord& o, MeshScratch& s, double& fBound) const;

    const TriangleMesh& mMesh;
    const std::vector<Vec3d>& mPts;
    const TriangleListTree& mLists;
    const PseudoNormals& mNormals;
    double mH;
    CentreBvh mBvh;
    OffsetTable mLattice, mReal;
    LatticeEdt mEdt;
    CoordBBox mEdtDomain;
    bool mEdtBuilt = false;
    tbb::enumerable_thread_specific<MeshScratch> mScratch;
    tbb::enumerable_thread_specific<std::vector<std::unique_ptr<FloatLeaf>>> mType1Leaves;
    tbb::enumerable_thread_specific<std::vector<float*>> mDeferredSign;
    std::shared_ptr<FloatTree> mType1;
    mutable tbb::enumerable_thread_specific<std::unique_ptr<openvdb::tree::ValueAccessor<const FloatTree, false>>> mT1Acc;
    double secondsSignFill = 0;
};

/// The per-level results of checkBounds(), voxels (-1: no cell of the level).
struct Bounds { std::array<double, kAdfLevels> testPoints, cells; };

/// Checks the reconstruction at the test points of every tile cell (levels 3, 4) and, if
/// `leafCells`, of the cells inside leaves (level 0: every unitStride-th finest cell). Returns per-level
/// (deviation + reference bound), in voxels; collects tile cells deviating more than tolWorld.
/// Polls `interrupter` (if set) after every 64 tile cells and every 4 leaves; throws
/// InterruptedError when it asks to stop.
Bounds checkBounds(const FloatTree& tree, const Layout& layout, MeshProvider& mp, bool leafCells, int unitStride,
                   double tolWorld, std::vector<std::pair<int, Coord>>* failing,
                   openvdb::util::NullInterrupter* interrupter = nullptr);

} // namespace adf_internal
} // namespace levelforge
