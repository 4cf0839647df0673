// Mesh → exact narrow-band level set (Chang, Cha, Ihm 2008). See MeshToLevelSet.h.
//
// This translation unit holds the heavy OpenVDB template work of the main road; keep it that way
// (compile time on 2 cores).
#include <levelforge/Exceptions.h>
#include <levelforge/MeshToLevelSet.h>
#include <levelforge/MicrotriangleVoxelizer.h>
#include <levelforge/Progress.h>
#include <levelforge/PseudoNormals.h>
#include <levelforge/TriangleDistance.h>
#include <levelforge/TriangleListTree.h>

#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

namespace levelforge {

namespace meshtols_internal {

using openvdb::Coord;
using FloatLeaf = openvdb::FloatTree::LeafNodeType;
using Clock = std::chrono::steady_clock;

inline double secondsSince(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

constexpr uint32_t kNone = 0xffffffffu;

/// A triangle copied next to the leaf that uses it (cell-space vertices, AABB and plane).
struct PreparedTri
{
    Vec3d a, b, c, lo, hi, n; // n: unit normal
    double offset;            // n · a
    uint32_t id;
};

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

/// A candidate triangle of a sub-block with its lower bound (squared, cells).
struct Cand
{
    double lb2;
    uint32_t lt;
};

/// Per-thread scratch reused for every leaf: no per-voxel allocation.
struct Scratch
{
    std::vector<Cand> cands;
    std::vector<uint64_t> bits;       // boundary-cell bit rows (along z) of the gathered region
    std::vector<uint64_t> dil;        // bits dilated along z by k = 0..R: (R+1) × rows × words
    std::vector<uint32_t> cellStart;  // per region cell: first entry in localList
    std::vector<uint32_t> cellCount;  // per region cell: list length
    std::vector<uint32_t> cellOrd;    // per gathered cell (temporary): global ordinal
    std::vector<uint32_t> cellIdx;    // per gathered cell (temporary): region index
    std::vector<uint32_t> localList;  // lists with leaf-local triangle ids
    std::vector<PreparedTri> tris;
    std::vector<uint32_t> hashKey, hashVal;
    std::vector<uint32_t> stamp;
    uint32_t gen = 0;
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

/// Fills one output leaf with origin `origin`; returns nullptr if no voxel is active.
FloatLeaf* computeLeaf(const Context& ctx, const Coord& origin, Scratch& s)
{
    const int R = ctx.R, D = ctx.D, W = ctx.words;
    const Coord rmin = origin.offsetBy(-R), rmax = origin.offsetBy(7 + R);
    const size_t nRegion = size_t(D) * D * D;
    const size_t nRows = size_t(D) * D;
    auto rowIndex = [D](int x, int y) { return size_t(x) * D + y; };

    // ---- gather the boundary cells of the region (one gather per leaf, cf. Yin et al. §6.2).
    // Region rows run along z, like the z-bytes of a VDB leaf's value mask.
    s.bits.assign(nRows * W, 0ull);
    if (s.cellStart.size() < nRegion) { s.cellStart.resize(nRegion); s.cellCount.resize(nRegion); }
    s.cellOrd.clear();
    s.cellIdx.clear();
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
                            s.cellIdx.push_back(uint32_t(row * D + rz));
                            entries += ctx.lists.listSize(ord);
                        }
                    }
                }
            }
    if (s.cellOrd.empty()) return nullptr;

    // ---- reach mask: voxels with at least one boundary cell closer than the band limit.
    // Rows dilated along z by k (k = 0..R), then OR-ed over the (dx, dy) row offsets.
    s.dil.resize(size_t(R + 1) * nRows * W);
    std::copy(s.bits.begin(), s.bits.end(), s.dil.begin());
    for (int k = 1; k <= R; ++k) { // dilate the previous level by one cell along z
        const uint64_t* prev = &s.dil[size_t(k - 1) * nRows * W];
        uint64_t* cur = &s.dil[size_t(k) * nRows * W];
        for (size_t r = 0; r < nRows; ++r) {
            const uint64_t* b = &prev[r * W];
            for (int w = 0; w < W; ++w) {
                uint64_t v = b[w] | (b[w] << 1) | (b[w] >> 1);
                if (w > 0) v |= b[w - 1] >> 63;
                if (w + 1 < W) v |= b[w + 1] << 63;
                cur[r * W + w] = v;
            }
        }
    }
    uint8_t reach[64]; // per (vx, vy): bit vz set when the voxel is within reach
    bool anyReach = false;
    for (int vx = 0; vx < 8; ++vx)
        for (int vy = 0; vy < 8; ++vy) {
            uint64_t acc = 0;
            const int cx = vx + R, cy = vy + R;
            for (const RowOffset& ro : ctx.rows) {
                const uint64_t* d = &s.dil[(size_t(ro.reachZ) * nRows + rowIndex(cx + ro.dx, cy + ro.dy)) * W];
                // bits R..R+7 of the row: voxel vz's own cell is at z = vz + R
                const int w0 = R >> 6, sh = R & 63;
                uint64_t v = d[w0] >> sh;
                if (sh && w0 + 1 < W) v |= d[w0 + 1] << (64 - sh);
                acc |= v & 0xffull;
                if (acc == 0xffull) break;
            }
            reach[vx * 8 + vy] = uint8_t(acc);
            anyReach |= acc != 0;
        }
    if (!anyReach) return nullptr;

    // ---- leaf-local triangle table (open addressing), lists rewritten with local ids
    size_t hsize = 64;
    while (hsize < 2 * entries) hsize <<= 1;
    const uint32_t hmask = uint32_t(hsize - 1);
    s.hashKey.assign(hsize, kNone);
    if (s.hashVal.size() < hsize) s.hashVal.resize(hsize);
    s.tris.clear();
    s.localList.clear();
    for (size_t k = 0; k < s.cellOrd.size(); ++k) {
        const uint32_t ord = s.cellOrd[k], idx = s.cellIdx[k];
        s.cellStart[idx] = uint32_t(s.localList.size());
        s.cellCount[idx] = ctx.lists.listSize(ord);
        for (const uint32_t* t = ctx.lists.listBegin(ord); t != ctx.lists.listEnd(ord); ++t) {
            uint32_t h = (*t * 2654435761u) & hmask;
            while (s.hashKey[h] != kNone && s.hashKey[h] != *t) h = (h + 1) & hmask;
            if (s.hashKey[h] == kNone) {
                s.hashKey[h] = *t;
                s.hashVal[h] = uint32_t(s.tris.size());
                const Vec3I& tri = ctx.mesh.triangles[*t];
                PreparedTri p;
                p.a = ctx.cellPts[tri[0]];
                p.b = ctx.cellPts[tri[1]];
                p.c = ctx.cellPts[tri[2]];
                p.lo = minComponent(minComponent(p.a, p.b), p.c);
                p.hi = maxComponent(maxComponent(p.a, p.b), p.c);
                p.n = ctx.normals.faceNormal(*t);
                p.offset = p.n.dot(p.a);
                p.id = *t;
                s.tris.push_back(p);
            }
            s.localList.push_back(s.hashVal[h]);
        }
    }
    if (s.stamp.size() < s.tris.size()) s.stamp.resize(s.tris.size(), 0);

    // ---- distances, 2×2×2 voxels at a time (Chang §4.1 layered culling, per sub-block):
    //  1. a seed triangle (the previous sub-block's closest) bounds every voxel's distance from
    //     above: U = max over the sub-block's voxels of their distance to the seed (≤ limit);
    //  2. only boundary cells whose minimum distance to the sub-block is below U can hold a
    //     closer triangle; their triangles, deduplicated, whose bounding box and plane are also
    //     closer than U, are the sub-block's candidates, sorted by that lower bound;
    //  3. each voxel walks the candidates while their bound is below its current best, testing
    //     the triangle's own box and plane before an exact point–triangle evaluation.
    //  The sign is the pseudonormal of the closest feature (§4.2).
    auto* out = new FloatLeaf(origin, ctx.background, false);
    uint64_t active = 0;
    const float bg = ctx.background;
    auto bitAt = [&](int x, int y, int z) {
        return (s.bits[rowIndex(x, y) * W + (z >> 6)] >> (z & 63)) & 1ull;
    };
    // Full layered search for one voxel (used once per leaf, to find a first seed).
    auto searchVoxel = [&](const Vec3d& p, int cx, int cy, int cz) -> uint32_t {
        if (++s.gen == 0) { std::fill(s.stamp.begin(), s.stamp.end(), 0u); s.gen = 1; }
        const uint32_t gen = s.gen;
        double best2 = ctx.limit2;
        uint32_t bestT = kNone;
        const int lo = cz - R, hi = cz + R;
        for (const RowOffset& row : ctx.rows) {
            if (row.m2 >= best2) break;
            const size_t rowI = rowIndex(cx + row.dx, cy + row.dy);
            const uint64_t* rowBits = &s.bits[rowI * W];
            for (int w = lo >> 6; w <= (hi >> 6); ++w) {
                uint64_t word = rowBits[w];
                if (!word) continue;
                const int wlo = std::max(lo - (w << 6), 0), whi = std::min(hi - (w << 6), 63);
                word &= (~0ull << wlo);
                if (whi < 63) word &= ((2ull << whi) - 1ull);
                while (word) {
                    const int lz = (w << 6) + __builtin_ctzll(word);
                    word &= word - 1;
                    const double mdz = minAxisDist(lz - cz);
                    if (row.m2 + mdz * mdz >= best2) continue;
                    const size_t idx = rowI * D + lz;
                    const uint32_t* L = s.localList.data() + s.cellStart[idx];
                    for (uint32_t k = 0, n = s.cellCount[idx]; k < n; ++k) {
                        const uint32_t lt = L[k];
                        if (s.stamp[lt] == gen) continue;
                        s.stamp[lt] = gen;
                        const PreparedTri& t = s.tris[lt];
                        if (boxDistanceSqr(p, t.lo, t.hi) >= best2) continue;
                        ++s.evaluations;
                        const double d2 = closestPointOnTriangle(p, t.a, t.b, t.c).distanceSqr;
                        if (d2 < best2) { best2 = d2; bestT = lt; }
                    }
                }
            }
        }
        return bestT;
    };

    std::vector<Cand>& cands = s.cands;
    uint32_t seed = kNone;
    for (int bx = 0; bx < 4; ++bx) {
        for (int by = 0; by < 4; ++by) {
            for (int bz = 0; bz < 4; ++bz) {
                // Reachable voxels of this sub-block.
                int vox[8][3];
                int nv = 0;
                for (int i = 0; i < 2; ++i)
                    for (int j = 0; j < 2; ++j) {
                        const uint32_t r = reach[(2 * bx + i) * 8 + 2 * by + j];
                        for (int k = 0; k < 2; ++k)
                            if (r & (1u << (2 * bz + k))) {
                                vox[nv][0] = 2 * bx + i; vox[nv][1] = 2 * by + j; vox[nv][2] = 2 * bz + k;
                                ++nv;
                            }
                    }
                if (nv == 0) continue;
                Vec3d P[8];
                for (int v = 0; v < nv; ++v)
                    P[v] = Vec3d(origin.x() + vox[v][0] + 0.5, origin.y() + vox[v][1] + 0.5, origin.z() + vox[v][2] + 0.5);
                if (seed == kNone)
                    seed = searchVoxel(P[0], vox[0][0] + R, vox[0][1] + R, vox[0][2] + R);

                // 1. upper bound from the seed
                double best2[8];
                uint32_t bestT[8];
                TriangleClosestPoint bestCp[8];
                double U2 = 0.0;
                for (int v = 0; v < nv; ++v) {
                    best2[v] = ctx.limit2;
                    bestT[v] = kNone;
                    if (seed != kNone) {
                        const PreparedTri& t = s.tris[seed];
                        ++s.evaluations;
                        const TriangleClosestPoint cp = closestPointOnTriangle(P[v], t.a, t.b, t.c);
                        if (cp.distanceSqr < best2[v]) { best2[v] = cp.distanceSqr; bestT[v] = seed; bestCp[v] = cp; }
                    }
                    U2 = std::max(U2, best2[v]);
                }

                // 2. candidates from the boundary cells within U of the sub-block
                if (++s.gen == 0) { std::fill(s.stamp.begin(), s.stamp.end(), 0u); s.gen = 1; }
                const uint32_t gen = s.gen;
                if (seed != kNone) s.stamp[seed] = gen;
                const int c0x = 2 * bx + R, c0y = 2 * by + R, c0z = 2 * bz + R; // first cell of the sub-block
                const Vec3d blo(origin.x() + 2 * bx + 0.5, origin.y() + 2 * by + 0.5, origin.z() + 2 * bz + 0.5);
                const Vec3d bhi = blo + Vec3d(1.0);
                auto md = [](int c, int lo) { // min distance along an axis from cell c to centres lo, lo+1
                    const int o = c < lo ? lo - c : (c > lo + 1 ? c - lo - 1 : 0);
                    return minAxisDist(o);
                };
                cands.clear();
                for (int x = c0x - R; x <= c0x + 1 + R; ++x) {
                    const double mx = md(x, c0x), mx2 = mx * mx;
                    if (mx2 >= U2) continue;
                    for (int y = c0y - R; y <= c0y + 1 + R; ++y) {
                        const double my = md(y, c0y), m2 = mx2 + my * my;
                        if (m2 >= U2) continue;
                        const size_t rowI = rowIndex(x, y);
                        const uint64_t* rowBits = &s.bits[rowI * W];
                        const int lo = c0z - R, hi = c0z + 1 + R;
                        for (int w = lo >> 6; w <= (hi >> 6); ++w) {
                            uint64_t word = rowBits[w];
                            if (!word) continue;
                            const int wlo = std::max(lo - (w << 6), 0), whi = std::min(hi - (w << 6), 63);
                            word &= (~0ull << wlo);
                            if (whi < 63) word &= ((2ull << whi) - 1ull);
                            while (word) {
                                const int lz = (w << 6) + __builtin_ctzll(word);
                                word &= word - 1;
                                const double mz = md(lz, c0z);
                                if (m2 + mz * mz >= U2) continue;
                                const size_t idx = rowI * D + lz;
                                const uint32_t* L = s.localList.data() + s.cellStart[idx];
                                for (uint32_t k = 0, n = s.cellCount[idx]; k < n; ++k) {
                                    const uint32_t lt = L[k];
                                    if (s.stamp[lt] == gen) continue;
                                    s.stamp[lt] = gen;
                                    const PreparedTri& t = s.tris[lt];
                                    // box–box distance between the triangle's AABB and the sub-block
                                    double lb2 = 0.0;
                                    for (int a = 0; a < 3; ++a) {
                                        const double e = t.lo[a] > bhi[a] ? t.lo[a] - bhi[a] : (blo[a] > t.hi[a] ? blo[a] - t.hi[a] : 0.0);
                                        lb2 += e * e;
                                    }
                                    if (lb2 >= U2) { ++s.boundTests; continue; }
                                    // plane distance to the sub-block (box half-extent 0.5)
                                    const double pc = t.n.dot(blo + Vec3d(0.5)) - t.offset;
                                    const double pr = 0.5 * (std::abs(t.n[0]) + std::abs(t.n[1]) + std::abs(t.n[2]));
                                    const double pd = std::abs(pc) - pr;
                                    if (pd > 0.0) lb2 = std::max(lb2, pd * pd);
                                    if (lb2 >= U2) { ++s.boundTests; continue; }
                                    cands.push_back(Cand{lb2, lt});
                                }
                            }
                        }
                    }
                }
                const int nc = int(cands.size());
                std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) {
                    return x.lb2 < y.lb2 || (x.lb2 == y.lb2 && x.lt < y.lt);
                });

                // 3. per voxel
                for (int v = 0; v < nv; ++v) {
                    const Vec3d& p = P[v];
                    double b2 = best2[v];
                    for (int k = 0; k < nc; ++k) {
                        if (cands[k].lb2 >= b2) break;
                        const PreparedTri& t = s.tris[cands[k].lt];
                        const double pd = t.n.dot(p) - t.offset;
                        if (pd * pd >= b2 || boxDistanceSqr(p, t.lo, t.hi) >= b2) { ++s.boundTests; continue; }
                        ++s.evaluations;
                        const TriangleClosestPoint cp = closestPointOnTriangle(p, t.a, t.b, t.c);
                        if (cp.distanceSqr < b2) { b2 = cp.distanceSqr; bestT[v] = cands[k].lt; bestCp[v] = cp; }
                    }
                    best2[v] = b2;
                    const int vx = vox[v][0], vy = vox[v][1], vz = vox[v][2];
                    const int cx = vx + R, cy = vy + R, cz = vz + R;
                    ++s.candidateVoxels;
                    if (bitAt(cx, cy, cz) || bitAt(cx - 1, cy, cz) || bitAt(cx + 1, cy, cz) ||
                        bitAt(cx, cy - 1, cz) || bitAt(cx, cy + 1, cz) || bitAt(cx, cy, cz - 1) ||
                        bitAt(cx, cy, cz + 1))
                        ++s.localCells;
                    if (bestT[v] == kNone) continue; // nothing within reach: sign left to the flood fill
                    seed = bestT[v];
                    const openvdb::Index offset = openvdb::Index((vx << 6) | (vy << 3) | vz);
                    const double d = std::sqrt(b2);
                    const Vec3d& n = ctx.normals.normal(s.tris[bestT[v]].id, bestCp[v].feature);
                    const bool inside = (p - bestCp[v].point).dot(n) < 0.0;
                    if (inside ? d < ctx.intW : d < ctx.extW) {
                        out->setValueOn(offset, float((inside ? -d : d) * ctx.voxelSize));
                        ++active;
                    } else {
                        out->setValueOff(offset, inside ? -bg : bg);
                    }
                }
            }
        }
    }
    s.activeVoxels += active;
    if (active == 0) { delete out; return nullptr; }
    return out;
}

void checkMesh(const TriangleMesh& mesh)
{
    const std::string where = mesh.source.empty() ? std::string("mesh") : mesh.source;
    if (mesh.triangles.empty()) throw InvalidMeshError(where + ": mesh has no triangles");
    const size_t nv = mesh.points.size();
    for (size_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k)
            if (mesh.triangles[t][k] >= nv) {
                std::ostringstream os;
                os << where << ": face " << t << " refers to vertex " << mesh.triangles[t][k]
                   << " but the mesh has " << nv << " vertices";
                throw InvalidMeshError(os.str());
            }
    for (size_t v = 0; v < nv; ++v) {
        const Vec3d& p = mesh.points[v];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            std::ostringstream os;
            os << where << ": vertex " << v << " has a non-finite coordinate (" << p[0] << ", " << p[1]
               << ", " << p[2] << ")";
            throw InvalidMeshError(os.str());
        }
    }
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

double resolveVoxelSize(const TriangleMesh& mesh, const MeshToLevelSetOptions& options)
{
    const double vs = options.voxelSize;
    if (std::isnan(vs) || std::isinf(vs) || vs < 0.0) {
        std::ostringstream os;
        os << "voxel size must be a positive number (world units), got " << vs;
        throw InvalidArgumentError(os.str());
    }
    if (vs > 0.0) return vs;
    if (options.voxelCount <= 0)
        throw InvalidArgumentError("give a positive voxel size or a positive voxel count (got voxel count " +
                                   std::to_string(options.voxelCount) + ")");
    const BBoxd b = mesh.bounds();
    if (mesh.triangles.empty() || b.min()[0] > b.max()[0])
        throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) + ": mesh has no triangles");
    const double extent = b.extents()[b.maxExtent()];
    if (!(extent > 0.0) || !std::isfinite(extent))
        throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) +
                               ": bounding box has zero or non-finite size; cannot derive a voxel size from a count");
    return extent / double(options.voxelCount);
}

openvdb::FloatGrid::Ptr meshToLevelSet(const TriangleMesh& mesh, const MeshToLevelSetOptions& options,
                                       MeshToLevelSetStats* statsOut)
{
    using namespace meshtols_internal;
    openvdb::initialize();
    MeshToLevelSetStats stats;
    auto* interrupter = options.interrupter;

    checkWidth("exterior band width", options.exteriorWidth);
    checkWidth("interior band width", options.interiorWidth);
    checkMesh(mesh);
    const double h = resolveVoxelSize(mesh, options);
    stats.voxelSize = h;

    const double extW = options.exteriorWidth, intW = options.interiorWidth;
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
    stats.secondsVoxelize = secondsSince(t0);
    stats.secondsLists = 0.0; // both passes are timed together in secondsVoxelize
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
    tbb::enumerable_thread_specific<Scratch> scratchTls;
    std::atomic<bool> stop{false};
    std::atomic<size_t> done{0};
    const size_t reportEvery = std::max<size_t>(1, cand.size() / 50);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cand.size(), 4), [&](const tbb::blocked_range<size_t>& r) {
        if (stop.load(std::memory_order_relaxed)) return;
        Scratch& s = scratchTls.local();
        for (size_t i = r.begin(); i != r.end(); ++i) outLeaves[i] = computeLeaf(ctx, cand[i], s);
        const size_t d = done.fetch_add(r.size()) + r.size();
        if (interrupter && (d / reportEvery) != ((d - r.size()) / reportEvery)) {
            if (interrupter->wasInterrupted(20 + int(75.0 * double(d) / double(cand.size())))) stop = true;
        }
    });
    if (stop) {
        for (FloatLeaf* l : outLeaves) delete l;
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
    stats.secondsFinish = secondsSince(t2);
    if (interrupter) { interrupter->wasInterrupted(100); interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return grid;
}

} // namespace levelforge
