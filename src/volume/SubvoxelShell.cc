// SPDX-License-Identifier: Apache-2.0
// Sub-voxel shell of closest-point vectors (see include/levelforge/volume/SubvoxelShell.h).
#include <levelforge/volume/SubvoxelShell.h>

#include "detail/IsoSurfaceCells.h"
#include "detail/Timer.h"
#include "detail/UninitialisedAllocator.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/TriangleDistance.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

namespace levelforge {
namespace {

using iso_surface_internal::Tri;
using iso_surface_internal::cellTriangles;

using detail::Clock;
/// The shell's triangles, written in parallel right after they are allocated: not zeroed first
/// (2.7 M triangles, 194 MB, for a 181 × 217 × 181 brain: 10 % of a conversion zeroed on one
/// thread).
using TriVector = std::vector<Tri, detail::UninitialisedAllocator<Tri>>;

void checkVolume(const ScalarVolume& f)
{
    requireValidVolume(f, "sub-voxel shell");
    if (f.dims.x() < 2 || f.dims.y() < 2 || f.dims.z() < 2) {
        std::ostringstream os;
        os << "sub-voxel shell: the volume must have at least 2 samples along each axis, got "
           << f.dims.x() << "x" << f.dims.y() << "x" << f.dims.z();
        throw InvalidArgumentError(os.str());
    }
}

using iso_surface_internal::triDistance2;

class Shell
{
public:
    Shell(const ScalarVolume& f, const SubvoxelShellOptions& o) : mF(f), mOpt(o)
    {
        const size_t n = f.voxelCount();
        for (size_t i = 0; i < n; ++i) {
            if (std::isnan(f.data[i])) {
                const int x = int(i % size_t(f.dims.x())), y = int((i / size_t(f.dims.x())) % size_t(f.dims.y())),
                          z = int(i / (size_t(f.dims.x()) * size_t(f.dims.y())));
                std::ostringstream os;
                os << "sub-voxel shell: sample (" << x << ", " << y << ", " << z << ") is NaN";
                throw InvalidArgumentError(os.str());
            }
        }
        mInside = insideFlags(f, o);
    }

    const MaskVolume& inside() const { return mInside; }

    /// Triangles of every surface cell, indexed by cell (CSR over the cells that have some).
    void buildSurface(SubvoxelShellStats& stats)
    {
        const int cx = mF.dims.x() - 1, cy = mF.dims.y() - 1, cz = mF.dims.z() - 1;
        mCellDims = openvdb::Coord(cx, cy, cz);
        const size_t nCells = size_t(cx) * size_t(cy) * size_t(cz);
        mCellBegin.assign(nCells + 1, 0);
        // pass 1: triangle counts per cell (parallel over z-slabs), pass 2: fill
        std::vector<uint32_t> counts(nCells, 0);
        tbb::parallel_for(tbb::blocked_range<int>(0, cz), [&](const tbb::blocked_range<int>& r) {
            for (int k = r.begin(); k != r.end(); ++k)
                for (int j = 0; j < cy; ++j)
                    for (int i = 0; i < cx; ++i) {
                        const size_t c = cellIndex(i, j, k);
                        if (!mixed(i, j, k)) continue;
                        uint32_t nt = 0;
                        double v[8];
                        Vec3d p[8];
                        corners(i, j, k, v, p);
                        cellTriangles(v, p, mOpt.iso, mOpt.insideBelow, [&](const Tri&) { ++nt; });
                        counts[c] = nt;
                    }
        });
        uint64_t total = 0, cells = 0;
        for (size_t c = 0; c < nCells; ++c) {
            mCellBegin[c] = total;
            total += counts[c];
            cells += counts[c] ? 1 : 0;
        }
        mCellBegin[nCells] = total;
        mTris.resize(total);
        tbb::parallel_for(tbb::blocked_range<int>(0, cz), [&](const tbb::blocked_range<int>& r) {
            for (int k = r.begin(); k != r.end(); ++k)
                for (int j = 0; j < cy; ++j)
                    for (int i = 0; i < cx; ++i) {
                        const size_t c = cellIndex(i, j, k);
                        if (mCellBegin[c + 1] == mCellBegin[c]) continue;
                        double v[8];
                        Vec3d p[8];
                        corners(i, j, k, v, p);
                        uint64_t w = mCellBegin[c];
                        cellTriangles(v, p, mOpt.iso, mOpt.insideBelow, [&](const Tri& t) { mTris[w++] = t; });
                    }
        });
        stats.surfaceCells = cells;
        stats.triangles = total;
    }

    const TriVector& triangles() const { return mTris; }

    /// Exact closest point of the surface to voxel (i, j, k): first the 8 cells that share the
    /// sample as a corner (they hold every point closer than the smallest spacing), then cells
    /// in growing windows whose half-width per axis follows a world radius (so anisotropic
    /// spacing costs nothing extra), each cell skipped when its box is no closer than the best
    /// point so far, until no cell outside the window can hold a closer point. `seed` (a triangle
    /// index, or kNoSeed) is evaluated first, and receives the closest triangle: the previous
    /// sample of a row gives a tight first bound, and a triangle whose box is no closer than the
    /// best point is skipped (exact: the box distance is a lower bound; ties keep the first).
    static constexpr uint64_t kNoSeed = ~uint64_t(0);
    bool closestPoint(int i, int j, int k, Vec3d& q, double& d2, uint64_t& seed) const
    {
        const Vec3d p = mF.worldPosition(i, j, k);
        const double hmin = std::min({mF.spacing[0], mF.spacing[1], mF.spacing[2]});
        const int c[3] = {i, j, k};
        d2 = std::numeric_limits<double>::infinity();
        // squared world gap between the sample and cell index ci along axis a (cell ci spans
        // samples ci..ci+1)
        auto gap2 = [&](int a, int ci) {
            const int g = ci >= c[a] ? ci - c[a] : c[a] - ci - 1;
            const double w = double(g) * mF.spacing[a];
            return w * w;
        };
        uint64_t bestT = kNoSeed;
        if (seed != kNoSeed) {
            d2 = triDistance2(p, mTris[seed], q);
            bestT = seed;
        }
        auto searchCell = [&](int ci, int cj, int ck) {
            const size_t cell = cellIndex(ci, cj, ck);
            for (uint64_t t = mCellBegin[cell]; t < mCellBegin[cell + 1]; ++t) {
                if (t == seed) continue;
                const Tri& tri = mTris[t];
                if (iso_surface_internal::triBoxDistance2(p, tri) >= d2) continue; // no point of it is closer
                Vec3d cp;
                const double e2 = triDistance2(p, tri, cp);
                if (e2 < d2) { d2 = e2; q = cp; bestT = t; }
            }
        };
        // the 8 cells around the sample
        for (int ck = std::max(0, k - 1); ck < std::min(mCellDims[2], k + 1); ++ck)
            for (int cj = std::max(0, j - 1); cj < std::min(mCellDims[1], j + 1); ++cj)
                for (int ci = std::max(0, i - 1); ci < std::min(mCellDims[0], i + 1); ++ci) searchCell(ci, cj, ck);
        if (d2 <= hmin * hmin) { seed = bestT; return true; } // every closer point would lie in those 8 cells
        int prev[3] = {1, 1, 1}; // half-widths of the window already searched
        for (double radius = 2.0 * hmin;; radius *= 1.5) {
            int hw[3];
            bool covers = true;
            for (int a = 0; a < 3; ++a) {
                hw[a] = std::max(2, int(std::ceil(radius / mF.spacing[a])));
                covers = covers && c[a] - hw[a] <= 0 && c[a] + hw[a] >= mCellDims[a];
            }
            const int lo[3] = {std::max(0, c[0] - hw[0]), std::max(0, c[1] - hw[1]), std::max(0, c[2] - hw[2])};
            const int hi[3] = {std::min(mCellDims[0], c[0] + hw[0]), std::min(mCellDims[1], c[1] + hw[1]),
                               std::min(mCellDims[2], c[2] + hw[2])};
            for (int ck = lo[2]; ck < hi[2]; ++ck) {
                const double gz = gap2(2, ck);
                if (gz >= d2) continue;
                for (int cj = lo[1]; cj < hi[1]; ++cj) {
                    const double gyz = gz + gap2(1, cj);
                    if (gyz >= d2) continue;
                    for (int ci = lo[0]; ci < hi[0]; ++ci) {
                        if (ci >= i - prev[0] && ci < i + prev[0] && cj >= j - prev[1] && cj < j + prev[1] &&
                            ck >= k - prev[2] && ck < k + prev[2])
                            continue; // searched in an earlier window
                        if (gyz + gap2(0, ci) >= d2) continue; // no closer point in this cell
                        searchCell(ci, cj, ck);
                    }
                }
            }
            for (int a = 0; a < 3; ++a) prev[a] = hw[a];
            // a cell outside the window [c-hw, c+hw) on axis a is at least hw[a] samples away
            double reach = std::numeric_limits<double>::infinity();
            for (int a = 0; a < 3; ++a) reach = std::min(reach, double(hw[a]) * mF.spacing[a]);
            if (d2 <= reach * reach || covers) break;
        }
        seed = bestT;
        return std::isfinite(d2);
    }

private:
    size_t cellIndex(int i, int j, int k) const
    {
        return (size_t(k) * size_t(mCellDims.y()) + size_t(j)) * size_t(mCellDims.x()) + size_t(i);
    }
    bool mixed(int i, int j, int k) const
    {
        bool any = false, all = true;
        for (int c = 0; c < 8; ++c) {
            const bool in = mInside(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)) != 0;
            any = any || in;
            all = all && in;
        }
        return any && !all;
    }
    void corners(int i, int j, int k, double v[8], Vec3d p[8]) const
    {
        for (int c = 0; c < 8; ++c) {
            const int x = i + (c & 1), y = j + ((c >> 1) & 1), z = k + ((c >> 2) & 1);
            v[c] = mF(x, y, z);
            p[c] = mF.worldPosition(x, y, z);
        }
    }

    const ScalarVolume& mF;
    SubvoxelShellOptions mOpt;
    MaskVolume mInside;
    openvdb::Coord mCellDims{0, 0, 0};
    std::vector<uint64_t> mCellBegin;
    TriVector mTris;
};

} // namespace

MaskVolume insideFlags(const ScalarVolume& field, const SubvoxelShellOptions& options)
{
    requireValidVolume(field, "inside flags");
    MaskVolume m(field.dims, 0, field.spacing, field.origin);
    const float iso = options.iso;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, field.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i)
            m.data[i] = options.insideBelow ? uint8_t(field.data[i] <= iso) : uint8_t(field.data[i] >= iso);
    });
    return m;
}

TriangleMesh isoSurfaceTriangles(const ScalarVolume& field, const SubvoxelShellOptions& options)
{
    checkVolume(field);
    Shell shell(field, options);
    SubvoxelShellStats st;
    shell.buildSurface(st);
    TriangleMesh mesh;
    mesh.source = "iso-surface";
    mesh.points.reserve(3 * shell.triangles().size());
    mesh.triangles.reserve(shell.triangles().size());
    for (const Tri& t : shell.triangles()) {
        const uint32_t b = uint32_t(mesh.points.size());
        mesh.points.push_back(t.a);
        mesh.points.push_back(t.b);
        mesh.points.push_back(t.c);
        mesh.triangles.emplace_back(b, b + 1, b + 2);
    }
    return mesh;
}

namespace {

/// out(v) = 1 where m is non-zero at v or at one of its 26 neighbours inside the volume: three
/// separable passes (x, y, z), each parallel over z-slabs; 3 reads per voxel and pass instead of 27.
MaskVolume dilate26(const MaskVolume& m)
{
    const int nx = m.dims.x(), ny = m.dims.y(), nz = m.dims.z();
    MaskVolume a(m.dims, 0, m.spacing, m.origin), b(m.dims, 0, m.spacing, m.origin);
    auto pass = [&](const MaskVolume& src, MaskVolume& dst, int axis) {
        const int n = m.dims[axis];
        const size_t stride = axis == 0 ? 1 : axis == 1 ? size_t(nx) : size_t(nx) * size_t(ny);
        tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int>& r) {
            for (int k = r.begin(); k != r.end(); ++k)
                for (int j = 0; j < ny; ++j)
                    for (int i = 0; i < nx; ++i) {
                        const size_t v = src.index(i, j, k);
                        const int c = axis == 0 ? i : axis == 1 ? j : k;
                        uint8_t x = src.data[v];
                        if (c > 0) x |= src.data[v - stride];
                        if (c + 1 < n) x |= src.data[v + stride];
                        dst.data[v] = x;
                    }
        });
    };
    pass(m, a, 0);
    pass(a, b, 1);
    pass(b, a, 2);
    return a;
}

} // namespace

VectorVolume subvoxelShell(const ScalarVolume& field, const SubvoxelShellOptions& options,
                           SubvoxelShellStats* statsOut)
{
    const auto t0 = Clock::now();
    checkVolume(field);
    SubvoxelShellStats stats;
    Shell shell(field, options);
    shell.buildSurface(stats);
    if (options.interrupter && options.interrupter->wasInterrupted(30))
        throw InterruptedError("interrupted while building the sub-voxel shell");

    const MaskVolume& in = shell.inside();
    const int nx = field.dims.x(), ny = field.dims.y(), nz = field.dims.z();
    // R: inside voxels with an outside 26-neighbour (transverse), and their 26-neighbours, by
    // separable 3×3×3 dilations (neighbours beyond the volume do not count)
    MaskVolume outside(field.dims, 0, field.spacing, field.origin);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, in.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t v = r.begin(); v != r.end(); ++v) outside.data[v] = in.data[v] ? 0 : 1;
    });
    MaskVolume transverse = dilate26(outside);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, in.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t v = r.begin(); v != r.end(); ++v) transverse.data[v] = transverse.data[v] & in.data[v];
    });
    outside = MaskVolume();
    const MaskVolume region = dilate26(transverse);
    transverse = MaskVolume();
    const float inf = std::numeric_limits<float>::infinity();
    VectorVolume out(field.dims, ClosestVector{inf, inf, inf, inf}, field.spacing, field.origin);
    std::atomic<uint64_t> shellCount{0}, insideCount{0};
    std::atomic<bool> stop{false};
    tbb::parallel_for(tbb::blocked_range<int>(0, nz), [&](const tbb::blocked_range<int>& r) {
        uint64_t ns = 0, ni = 0;
        for (int k = r.begin(); k != r.end() && !stop; ++k) {
            for (int j = 0; j < ny; ++j) {
                uint64_t seed = Shell::kNoSeed; // per row: the same for any thread count
                for (int i = 0; i < nx; ++i) {
                    ni += in(i, j, k) ? 1 : 0;
                    if (!region(i, j, k)) continue;
                    Vec3d q;
                    double d2;
                    if (!shell.closestPoint(i, j, k, q, d2, seed)) continue;
                    const Vec3d v = q - field.worldPosition(i, j, k);
                    out(i, j, k) = ClosestVector{float(v[0] / field.spacing[0]), float(v[1] / field.spacing[1]),
                                                 float(v[2] / field.spacing[2]), float(d2)};
                    ++ns;
                }
            }
            if (options.interrupter && options.interrupter->wasInterrupted(-1)) stop = true;
        }
        shellCount += ns;
        insideCount += ni;
    });
    if (stop) throw InterruptedError("interrupted while computing the sub-voxel shell");
    stats.shellVoxels = shellCount;
    stats.insideVoxels = insideCount;
    stats.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = stats;
    return out;
}

} // namespace levelforge
