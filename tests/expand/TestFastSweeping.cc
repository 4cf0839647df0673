// SPDX-License-Identifier: Apache-2.0
// expandLevelSet (fast sweeping on sparse topology): analytic planes and spheres, the exact
// reference (first-order error bound, coverage, signs), |∇φ| ≈ 1, frozen band, thread-count
// determinism, the convergence report, domains (fill interior, bounding box, world units) and
// bad input.
#include "TestUtil.h"

#include <levelforge/reference/ExactReference.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include "expand/FastSweeping.h" // dilationPattern (white-box)
#include <levelforge/io/MeshIO.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/global_control.h>

#include <atomic>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

using namespace levelforge;

namespace {

openvdb::FloatGrid::Ptr exactBand(const TriangleMesh& mesh, int voxelCount, float w = 3.0f)
{
    MeshToLevelSetOptions opt;
    opt.voxelCount = voxelCount;
    opt.exteriorWidth = opt.interiorWidth = w;
    return meshToLevelSet(mesh, opt);
}

/// Fraction of voxels with |φ| in [lo, hi] voxels whose |∇φ| is within tol of 1. `godunov`: the
/// first-order upwind (Godunov) norm of OpenVDB's CheckNormGrad (ISGradientNormSqrd<FIRST_BIAS>);
/// otherwise central differences.
double normGradOk(const openvdb::FloatGrid& g, double lo, double hi, double tol, bool godunov,
                  uint64_t& n)
{
    auto acc = g.getConstAccessor();
    const double h = g.voxelSize()[0];
    uint64_t ok = 0;
    n = 0;
    for (auto it = g.cbeginValueOn(); it; ++it) {
        const double a = std::abs(*it) / h;
        if (a < lo || a > hi) continue;
        const openvdb::Coord c = it.getCoord();
        const double v = *it;
        double g2 = 0;
        bool all = true;
        for (int k = 0; k < 3; ++k) {
            openvdb::Coord p = c, m = c;
            p[k] += 1;
            m[k] -= 1;
            all = all && acc.isValueOn(p) && acc.isValueOn(m);
            const double vp = acc.getValue(p), vm = acc.getValue(m);
            if (godunov) {
                const double dm = (v - vm) / h, dp = (vp - v) / h;
                g2 += v > 0 ? std::max(std::pow(std::max(dm, 0.0), 2), std::pow(std::min(dp, 0.0), 2))
                            : std::max(std::pow(std::min(dm, 0.0), 2), std::pow(std::max(dp, 0.0), 2));
            } else {
                const double d = (vp - vm) / (2 * h);
                g2 += d * d;
            }
        }
        if (!all) continue;
        ++n;
        if (std::abs(std::sqrt(g2) - 1.0) <= tol) ++ok;
    }
    return n ? double(ok) / double(n) : 0.0;
}

} // namespace

TEST(FastSweeping, DilationPatternContainsTheEuclideanBall)
{
    for (double r : {0.5, 1.0, 1.8, 4.7, 10.0, 17.3, 33.9}) {
        int a = 0, b = 0;
        fast_sweeping_internal::dilationPattern(r, a, b);
        EXPECT_LE(a + b, int(std::ceil(r)) + 1) << r;
        const int n = int(std::ceil(r));
        for (int x = -n; x <= n; ++x)
            for (int y = -n; y <= n; ++y)
                for (int z = -n; z <= n; ++z) {
                    if (double(x) * x + double(y) * y + double(z) * z >= r * r) continue;
                    const int need = std::max(std::abs(x) - a, 0) + std::max(std::abs(y) - a, 0) +
                                     std::max(std::abs(z) - a, 0);
                    ASSERT_LE(need, b) << "radius " << r << " point " << x << "," << y << "," << z;
                }
    }
}

TEST(FastSweeping, TiltedPlaneIsReproduced)
{
    // Analytic band of a tilted plane, |x|,|y| <= 48 voxels; expand 3 -> 12 voxels.
    const double h = 0.1;
    const openvdb::Vec3d n = openvdb::Vec3d(0.3, -0.5, 0.81).unit();
    auto grid = openvdb::FloatGrid::create(float(3 * h));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(h));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    auto acc = grid->getAccessor();
    auto phi = [&](const openvdb::Coord& c) { return h * (n.dot(c.asVec3d()) + 0.37); };
    for (int x = -48; x <= 48; ++x)
        for (int y = -48; y <= 48; ++y)
            for (int z = -60; z <= 60; ++z) {
                const openvdb::Coord c(x, y, z);
                if (std::abs(phi(c)) < 3 * h) acc.setValue(c, float(phi(c)));
            }
    openvdb::tools::signedFloodFill(grid->tree());
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = opt.interiorWidth = 12;
    ExpandLevelSetStats st;
    auto out = expandLevelSet(*grid, opt, &st);
    EXPECT_TRUE(st.converged);
    EXPECT_GT(st.candidateVoxels, st.frozenVoxels);
    uint64_t checked = 0;
    double maxErr = 0;
    for (auto it = out->cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        if (std::abs(c.x()) > 24 || std::abs(c.y()) > 24) continue; // away from the band's edges
        ++checked;
        maxErr = std::max(maxErr, std::abs(*it - phi(c)) / h);
    }
    EXPECT_GT(checked, 50000u);
    EXPECT_LT(maxErr, 1e-3);
    // coverage: every voxel in the window within 12 voxels is active
    auto oacc = out->getConstAccessor();
    for (int x = -24; x <= 24; ++x)
        for (int y = -24; y <= 24; ++y)
            for (int z = -60; z <= 60; ++z) {
                const openvdb::Coord c(x, y, z);
                if (std::abs(phi(c)) < 12 * h) ASSERT_TRUE(oacc.isValueOn(c)) << c;
            }
}

TEST(FastSweeping, ConvergenceIsReported)
{
    // Converged: every change above the tolerance was passed on, so the reported final change
    // (the largest one not passed on) is at most the tolerance. With one pass per leaf allowed
    // the sweeps stop early: not converged, maxChange infinite, and since the updates only lower
    // values towards the fixed point, no value is below the converged one (minus the tolerance).
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 4);
    auto band = exactBand(sphere, 48);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = opt.interiorWidth = 15;
    ExpandLevelSetStats full;
    auto converged = expandLevelSet(*band, opt, &full);
    EXPECT_TRUE(full.converged);
    EXPECT_GE(full.iterations, 2);
    EXPECT_GE(full.maxChange, 0.0);
    EXPECT_LE(full.maxChange, opt.tolerance);
    EXPECT_GT(full.leafUpdates, 0u);
    EXPECT_GE(full.voxelUpdates, full.activeVoxels - full.frozenVoxels);

    opt.maxIterations = 1;
    ExpandLevelSetStats capped;
    auto partial = expandLevelSet(*band, opt, &capped);
    EXPECT_FALSE(capped.converged);
    EXPECT_EQ(capped.iterations, 1);
    EXPECT_TRUE(std::isinf(capped.maxChange));
    EXPECT_LT(capped.voxelUpdates, full.voxelUpdates);
    const double h = band->voxelSize()[0];
    auto facc = converged->getConstAccessor();
    uint64_t common = 0;
    for (auto it = partial->cbeginValueOn(); it; ++it) {
        if (!facc.isValueOn(it.getCoord())) continue;
        ++common;
        const float f = facc.getValue(it.getCoord());
        ASSERT_EQ(f < 0, *it < 0) << it.getCoord();
        ASSERT_GE(std::abs(*it), std::abs(f) - opt.tolerance * h) << it.getCoord();
    }
    EXPECT_GT(common, 100000u);
}

TEST(FastSweeping, SphereWithinFirstOrderBoundOfTheExactReference)
{
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 5);
    auto band = exactBand(sphere, 64);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = opt.interiorWidth = 12;
    ExpandLevelSetStats st;
    auto out = expandLevelSet(*band, opt, &st);
    EXPECT_TRUE(st.converged);
    EXPECT_LE(st.iterations, 6);
    ExactReference ref(sphere);
    const BandErrorReport r = compareToReference(*out, ref, 12, 12);
    std::cout << "[ sphere 64, 3->12 ] voxels " << r.checkedVoxels << " mean " << r.meanError
              << " max " << r.maxError << " iterations " << st.iterations << " extra "
              << r.extraVoxels << "\n";
    EXPECT_EQ(r.signErrors, 0u);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_LT(r.meanError, 0.1);
    EXPECT_LT(r.maxError, 0.5);
    // the analytic sphere too (the icosphere is within 0.1 voxel of it at this resolution)
    const double h = out->voxelSize()[0];
    double maxAnalytic = 0;
    for (auto it = out->cbeginValueOn(); it; ++it) {
        const double d = out->indexToWorld(it.getCoord()).length() - 1.0;
        maxAnalytic = std::max(maxAnalytic, std::abs(*it - d) / h);
    }
    EXPECT_LT(maxAnalytic, 0.6);
}

TEST(FastSweeping, FrozenBandIsKeptBitForBit)
{
    const TriangleMesh knot = makeTorusKnot();
    auto band = exactBand(knot, 80);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = 8;
    opt.interiorWidth = 4;
    auto out = expandLevelSet(*band, opt);
    auto acc = out->getConstAccessor();
    for (auto it = band->cbeginValueOn(); it; ++it) {
        ASSERT_TRUE(acc.isValueOn(it.getCoord()));
        ASSERT_EQ(acc.getValue(it.getCoord()), *it);
    }
    EXPECT_EQ(out->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_EQ(out->getName(), band->getName());
    EXPECT_GE(out->background(), float(9 * out->voxelSize()[0]));
}

TEST(FastSweeping, GradientMagnitudeIsOneAwayFromKinks)
{
    auto band = exactBand(makeIcosphere(Vec3d(0.0), 1.0, 6), 80);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = opt.interiorWidth = 15;
    auto out = expandLevelSet(*band, opt);
    uint64_t n = 0, nc = 0;
    // outside: characteristics diverge, no kinks; inside stop well before the centre (kink)
    const double frac = normGradOk(*out, 3.5, 13.0, 0.01, true, n);
    const double central = normGradOk(*out, 3.5, 13.0, 0.01, false, nc);
    const double central5 = normGradOk(*out, 3.5, 13.0, 0.05, false, nc);
    std::cout << "[ |grad| in [0.99, 1.01] ] Godunov (CheckNormGrad) " << frac
              << ", central differences " << central << " (within 5%: " << central5 << ") of "
              << n << " voxels\n";
    EXPECT_GT(n, 20000u);
    EXPECT_GT(frac, 0.999) << n;
    EXPECT_GT(central5, 0.99) << nc;
}

TEST(FastSweeping, MeshesAreCoveredWithCorrectSigns)
{
    const TriangleMesh knot = makeTorusKnot();
    const TriangleMesh box = makeBox(Vec3d(-0.93, -0.51, -0.37), Vec3d(0.71, 0.49, 0.83), 2);
    for (const TriangleMesh* mesh : {&knot, &box}) {
        auto band = exactBand(*mesh, 60);
        ExpandLevelSetOptions opt;
        opt.exteriorWidth = 10;
        opt.interiorWidth = 6;
        ExpandLevelSetStats st;
        auto out = expandLevelSet(*band, opt, &st);
        ExactReference ref(*mesh);
        const BandErrorReport r = compareToReference(*out, ref, 10, 6);
        std::cout << "[ mesh 60, 3->10/6 ] mean " << r.meanError << " max " << r.maxError
                  << " extra " << r.extraVoxels << " of " << r.checkedVoxels << "\n";
        EXPECT_EQ(r.signErrors, 0u);
        EXPECT_EQ(r.missingVoxels, 0u);
        EXPECT_LT(r.meanError, 0.15);
        EXPECT_LT(r.maxError, 1.0);
        EXPECT_TRUE(st.converged);
    }
}

TEST(FastSweeping, RealMeshesFromSharedDataAreCovered)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "meshes/watertight/spot.obj");
    const TriangleMesh mesh = readMesh(path);
    auto band = exactBand(mesh, 64);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = opt.interiorWidth = 12;
    auto out = expandLevelSet(*band, opt);
    ExactReference ref(mesh);
    const BandErrorReport r = compareToReference(*out, ref, 12, 12);
    std::cout << "[ spot 64, 3->12 ] mean " << r.meanError << " max " << r.maxError << "\n";
    EXPECT_EQ(r.signErrors, 0u);
    EXPECT_EQ(r.missingVoxels, 0u);
    EXPECT_LT(r.meanError, 0.2);
}

TEST(FastSweeping, IdenticalForAnyThreadCount)
{
    auto band = exactBand(makeTorusKnot(), 100);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = 12;
    opt.interiorWidth = 5;
    openvdb::FloatGrid::Ptr one, two;
    ExpandLevelSetStats s1, s2;
    {
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
        one = expandLevelSet(*band, opt, &s1);
    }
    {
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 2);
        two = expandLevelSet(*band, opt, &s2);
    }
    auto many = expandLevelSet(*band, opt);
    for (const auto& other : {two, many}) {
        ASSERT_EQ(one->activeVoxelCount(), other->activeVoxelCount());
        ASSERT_EQ(one->tree().leafCount(), other->tree().leafCount());
        auto acc = other->getConstAccessor();
        for (auto it = one->cbeginValueAll(); it; ++it) {
            ASSERT_EQ(acc.isValueOn(it.getCoord()), it.isValueOn()) << it.getCoord();
            ASSERT_EQ(acc.getValue(it.getCoord()), *it) << it.getCoord();
        }
    }
    EXPECT_EQ(s1.iterations, s2.iterations);
    EXPECT_EQ(s1.leafUpdates, s2.leafUpdates);
    EXPECT_EQ(s1.voxelUpdates, s2.voxelUpdates);
    EXPECT_EQ(s1.maxChange, s2.maxChange);
}

TEST(FastSweeping, SameFixedPointAsAPlainDenseGaussSeidel)
{
    // The dirty bits, the leaf skipping, the capped values and the leaf candidates change only
    // which updates are computed, not the solution: compare with every voxel of a dense box
    // updated (double precision) in the 8 orderings until nothing changes. Interior 4, exterior
    // 9 voxels (two caps).
    auto band = exactBand(makeTorusKnot(), 48);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = 9;
    opt.interiorWidth = 4;
    ExpandLevelSetStats st;
    auto out = expandLevelSet(*band, opt, &st);
    EXPECT_TRUE(st.converged);
    EXPECT_GT(st.voxelUpdates, 0u);
    const double h = band->voxelSize()[0];
    openvdb::CoordBBox box = band->evalActiveVoxelBoundingBox();
    box.expand(14);
    const openvdb::Coord dim = box.dim();
    const auto index = [&](int x, int y, int z) { return (size_t(x) * dim.y() + y) * dim.z() + z; };
    const double big = 1e30;
    std::vector<double> u(size_t(dim.x()) * dim.y() * dim.z());
    std::vector<char> fixed(u.size()), neg(u.size());
    auto bacc = band->getConstAccessor();
    for (int x = 0; x < dim.x(); ++x)
        for (int y = 0; y < dim.y(); ++y)
            for (int z = 0; z < dim.z(); ++z) {
                const openvdb::Coord c = box.min() + openvdb::Coord(x, y, z);
                const size_t i = index(x, y, z);
                const float v = bacc.getValue(c);
                neg[i] = v < 0;
                fixed[i] = bacc.isValueOn(c);
                u[i] = fixed[i] ? std::abs(double(v)) / h : big; // magnitudes, voxels
            }
    auto godunov = [](double a, double b, double c) {
        double s[3] = {a, b, c};
        std::sort(s, s + 3);
        double r = s[0] + 1;
        if (r <= s[1]) return r;
        r = 0.5 * (s[0] + s[1] + std::sqrt(2 - (s[1] - s[0]) * (s[1] - s[0])));
        if (r <= s[2]) return r;
        const double q = (s[0] - s[1]) * (s[0] - s[1]) + (s[0] - s[2]) * (s[0] - s[2]) +
                         (s[1] - s[2]) * (s[1] - s[2]);
        return (s[0] + s[1] + s[2] + std::sqrt(std::max(3 - q, 0.0))) / 3;
    };
    for (int round = 0; round < 100; ++round) {
        double change = 0;
        for (int o = 0; o < 8; ++o) {
            for (int xi = 1; xi < dim.x() - 1; ++xi)
                for (int yi = 1; yi < dim.y() - 1; ++yi)
                    for (int zi = 1; zi < dim.z() - 1; ++zi) {
                        const int x = (o & 1) ? dim.x() - 1 - xi : xi;
                        const int y = (o & 2) ? dim.y() - 1 - yi : yi;
                        const int z = (o & 4) ? dim.z() - 1 - zi : zi;
                        const size_t i = index(x, y, z);
                        if (fixed[i]) continue;
                        // neighbour magnitudes on this voxel's side (across the surface: 0)
                        auto m = [&](size_t j) { return neg[j] == neg[i] ? u[j] : (u[j] < big ? 0.0 : big); };
                        const double a = std::min(m(index(x - 1, y, z)), m(index(x + 1, y, z)));
                        const double b = std::min(m(index(x, y - 1, z)), m(index(x, y + 1, z)));
                        const double c = std::min(m(index(x, y, z - 1)), m(index(x, y, z + 1)));
                        if (std::min({a, b, c}) >= big) continue;
                        const double r = godunov(a, b, c);
                        if (r < u[i]) {
                            change = std::max(change, u[i] >= big ? big : u[i] - r);
                            u[i] = r;
                        }
                    }
        }
        if (change < 1e-9) break;
    }
    // every active output voxel away from the box walls: the same value; every voxel below the
    // target widths: active
    uint64_t compared = 0, newVoxels = 0;
    double maxDiff = 0;
    auto oacc = out->getConstAccessor();
    for (int x = 1; x < dim.x() - 1; ++x)
        for (int y = 1; y < dim.y() - 1; ++y)
            for (int z = 1; z < dim.z() - 1; ++z) {
                const openvdb::Coord c = box.min() + openvdb::Coord(x, y, z);
                const size_t i = index(x, y, z);
                const double ref = neg[i] ? -u[i] : u[i];
                const double w = neg[i] ? 4.0 : 9.0;
                if (std::abs(ref) < w) ASSERT_TRUE(oacc.isValueOn(c)) << c << " " << ref;
                if (!oacc.isValueOn(c)) continue;
                ++compared;
                if (!fixed[i]) ++newVoxels;
                maxDiff = std::max(maxDiff, std::abs(oacc.getValue(c) / h - ref));
            }
    EXPECT_GT(newVoxels, 50000u);
    EXPECT_EQ(compared, out->activeVoxelCount());
    EXPECT_LT(maxDiff, 1e-3); // float arithmetic and changes below the tolerance not passed on
}

TEST(FastSweeping, FillInteriorBoundingBoxAndWorldUnits)
{
    const TriangleMesh sphere = makeIcosphere(Vec3d(0.0), 1.0, 4);
    auto band = exactBand(sphere, 40);
    const double h = band->voxelSize()[0];
    {
        ExpandLevelSetOptions opt;
        opt.fillInterior = true;
        opt.exteriorWidth = 2;
        auto out = expandLevelSet(*band, opt);
        auto acc = out->getConstAccessor();
        // every voxel inside the sphere (and not on it) is active and negative
        const int n = int(1.0 / h) + 1;
        for (int x = -n; x <= n; ++x)
            for (int y = -n; y <= n; ++y)
                for (int z = -n; z <= n; ++z) {
                    const openvdb::Coord c(x, y, z);
                    if (out->indexToWorld(c).length() > 1.0 - 1.1 * h) continue;
                    ASSERT_TRUE(acc.isValueOn(c)) << c;
                    ASSERT_LT(acc.getValue(c), 0.0f) << c;
                }
        // the centre (a kink of the distance: the medial axis) is within 1.5 voxels of exact
        ExactReference ref(sphere);
        const double centre = ref.signedDistance(Vec3d(0.0));
        EXPECT_NEAR(acc.getValue(openvdb::Coord(0)), centre, 1.5 * h);
        EXPECT_GE(out->background(), std::abs(acc.getValue(openvdb::Coord(0))));
    }
    {
        ExpandLevelSetOptions opt;
        opt.domain = ExpansionDomain::BoundingBox;
        opt.boundingBoxMargin = 4;
        auto out = expandLevelSet(*band, opt);
        openvdb::CoordBBox box = band->evalActiveVoxelBoundingBox();
        box.expand(4);
        EXPECT_EQ(out->activeVoxelCount(), box.volume());
        auto acc = out->getConstAccessor();
        EXPECT_GT(acc.getValue(box.max()), 0.0f);
    }
    {
        ExpandLevelSetOptions a, b;
        a.exteriorWidth = a.interiorWidth = 7;
        b.units = WidthUnits::World;
        b.exteriorWidth = b.interiorWidth = 7 * h;
        auto ga = expandLevelSet(*band, a), gb = expandLevelSet(*band, b);
        EXPECT_EQ(ga->activeVoxelCount(), gb->activeVoxelCount());
    }
}

TEST(FastSweeping, NarrowerTargetTrimsTheBand)
{
    auto band = exactBand(makeTorusKnot(), 60, 5.0f);
    ExpandLevelSetOptions opt;
    opt.exteriorWidth = opt.interiorWidth = 2;
    opt.coverageMargin = 0;
    auto out = expandLevelSet(*band, opt);
    const float lim = float(2 * out->voxelSize()[0]);
    for (auto it = out->cbeginValueOn(); it; ++it) ASSERT_LT(std::abs(*it), lim);
    EXPECT_LT(out->activeVoxelCount(), band->activeVoxelCount());
}

TEST(FastSweeping, BadWidthsGiveClearErrors)
{
    auto band = exactBand(makeIcosphere(Vec3d(0.0), 1.0, 3), 30);
    auto expectThrow = [&](ExpandLevelSetOptions opt, bool resource, const char* what) {
        try {
            expandLevelSet(*band, opt);
            ADD_FAILURE() << what << ": no exception";
        } catch (const ResourceLimitError& e) {
            EXPECT_TRUE(resource) << what << ": " << e.what();
        } catch (const InvalidArgumentError& e) {
            EXPECT_FALSE(resource) << what << ": " << e.what();
            EXPECT_NE(std::string(e.what()).find("Width"), std::string::npos) << e.what();
        }
    };
    ExpandLevelSetOptions o;
    o.exteriorWidth = -1;
    expectThrow(o, false, "negative");
    o.exteriorWidth = std::numeric_limits<double>::quiet_NaN();
    expectThrow(o, false, "NaN");
    o.exteriorWidth = std::numeric_limits<double>::infinity();
    expectThrow(o, false, "inf");
    o = {};
    o.interiorWidth = 0;
    expectThrow(o, false, "zero");
    o = {};
    o.exteriorWidth = 1e9;
    expectThrow(o, true, "huge");
    o = {};
    o.exteriorWidth = 5000;
    o.maxVoxels = 1'000'000;
    expectThrow(o, true, "over the voxel limit");
    // empty and non-level-set inputs
    auto empty = openvdb::FloatGrid::create(0.3f);
    EXPECT_THROW(expandLevelSet(*empty), InvalidArgumentError);
    auto fog = band->deepCopy();
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    EXPECT_THROW(expandLevelSet(*fog), InvalidArgumentError);
}

TEST(FastSweeping, InterrupterStopsCleanly)
{
    struct StopAt : openvdb::util::NullInterrupter
    {
        std::atomic<int> calls{0}; // polled from TBB workers too
        bool wasInterrupted(int) override { return ++calls > 3; }
    } stop;
    auto band = exactBand(makeTorusKnot(), 60);
    ExpandLevelSetOptions opt;
    opt.interrupter = &stop;
    EXPECT_THROW(expandLevelSet(*band, opt), InterruptedError);
}

// ---------------------------------------------------------------- the `expand` operator (CLI)
#ifdef LEVELFORGE_CLI_PATH
#include <levelforge/io/VdbIO.h>

#include <filesystem>
#include <fstream>
#include <sys/wait.h>

namespace {

struct ExpandRun
{
    int code = -1;
    std::string err;
};

ExpandRun runCli(const std::filesystem::path& dir, const std::string& args)
{
    const std::string errFile = (dir / "stderr.txt").string();
    const std::string cmd = std::string("'") + LEVELFORGE_CLI_PATH + "' " + args + " >'" +
                            (dir / "stdout.txt").string() + "' 2>'" + errFile + "'";
    const int status = std::system(cmd.c_str());
    ExpandRun r;
    r.code = (status != -1 && WIFEXITED(status)) ? WEXITSTATUS(status) : -1;
    std::ifstream in(errFile);
    r.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return r;
}

openvdb::FloatGrid::Ptr readFirst(const std::string& path)
{
    return openvdb::gridPtrCast<openvdb::FloatGrid>((*readGrids(path))[0]);
}

} // namespace

TEST(ExpandCli, WidensALevelSetFile)
{
    const auto dir = levelforge_test::scratchDir("expand_cli");
    const std::string a = (dir / "a.vdb").string(), b = (dir / "b.vdb").string();
    ASSERT_EQ(runCli(dir, "mesh-to-sdf builtin:sphere '" + a + "' --voxel-count 40 --quiet").code, 0);
    const ExpandRun r = runCli(dir, "expand '" + a + "' '" + b +
                                        "' --exterior-width 8 --interior-width 6 --quiet");
    ASSERT_EQ(r.code, 0) << r.err;
    auto in = readFirst(a), out = readFirst(b);
    EXPECT_GT(out->activeVoxelCount(), 2 * in->activeVoxelCount());
    EXPECT_EQ(out->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_FLOAT_EQ(out->metaValue<float>("levelforge:exterior_band_voxels"), 8.0f);
    EXPECT_FLOAT_EQ(out->metaValue<float>("levelforge:interior_band_voxels"), 6.0f);
    EXPECT_EQ(out->metaValue<std::string>("levelforge:method"), "zhao2005-fast-sweeping");
}

TEST(ExpandCli, BadWidthsExitNonZeroWithOneLineAndNoOutput)
{
    const auto dir = levelforge_test::scratchDir("expand_cli_bad");
    const std::string a = (dir / "a.vdb").string(), b = (dir / "b.vdb").string();
    ASSERT_EQ(runCli(dir, "mesh-to-sdf builtin:sphere '" + a + "' --voxel-count 20 --quiet").code, 0);
    for (const char* bad : {"--exterior-width -1", "--exterior-width nan", "--interior-width 0",
                            "--exterior-width 1e9", "--fill-interior --interior-width 3"}) {
        const ExpandRun r = runCli(dir, "expand '" + a + "' '" + b + "' --quiet " + bad);
        EXPECT_EQ(r.code, 2) << bad << ": " << r.err;
        EXPECT_NE(r.err.find("levelforge: error: "), std::string::npos) << bad << ": " << r.err;
        EXPECT_FALSE(std::filesystem::exists(b)) << bad;
    }
    const ExpandRun missing = runCli(dir, "expand '" + (dir / "none.vdb").string() + "' '" + b + "'");
    EXPECT_EQ(missing.code, 1) << missing.err;
    EXPECT_FALSE(std::filesystem::exists(b));
}

TEST(ExpandCli, MeshToSdfWithSweepExpansion)
{
    const auto dir = levelforge_test::scratchDir("expand_cli_mesh");
    const std::string s = (dir / "s.vdb").string(), e = (dir / "e.vdb").string();
    ASSERT_EQ(runCli(dir, "mesh-to-sdf builtin:sphere '" + s +
                              "' --voxel-count 40 --exterior-band 10 --interior-band 6 "
                              "--expansion sweep --quiet").code, 0);
    ASSERT_EQ(runCli(dir, "mesh-to-sdf builtin:sphere '" + e +
                              "' --voxel-count 40 --exterior-band 10 --interior-band 6 "
                              "--expansion exact --quiet").code, 0);
    auto gs = readFirst(s), ge = readFirst(e);
    EXPECT_NE(gs->metaValue<std::string>("levelforge:method").find("zhao2005"), std::string::npos);
    EXPECT_FLOAT_EQ(gs->metaValue<float>("levelforge:exterior_band_voxels"), 10.0f);
    // the swept band covers the exact one and agrees with it to first order
    auto acc = gs->getConstAccessor();
    const double h = ge->voxelSize()[0];
    double maxErr = 0;
    for (auto it = ge->cbeginValueOn(); it; ++it) {
        ASSERT_TRUE(acc.isValueOn(it.getCoord())) << it.getCoord();
        maxErr = std::max(maxErr, std::abs(double(acc.getValue(it.getCoord())) - *it) / h);
    }
    EXPECT_LT(maxErr, 0.5);
}
#endif
