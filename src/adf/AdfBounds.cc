// SPDX-License-Identifier: Apache-2.0
// The stated bound of the ADF (see AdaptiveDistanceField.h, "error"): the reconstruction checked
// against the level's sample function at Frisken's test points and corners of every cell, plus
// the sample function's own bound and a Lipschitz term for the points between (Frisken, Perry,
// Rockwood, Jones, "Adaptively Sampled Distance Fields", SIGGRAPH 2000).
#include "adf/AdfLeafSearch.h"
#include "adf/AdfMeshProvider.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace levelforge {
namespace adf_internal {

/// Reference value of the sample function at a point of a leaf cell, world, with its own
/// bound (world).
inline double MeshProvider::leafReference(const Vec3d& q, const Coord& o, MeshScratch& s, double& fBound) const
{
    Coord base(int(std::floor(q[0])), int(std::floor(q[1])), int(std::floor(q[2])));
    for (int k = 0; k < 3; ++k) base[k] = std::min(base[k], o[k] + 7);
    const Coord local = base - o + Coord(kGather);
    const Nearest nb = nearest(q, local, mReal, s);
    if (nb.tri == kNone) {
        fBound = std::sqrt(3.0) / 2 * mH;
        return estimate(q, base, s.hint);
    }
    double cert = 0;
    const double v = certified(nb, q, s, cert);
    fBound = cert * mH;
    return v;
}

namespace {

/// Frisken's 19 test points of a cell (centre, face centres, edge midpoints) and its 8
/// corners, index space; `isCorner` tells which.
template<typename F>
void forTestPoints(const CellInfo& X, F&& f)
{
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b)
            for (int c = 0; c < 3; ++c)
                f(Vec3d(X.origin.x() + 0.5 * a * X.size, X.origin.y() + 0.5 * b * X.size, X.origin.z() + 0.5 * c * X.size),
                  a != 1 && b != 1 && c != 1);
}

/// Bound of |∇rec| in a cell (world units per world unit): each component of the gradient of a
/// trilinear function is bilinear in the other two coordinates, so its extreme values are
/// taken on the 4 cell edges along that axis.
double gradientBound(Reconstruction& rec, const CellInfo& X, double h)
{
    double v[8];
    for (int k = 0; k < 8; ++k)
        v[k] = rec.value(X.origin + Coord(((k >> 2) & 1) * X.size, ((k >> 1) & 1) * X.size, (k & 1) * X.size));
    double g2 = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const int bit = 4 >> axis;
        double m = 0;
        for (int k = 0; k < 8; ++k)
            if (!(k & bit)) m = std::max(m, std::abs(v[k | bit] - v[k]));
        g2 += (m / (X.size * h)) * (m / (X.size * h));
    }
    return std::sqrt(g2);
}

struct BoundAcc
{
    std::array<double, kAdfLevels> dev{{-1, -1, -1, -1, -1}};   // Frisken: test points only
    std::array<double, kAdfLevels> bound{{-1, -1, -1, -1, -1}}; // everywhere in the cell
    std::vector<std::pair<int, Coord>> failing; // (level, cell origin) over tolerance
    void add(int level, double testDev, double cellBound)
    {
        dev[size_t(level)] = std::max(dev[size_t(level)], testDev);
        bound[size_t(level)] = std::max(bound[size_t(level)], cellBound);
    }
};

} // namespace

Bounds checkBounds(const FloatTree& tree, const Layout& layout, MeshProvider& mp, bool leafCells, int unitStride,
                   double tolWorld, std::vector<std::pair<int, Coord>>* failing,
                   openvdb::util::NullInterrupter* interrupter)
{
    const CoordBBox dom = layout.domain;
    const double h = mp.mH, e3 = std::sqrt(3.0) / 2 * h;
    tbb::enumerable_thread_specific<BoundAcc> accs;
    std::atomic<bool> stop{false};
    auto poll = [&] {
        if (interrupter && !stop.load(std::memory_order_relaxed) && interrupter->wasInterrupted()) stop = true;
    };
    auto throwIfStopped = [&] {
        if (stop.load()) throw InterruptedError("interrupted while checking the ADF's error bounds");
    };
    // tile cells
    std::vector<CellInfo> tileCells;
    for (const Coord& b : layout.subdividedL2) {
        const Internal1* n1 = tree.root().template probeConstNode<Internal1>(b);
        if (!n1 || !inDomainCell(dom, b)) continue;
        for (openvdb::Index n = 0; n < Internal1::NUM_VALUES; ++n)
            if (!n1->isChildMaskOn(n)) tileCells.push_back({8, n1->offsetToGlobalCoord(n)});
    }
    for (const Coord& b : layout.tileL2)
        if (inDomainCell(dom, b)) tileCells.push_back({128, b});
    tbb::parallel_for(tbb::blocked_range<size_t>(0, tileCells.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        if (stop.load(std::memory_order_relaxed)) return;
        Reconstruction rec(tree, dom);
        BoundAcc& acc = accs.local();
        MeshScratch& s = mp.mScratch.local();
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const CellInfo X = tileCells[i];
            double worst = 0, worstTest = 0;
            forTestPoints(X, [&](const Vec3d& q, bool corner) {
                const double f = mp.estimate(q, X.origin, s.hint);
                const double dev = std::abs(rec.distanceIndex(q, nullptr, nullptr) - f);
                worst = std::max(worst, dev);
                if (!corner) worstTest = std::max(worstTest, dev);
            });
            const double lip = (1.0 + gradientBound(rec, X, h)) * std::sqrt(3.0) / 4 * X.size * h;
            acc.add(levelOfSize(X.size), worstTest + e3, worst + e3 + lip);
            if (tolWorld > 0 && worstTest > tolWorld) acc.failing.push_back({levelOfSize(X.size), X.origin});
        }
        poll();
    });
    throwIfStopped();
    if (leafCells) {
        const size_t nLeaves = layout.leafOrigins.size();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nLeaves, 4), [&](const tbb::blocked_range<size_t>& r) {
            if (stop.load(std::memory_order_relaxed)) return;
            Reconstruction rec(tree, dom);
            BoundAcc& acc = accs.local();
            MeshScratch& s = mp.mScratch.local();
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const Coord o = layout.leafOrigins[i];
                mp.gather(o, s, false);
                int unitCounter = 0;
                for (int x = 0; x < 8; ++x)
                    for (int y = 0; y < 8; ++y)
                        for (int z = 0; z < 8; ++z) {
                            const Coord c = o + Coord(x, y, z);
                            const CellInfo X = rec.cellAt(c);
                            if (X.origin != c) continue; // visit each cell once, at its origin
                            if (X.size == 1 && (unitCounter++ % unitStride) != 0) continue;
                            double worst = 0, worstTest = 0;
                            forTestPoints(X, [&](const Vec3d& q, bool corner) {
                                double fb = 0;
                                const double f = mp.leafReference(q, o, s, fb);
                                const double dev = std::abs(rec.distanceIndex(q, nullptr, nullptr) - f) + fb;
                                worst = std::max(worst, dev);
                                if (!corner) worstTest = std::max(worstTest, dev);
                            });
                            const double lip = (1.0 + gradientBound(rec, X, h)) * std::sqrt(3.0) / 4 * X.size * h;
                            acc.add(levelOfSize(X.size), worstTest, worst + lip);
                        }
            }
            poll();
        });
        throwIfStopped();
    }
    Bounds out;
    out.testPoints.fill(-1);
    out.cells.fill(-1);
    for (const BoundAcc& a : accs) {
        for (int l = 0; l < kAdfLevels; ++l) {
            out.testPoints[size_t(l)] = std::max(out.testPoints[size_t(l)], a.dev[size_t(l)]);
            out.cells[size_t(l)] = std::max(out.cells[size_t(l)], a.bound[size_t(l)]);
        }
        if (failing) failing->insert(failing->end(), a.failing.begin(), a.failing.end());
    }
    for (int l = 0; l < kAdfLevels; ++l) {
        if (out.testPoints[size_t(l)] >= 0) out.testPoints[size_t(l)] /= h;
        if (out.cells[size_t(l)] >= 0) out.cells[size_t(l)] /= h;
    }
    if (failing) std::sort(failing->begin(), failing->end());
    return out;
}

} // namespace adf_internal
} // namespace levelforge
