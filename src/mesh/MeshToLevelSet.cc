// SPDX-License-Identifier: Apache-2.0
// Mesh → exact narrow-band level set (Chang, Cha, Ihm 2008): the exact band. See MeshToLevelSet.h.
// This translation unit holds the heavy OpenVDB template work of the main road.
#include "detail/ProgressCheck.h"
#include "detail/PreparedTriangle.h"
#include "detail/Timer.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/mesh/MicrotriangleVoxelizer.h>
#include <levelforge/core/Progress.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/core/TriangleDistance.h>
#include <levelforge/mesh/TriangleListTree.h>

#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

namespace levelforge {

namespace meshtols_internal {

using openvdb::Coord;
using FloatLeaf = openvdb::FloatTree::LeafNodeType;
using Vec3fLeaf = openvdb::Vec3fTree::LeafNodeType;
using Int32Leaf = openvdb::Int32Tree::LeafNodeType;
using detail::Clock;
using detail::secondsSince;
using detail::PreparedTri;

constexpr uint32_t kNone = 0xffffffffu;


/// A row of cells (along z) at offsets (dx, dy) from the voxel's cell, with its minimum squared
/// distance from the voxel centre (the paper's layer groups 0, 1/4, 1/2, ... generalised), and
/// how far along z the row can hold a cell closer than the band limit.
struct RowOffset
{
    int dx, dy;
    double m2;
    int reachZ;
};

inline double minAxisDist(int o) { const double d = std::abs(o) - 0.5; return d > 0.0 ? d : 0.0; }


/// Per-thread scratch reused for every leaf: no per-voxel allocation.
struct Scratch
{
    std::vector<uint64_t> bits;       // boundary-cell bit rows (along z) of the gathered region
    std::vector<uint32_t> cellOrd;    // per gathered cell (temporary): global ordinal
    std::vector<uint8_t> zwin;        // z-windows of the dilated rows, per dilation k
    std::vector<PreparedTri> tris;
    std::vector<float> soa, lb2;  // lower-bound planes (16 SoA arrays) and per-voxel bounds
    std::vector<uint32_t> surv;
    std::vector<uint32_t> hashKey;    // leaf-local set of triangle ids (open addressing)
    uint64_t evaluations = 0, boundTests = 0, candidateVoxels = 0, activeVoxels = 0, localCells = 0;
};

struct Context
{
    const TriangleMesh& mesh;
    const std::vector<Vec3d>& cellPts; // mesh points in cell space
    const TriangleListTree& lists;
    const PseudoNormals& normals;
    double voxelSize;
    double extW, intW, limit, limit2;
    int R, D, words;
    std::vector<RowOffset> rows;
    float background;
};

/// The 8 bits of a multi-word bit row starting at bit `pos` (bits past the end read as 0).
inline uint32_t bits8Helper(const uint64_t* row, int pos, int words)
{
    const int w = pos >> 6, sh = pos & 63;
    if (w >= words) return 0u;
    uint64_t v = row[w] >> sh;
    if (sh > 56 && w + 1 < words) v |= row[w + 1] << (64 - sh);
    return uint32_t(v & 0xffu);
}

/// lb2[i] = plane_i(p)² + max(0, edge lines_i(p))² for the SoA bound planes F[0..15];
/// n is a multiple of 8. Appends to surv the indices with lb2 < bm2 and returns their count. SSE2 on x86-64 (4 triangles per instruction), scalar elsewhere.
uint32_t computeBounds(float* const* F, size_t n, float px, float py, float pz, float bm2, float* __restrict lb2,
                       uint32_t* __restrict surv)
{
    uint32_t ns = 0;
#if defined(__SSE2__)
    const __m128 X = _mm_set1_ps(px), Y = _mm_set1_ps(py), Z = _mm_set1_ps(pz), zero = _mm_setzero_ps();
    auto plane = [&](int f, size_t i) {
        const __m128 v = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_loadu_ps(F[f] + i), X), _mm_mul_ps(_mm_loadu_ps(F[f + 1] + i), Y)),
                                    _mm_mul_ps(_mm_loadu_ps(F[f + 2] + i), Z));
        return _mm_sub_ps(v, _mm_loadu_ps(F[f + 3] + i));
    };
    for (size_t i = 0; i < n; i += 4) {
        const __m128 pd = plane(0, i);
        const __m128 e = _mm_max_ps(_mm_max_ps(plane(4, i), plane(8, i)), _mm_max_ps(plane(12, i), zero));
        const __m128 l = _mm_add_ps(_mm_mul_ps(pd, pd), _mm_mul_ps(e, e));
        _mm_storeu_ps(lb2 + i, l);
        int m = _mm_movemask_ps(_mm_cmplt_ps(l, _mm_set1_ps(bm2)));
        while (m) {
            surv[ns++] = uint32_t(i) + uint32_t(__builtin_ctz(unsigned(m)));
            m &= m - 1;
        }
    }
#else
    for (size_t i = 0; i < n; ++i) {
        auto plane = [&](int f) { return F[f][i] * px + F[f + 1][i] * py + F[f + 2][i] * pz - F[f + 3][i]; };
        const float pd = plane(0);
        const float e = std::max(std::max(plane(4), plane(8)), std::max(plane(12), 0.0f));
        lb2[i] = pd * pd + e * e;
        if (lb2[i] < bm2) surv[ns++] = uint32_t(i);
    }
#endif
    return ns;
}

/// Fills one output leaf with origin `origin`; returns nullptr if no voxel is active.
// cpOut / triOut (optional, together): receive leaves of closest-point offsets (voxel units) and
// closest-triangle indices for the active voxels.
FloatLeaf* computeLeaf(const Context& ctx, const Coord& origin, Scratch& s, Vec3fLeaf** cpOut = nullptr,
                       Int32Leaf** triOut = nullptr)
{
    const int R = ctx.R, D = ctx.D, W = ctx.words;
    const Coord rmin = origin.offsetBy(-R), rmax = origin.offsetBy(7 + R);
    const size_t nRows = size_t(D) * D;
    auto rowIndex = [D](int x, int y) { return size_t(x) * D + y; };

    // ---- gather the boundary cells of the region (one gather per leaf, cf. Yin et al. §6.2).
    // Region rows run along z, like the z-bytes of a VDB leaf's value mask.
    s.bits.assign(nRows * W, 0ull);
    s.cellOrd.clear();
    uint64_t entries = 0;
    const auto& tree = ctx.lists.tree();
    for (int lx = rmin.x() & ~7; lx <= rmax.x(); lx += 8)
        for (int ly = rmin.y() & ~7; ly <= rmax.y(); ly += 8)
            for (int lz = rmin.z() & ~7; lz <= rmax.z(); lz += 8) {
                const auto* leaf = tree.probeConstLeaf(Coord(lx, ly, lz));
                if (!leaf) continue;
                const auto& mask = leaf->getValueMask();
                const int x0 = std::max(lx, rmin.x()), x1 = std::min(lx + 7, rmax.x());
                const int y0 = std::max(ly, rmin.y()), y1 = std::min(ly + 7, rmax.y());
                const int z0 = std::max(lz, rmin.z()), z1 = std::min(lz + 7, rmax.z());
                const uint32_t zsel = (0xffu << (z0 - lz)) & (0xffu >> (7 - (z1 - lz)));
                for (int x = x0; x <= x1; ++x) {
                    const uint64_t word = mask.template getWord<uint64_t>(x - lx);
                    for (int y = y0; y <= y1; ++y) {
                        uint32_t zb = uint32_t(word >> (8 * (y - ly))) & zsel;
                        if (!zb) continue;
                        const int rx = x - rmin.x(), ry = y - rmin.y();
                        const size_t row = rowIndex(rx, ry);
                        while (zb) {
                            const int bz = __builtin_ctz(zb);
                            zb &= zb - 1;
                            const int rz = lz + bz - rmin.z();
                            s.bits[row * W + (rz >> 6)] |= (1ull << (rz & 63));
                            const uint32_t ord = leaf->getValue(openvdb::Index(((x - lx) << 6) | ((y - ly) << 3) | bz));
                            s.cellOrd.push_back(ord);
                            entries += ctx.lists.listSize(ord);
                        }
                    }
                }
            }
    if (s.cellOrd.empty()) return nullptr;

    // ---- reach mask: voxels with at least one boundary cell closer than the band limit.
    // zwin[k][row] = the 8 bits of the leaf's z-range (region z = R..R+7) of the row dilated
    // along z by k cells; a voxel is within reach if, for some row offset (dx, dy) with its
    // largest admissible dz = reachZ, zwin[reachZ][row(x+dx, y+dy)] has its bit set. Rows are
    // laid out x-major, so for fixed x the 8 y-neighbours are 8 consecutive bytes: one 64-bit
    // load covers a whole (vx, ·) line of the leaf.
    auto bits8 = [&](const uint64_t* row, int pos) -> uint32_t { // 8 bits starting at pos (may be < 0)
        if (pos < 0) { return pos <= -8 ? 0u : uint32_t(bits8Helper(row, 0, W) << (-pos)) & 0xffu; }
        return bits8Helper(row, pos, W);
    };
    s.zwin.assign(size_t(R + 1) * nRows + 8, 0u);
    for (size_t r = 0; r < nRows; ++r) {
        const uint64_t* row = &s.bits[r * W];
        uint32_t acc = bits8(row, R);
        s.zwin[r] = uint8_t(acc);
        for (int k = 1; k <= R; ++k) {
            acc |= bits8(row, R + k) | bits8(row, R - k);
            s.zwin[size_t(k) * nRows + r] = uint8_t(acc);
        }
    }
    uint8_t reach[64]; // [vx * 8 + vy]: bit vz set when the voxel is within reach
    uint64_t any = 0;
    for (int vx = 0; vx < 8; ++vx) {
        uint64_t line = 0; // byte vy = reach bits of (vx, vy, ·)
        for (const RowOffset& ro : ctx.rows) {
            uint64_t w;
            std::memcpy(&w, &s.zwin[size_t(ro.reachZ) * nRows + rowIndex(vx + R + ro.dx, R + ro.dy)], 8);
            line |= w;
        }
        std::memcpy(&reach[vx * 8], &line, 8);
        any |= line;
    }
    const bool anyReach = any != 0;
    if (!anyReach) return nullptr;

    // ---- the leaf's triangle set T: every triangle listed in a boundary cell of the region.
    // Any triangle closer than `limit` to a voxel of this leaf has its closest point in such a
    // cell (the layer rule of §4.1 bounds the cell's minimum distance), so T is complete.
    size_t hsize = 64;
    while (hsize < 2 * entries) hsize <<= 1;
    const uint32_t hmask = uint32_t(hsize - 1);
    s.hashKey.assign(hsize, kNone);
    s.tris.clear();
    for (size_t k = 0; k < s.cellOrd.size(); ++k) {
        const uint32_t ord = s.cellOrd[k];
        for (const uint32_t* t = ctx.lists.listBegin(ord); t != ctx.lists.listEnd(ord); ++t) {
            uint32_t h = (*t * 2654435761u) & hmask;
            while (s.hashKey[h] != kNone && s.hashKey[h] != *t) h = (h + 1) & hmask;
            if (s.hashKey[h] != kNone) continue;
            s.hashKey[h] = *t;
            const Vec3I& tri = ctx.mesh.triangles[*t];
            PreparedTri p;
            p.a = ctx.cellPts[tri[0]];
            p.b = ctx.cellPts[tri[1]];
            p.c = ctx.cellPts[tri[2]];
            p.id = *t;
            s.tris.push_back(p);
        }
    }
    // Lower-bound planes in single precision, relative to the leaf centre (small numbers):
    // the triangle's plane and the three in-plane edge lines (outward normals). For a point p,
    // dist² ≥ plane(p)² + max(0, edge_k(p))², exact in face and edge regions.
    const size_t nT = s.tris.size(), nTpad = (nT + 7) & ~size_t(7);
    s.soa.assign(16 * nTpad, 0.0f);
    float* F[16];
    for (int f = 0; f < 16; ++f) F[f] = s.soa.data() + f * nTpad;
    const Vec3d centre(origin.x() + 4.0, origin.y() + 4.0, origin.z() + 4.0);
    for (size_t i = 0; i < nT; ++i) {
        const PreparedTri& t = s.tris[i];
        const Vec3d& n = ctx.normals.faceNormal(t.id);
        const Vec3d v[3] = {t.a - centre, t.b - centre, t.c - centre};
        F[0][i] = float(n[0]); F[1][i] = float(n[1]); F[2][i] = float(n[2]); F[3][i] = float(n.dot(v[0]));
        for (int k = 0; k < 3; ++k) {
            Vec3d m = (v[(k + 1) % 3] - v[k]).cross(n);
            const double len = m.length();
            m = len > 0.0 ? m / len : Vec3d(0.0);
            F[4 + 4 * k][i] = float(m[0]);
            F[5 + 4 * k][i] = float(m[1]);
            F[6 + 4 * k][i] = float(m[2]);
            F[7 + 4 * k][i] = float(m.dot(v[k]));
        }
    }
    for (size_t i = nT; i < nTpad; ++i) F[3][i] = 1e30f; // padding never survives
    if (s.lb2.size() < nTpad) { s.lb2.resize(nTpad); s.surv.resize(nTpad); }

    // ---- per voxel (Chang §4.1 culling, with triangle-level bounds instead of cell groups):
    // the previous voxel's closest triangle gives an upper bound; the bounds of all of T are
    // computed in one vectorised pass; survivors are evaluated exactly in increasing bound
    // order until the bound passes the best distance. The sign is the pseudonormal of the
    // closest feature (§4.2).
    auto* out = new FloatLeaf(origin, ctx.background, false);
    Vec3fLeaf* cpLeaf = cpOut ? new Vec3fLeaf(origin, openvdb::Vec3f(0.0f), false) : nullptr;
    Int32Leaf* triLeaf = cpOut ? new Int32Leaf(origin, -1, false) : nullptr;
    uint64_t active = 0;
    const float bg = ctx.background;
    // Cells; covers the single-precision rounding of the bounds. The bound terms that matter are
    // differences of values of magnitude <= limit + ~20 cells (the plane or edge line passes that
    // close to the leaf centre), so their rounding error is a few ulps of that: ~1e-5 at limit 3.
    const double kMargin = 1e-4 * std::max(1.0, (ctx.limit + 20.0) / 32.0);
    auto bitAt = [&](int x, int y, int z) {
        return (s.bits[rowIndex(x, y) * W + (z >> 6)] >> (z & 63)) & 1ull;
    };
    uint32_t seed = kNone;
    float* lb2 = s.lb2.data();
    uint32_t* surv = s.surv.data();
    for (int vx = 0; vx < 8; ++vx) {
        for (int vy = 0; vy < 8; ++vy) {
            uint32_t reachBits = reach[vx * 8 + vy];
            const int cx = vx + R, cy = vy + R;
            while (reachBits) {
                const int vz = __builtin_ctz(reachBits);
                reachBits &= reachBits - 1;
                const int cz = vz + R;
                ++s.candidateVoxels;
                if (bitAt(cx, cy, cz) || bitAt(cx - 1, cy, cz) || bitAt(cx + 1, cy, cz) ||
                    bitAt(cx, cy - 1, cz) || bitAt(cx, cy + 1, cz) || bitAt(cx, cy, cz - 1) ||
                    bitAt(cx, cy, cz + 1))
                    ++s.localCells;
                const Vec3d p(origin.x() + vx + 0.5, origin.y() + vy + 0.5, origin.z() + vz + 0.5);
                double best2 = ctx.limit2;
                uint32_t bestT = kNone;
                TriangleClosestPoint bestCp{Vec3d(0.0), 0.0, TriangleFeature::Face};
                if (seed != kNone) {
                    const PreparedTri& t = s.tris[seed];
                    ++s.evaluations;
                    const TriangleClosestPoint cp = closestPointOnTriangle(p, t.a, t.b, t.c);
                    if (cp.distanceSqr < best2) { best2 = cp.distanceSqr; bestT = seed; bestCp = cp; }
                }
                // Bounds of every triangle of T (SIMD), survivors below the current best.
                double bm = std::sqrt(best2) + kMargin;
                float bm2 = float(bm * bm);
                const uint32_t ns = computeBounds(F, nTpad, float(vx - 3.5), float(vy - 3.5), float(vz - 3.5), bm2, lb2, surv);
                s.boundTests += nT;
                // Evaluate survivors in increasing bound order (lazy selection: usually the first
                // one is the closest and the next bound already exceeds it).
                for (uint32_t done = 0; done < ns; ++done) {
                    uint32_t pick = done;
                    for (uint32_t k = done + 1; k < ns; ++k)
                        if (lb2[surv[k]] < lb2[surv[pick]] || (lb2[surv[k]] == lb2[surv[pick]] && surv[k] < surv[pick])) pick = k;
                    std::swap(surv[done], surv[pick]);
                    const uint32_t lt = surv[done];
                    if (lb2[lt] >= bm2) break;
                    if (lt == seed) continue;
                    const PreparedTri& t = s.tris[lt];
                    ++s.evaluations;
                    const TriangleClosestPoint cp = closestPointOnTriangle(p, t.a, t.b, t.c);
                    if (cp.distanceSqr < best2) {
                        best2 = cp.distanceSqr;
                        bestT = lt;
                        bestCp = cp;
                        bm = std::sqrt(best2) + kMargin;
                        bm2 = float(bm * bm);
                    }
                }

                seed = bestT;
                if (bestT == kNone) continue; // nothing within reach: sign left to the flood fill
                const openvdb::Index offset = openvdb::Index((vx << 6) | (vy << 3) | vz);
                const double d = std::sqrt(best2);
                const bool inside = ctx.normals.isInside(s.tris[bestT].id, bestCp, p);
                if (inside ? d < ctx.intW : d < ctx.extW) {
                    out->setValueOn(offset, float((inside ? -d : d) * ctx.voxelSize));
                    if (cpLeaf) {
                        cpLeaf->setValueOn(offset, openvdb::Vec3f(bestCp.point - p));
                        triLeaf->setValueOn(offset, int32_t(s.tris[bestT].id));
                    }
                    ++active;
                } else {
                    out->setValueOff(offset, inside ? -bg : bg);
                }
            }
        }
    }
    s.activeVoxels += active;
    if (active == 0) { delete out; delete cpLeaf; delete triLeaf; return nullptr; }
    if (cpOut) { *cpOut = cpLeaf; *triOut = triLeaf; }
    return out;
}

void checkWidth(const char* name, float w)
{
    if (!std::isfinite(w) || w <= 0.0f) {
        std::ostringstream os;
        os << name << " must be a positive number of voxels, got " << w;
        throw InvalidArgumentError(os.str());
    }
}

} // namespace meshtols_internal

namespace {
LevelSetWithClosestPoints convert(const TriangleMesh& mesh, const MeshToLevelSetOptions& options,
                                  MeshToLevelSetStats* statsOut, bool wantClosest)
{
    using namespace meshtols_internal;
    openvdb::initialize();
    MeshToLevelSetStats stats;
    auto* interrupter = options.interrupter;

    requireUsableMesh(mesh);
    const double h = resolveVoxelSize(mesh, options);
    stats.voxelSize = h;
    // Band limits in voxels, held in float as they always were.
    const float extWf = static_cast<float>(options.widthInVoxels(options.exteriorWidth, h));
    const float intWf = static_cast<float>(options.widthInVoxels(options.interiorWidth, h));
    checkWidth("exterior band width", extWf);
    checkWidth("interior band width", intWf);

    const double extW = extWf, intW = intWf;
    const double limit = std::max(extW, intW);

    // Cell space: cell ijk = [i, i+1)^3 holds voxel ijk, whose centre is at world ijk*h.
    const BBoxd bounds = mesh.bounds();
    for (int k = 0; k < 3; ++k) {
        const double lo = bounds.min()[k] / h - limit - 16, hi = bounds.max()[k] / h + limit + 16;
        if (!(std::abs(lo) < 1.0e9 && std::abs(hi) < 1.0e9)) {
            std::ostringstream os;
            os << "voxel size " << h << " is too small for this mesh: index coordinates would reach "
               << std::max(std::abs(lo), std::abs(hi)) << " (limit 1e9)";
            throw ResourceLimitError(os.str());
        }
    }

    if (interrupter) interrupter->start("mesh to level set");
    const auto t0 = Clock::now();

    std::vector<Vec3d> cellPts(mesh.points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cellPts.size(), 8192), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) cellPts[i] = mesh.points[i] / h + Vec3d(0.5);
    });
    PseudoNormals normals(mesh);
    std::vector<uint32_t> use;
    use.reserve(mesh.triangles.size());
    double area = 0.0; // voxel units, for the memory estimate
    for (uint32_t t = 0; t < mesh.triangles.size(); ++t) {
        if (normals.isDegenerate(t)) { ++stats.skippedDegenerate; continue; }
        const Vec3I& tri = mesh.triangles[t];
        area += 0.5 * (cellPts[tri[1]] - cellPts[tri[0]]).cross(cellPts[tri[2]] - cellPts[tri[0]]).length();
        use.push_back(t);
    }
    stats.triangles = use.size();
    if (use.empty())
        throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) +
                               ": every triangle is degenerate (zero area)");

    // Memory guard: a band of width (ext + int) over the surface area, both sides.
    const double estimate = area * (extW + intW + 2.0) + double(use.size());
    if (options.maxVoxels > 0 && estimate > double(options.maxVoxels)) {
        std::ostringstream os;
        os << "the band would hold about " << uint64_t(estimate) << " voxels (surface area " << uint64_t(area)
           << " voxels² × band " << (extW + intW) << " voxels), more than the limit of " << options.maxVoxels
           << "; use a larger voxel size or narrower band";
        throw ResourceLimitError(os.str());
    }

    // ---- §3: voxelization + two-pass triangle lists
    VoxelizerCounters vc;
    TriangleListTree lists = TriangleListTree::build(cellPts, mesh.triangles, use, &vc, interrupter);
    stats.microtriangles = vc.microtriangles;
    stats.caseCounts = vc.cases;
    stats.boundaryCells = lists.cellCount();
    stats.triangleListEntries = lists.entryCount();
    stats.secondsLists = lists.secondsLists();
    stats.secondsVoxelize = secondsSince(t0) - stats.secondsLists; // checks, normals, pass 1
    progress_internal::check(interrupter, 20);

    // ---- candidate output leaves: leaves within reach R of a boundary-cell leaf
    Context ctx{mesh, cellPts, lists, normals, h, extW, intW, limit, limit * limit, 0, 0, 1, {}, float(extW * h)};
    ctx.R = int(std::ceil(limit + 0.5)) - 1;
    if (ctx.R < 1) ctx.R = 1;
    ctx.D = 8 + 2 * ctx.R;
    ctx.words = (ctx.D + 63) / 64;
    for (int dx = -ctx.R; dx <= ctx.R; ++dx)
        for (int dy = -ctx.R; dy <= ctx.R; ++dy) {
            const double m2 = minAxisDist(dx) * minAxisDist(dx) + minAxisDist(dy) * minAxisDist(dy);
            if (m2 >= ctx.limit2) continue;
            int reachZ = 0; // largest |dz| with m2 + minAxisDist(dz)^2 < limit^2
            while (reachZ < ctx.R && m2 + minAxisDist(reachZ + 1) * minAxisDist(reachZ + 1) < ctx.limit2) ++reachZ;
            ctx.rows.push_back({dx, dy, m2, reachZ});
        }
    std::stable_sort(ctx.rows.begin(), ctx.rows.end(), [](const RowOffset& a, const RowOffset& b) { return a.m2 < b.m2; });

    const auto t1 = Clock::now();
    std::vector<Coord> listLeafOrigins;
    listLeafOrigins.reserve(lists.tree().leafCount());
    for (auto it = lists.tree().cbeginLeaf(); it; ++it) listLeafOrigins.push_back(it->origin());
    tbb::enumerable_thread_specific<std::vector<Coord>> candTls;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, listLeafOrigins.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        auto& out = candTls.local();
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const auto* leaf = lists.tree().probeConstLeaf(listLeafOrigins[i]);
            openvdb::CoordBBox bb;
            leaf->evalActiveBoundingBox(bb, false);
            bb.expand(ctx.R);
            for (int z = bb.min().z() & ~7; z <= bb.max().z(); z += 8)
                for (int y = bb.min().y() & ~7; y <= bb.max().y(); y += 8)
                    for (int x = bb.min().x() & ~7; x <= bb.max().x(); x += 8) out.emplace_back(x, y, z);
        }
    });
    std::vector<Coord> cand;
    for (auto& v : candTls) cand.insert(cand.end(), v.begin(), v.end());
    tbb::parallel_sort(cand.begin(), cand.end());
    cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
    if (options.maxVoxels > 0 && double(cand.size()) * 512.0 > 4.0 * double(options.maxVoxels)) {
        std::ostringstream os;
        os << "the band would need " << cand.size() << " leaf nodes (" << cand.size() * 512
           << " voxels), more than the limit allows; use a larger voxel size or narrower band";
        throw ResourceLimitError(os.str());
    }

    // ---- §4: distances, leaf by leaf
    std::vector<FloatLeaf*> outLeaves(cand.size(), nullptr);
    std::vector<Vec3fLeaf*> cpLeaves(wantClosest ? cand.size() : 0, nullptr);
    std::vector<Int32Leaf*> triLeaves(wantClosest ? cand.size() : 0, nullptr);
    tbb::enumerable_thread_specific<Scratch> scratchTls;
    std::atomic<bool> stop{false};
    std::atomic<size_t> done{0};
    const size_t reportEvery = std::max<size_t>(1, cand.size() / 50);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cand.size(), 4), [&](const tbb::blocked_range<size_t>& r) {
        if (stop.load(std::memory_order_relaxed)) return;
        Scratch& s = scratchTls.local();
        for (size_t i = r.begin(); i != r.end(); ++i)
            outLeaves[i] = computeLeaf(ctx, cand[i], s, wantClosest ? &cpLeaves[i] : nullptr,
                                       wantClosest ? &triLeaves[i] : nullptr);
        const size_t d = done.fetch_add(r.size()) + r.size();
        if (interrupter && (d / reportEvery) != ((d - r.size()) / reportEvery)) {
            if (interrupter->wasInterrupted(20 + int(75.0 * double(d) / double(cand.size())))) stop = true;
        }
    });
    if (stop) {
        for (FloatLeaf* l : outLeaves) delete l;
        for (Vec3fLeaf* l : cpLeaves) delete l;
        for (Int32Leaf* l : triLeaves) delete l;
        throw InterruptedError("interrupted while computing distances");
    }
    for (const Scratch& s : scratchTls) {
        stats.distanceEvaluations += s.evaluations;
        stats.boundTests += s.boundTests;
        stats.candidateVoxels += s.candidateVoxels;
        stats.activeVoxels += s.activeVoxels;
        stats.localCells += s.localCells;
    }
    stats.secondsDistance = secondsSince(t1);

    // ---- assemble the tree (serial, fixed order), signed flood fill, grid
    const auto t2 = Clock::now();
    auto tree = std::make_shared<openvdb::FloatTree>(float(extW * h));
    for (FloatLeaf* l : outLeaves)
        if (l) tree->addLeaf(l);
    openvdb::tools::signedFloodFill(*tree);
    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName(options.gridName);
    LevelSetWithClosestPoints result;
    result.levelSet = grid;
    if (wantClosest) {
        auto cpTree = std::make_shared<openvdb::Vec3fTree>(openvdb::Vec3f(0.0f));
        for (Vec3fLeaf* l : cpLeaves)
            if (l) cpTree->addLeaf(l);
        result.closestPoints = openvdb::Vec3fGrid::create(cpTree);
        result.closestPoints->setTransform(grid->transform().copy());
        result.closestPoints->setName(options.gridName + "_closest");
        result.closestPoints->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
        auto triTree = std::make_shared<openvdb::Int32Tree>(-1);
        for (Int32Leaf* l : triLeaves)
            if (l) triTree->addLeaf(l);
        result.closestTriangles = openvdb::Int32Grid::create(triTree);
        result.closestTriangles->setTransform(grid->transform().copy());
        result.closestTriangles->setName(options.gridName + "_triangle");
    }
    stats.secondsFinish = secondsSince(t2);
    if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return result;
}
} // namespace

openvdb::FloatGrid::Ptr meshToLevelSet(const TriangleMesh& mesh, const MeshToLevelSetOptions& options,
                                       MeshToLevelSetStats* statsOut)
{
    return convert(mesh, options, statsOut, false).levelSet;
}

LevelSetWithClosestPoints meshToLevelSetWithClosestPoints(const TriangleMesh& mesh,
                                                          const MeshToLevelSetOptions& options,
                                                          MeshToLevelSetStats* statsOut)
{
    return convert(mesh, options, statsOut, true);
}

} // namespace levelforge
