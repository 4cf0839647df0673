// SPDX-License-Identifier: Apache-2.0
// Sign modes of the exact band (issue 16): the fast winding number against the exact winding
// number of ExactReference, winding signs on open, broken, interpenetrating, inverted and
// double-walled meshes (generated, and the shared open/broken meshes when present), the
// unsigned distance against brute force, fill interior, thread-count determinism, bad input.
#include "TestUtil.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/mesh/FastWindingNumber.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/reference/MeshShapes.h>

#include <tbb/global_control.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

using namespace levelforge;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Appends `b` to `a` (vertices and triangles), optionally with every triangle flipped.
void append(TriangleMesh& a, const TriangleMesh& b, bool flip = false)
{
    const uint32_t base = uint32_t(a.points.size());
    a.points.insert(a.points.end(), b.points.begin(), b.points.end());
    for (const Vec3I& t : b.triangles)
        a.triangles.push_back(flip ? Vec3I(t[0] + base, t[2] + base, t[1] + base) : Vec3I(t[0] + base, t[1] + base, t[2] + base));
}

TriangleMesh flipped(const TriangleMesh& m)
{
    TriangleMesh f;
    append(f, m, true);
    f.source = m.source + " (inverted)";
    return f;
}

/// The unit icosphere without the triangles of its cap z > 0.7: a sphere with a hole.
TriangleMesh sphereWithHole(int subdivisions = 3)
{
    const TriangleMesh s = makeIcosphere(Vec3d(0.0), 1.0, subdivisions);
    TriangleMesh m;
    m.points = s.points;
    for (const Vec3I& t : s.triangles) {
        const Vec3d c = (s.points[t[0]] + s.points[t[1]] + s.points[t[2]]) / 3.0;
        if (c[2] <= 0.7) m.triangles.push_back(t);
    }
    m.source = "<sphere with a hole>";
    return m;
}

/// Two closed boxes that pass through each other.
TriangleMesh twoBoxes()
{
    TriangleMesh m;
    append(m, makeBox(Vec3d(-1.0, -0.5, -0.5), Vec3d(0.3, 0.5, 0.5), 3));
    append(m, makeBox(Vec3d(-0.3, -0.4, -0.7), Vec3d(1.0, 0.4, 0.35), 3));
    m.source = "<two interpenetrating boxes>";
    return m;
}

/// A double-walled hollow shell: a sphere of radius 1 and, inside it, an inverted sphere of
/// radius 0.6 (solid between the walls, w = 1; the cavity w = 0).
TriangleMesh hollowShell(int subdivisions = 3)
{
    TriangleMesh m;
    append(m, makeIcosphere(Vec3d(0.0), 1.0, subdivisions));
    append(m, makeIcosphere(Vec3d(0.0), 0.6, subdivisions), true);
    m.source = "<double-walled hollow shell>";
    return m;
}

/// A torus and, beside it, an inside-out box (w = −1 inside it).
TriangleMesh flippedPart()
{
    TriangleMesh m;
    append(m, makeTorus(Vec3d(-0.5, 0.0, 0.0), 0.6, 0.25, 48, 16));
    append(m, makeBox(Vec3d(0.3, -0.4, -0.4), Vec3d(1.1, 0.4, 0.4), 2), true);
    m.source = "<torus and an inverted box>";
    return m;
}

/// A single open sheet: a curved square patch (z = 0.3 (x² − y²)), 20 × 20 quads.
TriangleMesh openSheet()
{
    TriangleMesh m;
    const int n = 20;
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j) {
            const double x = -1.0 + 2.0 * i / n, y = -1.0 + 2.0 * j / n;
            m.points.emplace_back(x, y, 0.3 * (x * x - y * y));
        }
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const uint32_t a = uint32_t(i * (n + 1) + j), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
            m.triangles.emplace_back(a, c, d);
            m.triangles.emplace_back(a, d, b);
        }
    m.source = "<open sheet>";
    return m;
}

struct Case
{
    std::string name;
    TriangleMesh mesh;
};

std::vector<Case> brokenCases()
{
    return {{"sphere with a hole", sphereWithHole()},
            {"two interpenetrating boxes", twoBoxes()},
            {"double-walled hollow shell", hollowShell()},
            {"torus and an inverted box", flippedPart()},
            {"open sheet", openSheet()}};
}

MeshToLevelSetOptions options(SignMode sign, int voxels)
{
    MeshToLevelSetOptions o;
    o.voxelCount = voxels;
    o.sign = sign;
    return o;
}

/// Every active voxel of the band (|φ| below the background; a filled interior holds
/// −background) holds the exact unsigned distance (1e-4 voxel).
void expectExactMagnitudes(const openvdb::FloatGrid& grid, const ExactReference& ref, const std::string& what)
{
    const double h = grid.voxelSize()[0];
    double worst = 0.0;
    uint64_t n = 0;
    for (auto it = grid.tree().cbeginValueOn(); it; ++it) {
        if (!(std::abs(*it) < grid.background())) continue;
        const double d = std::abs(ref.query(grid.indexToWorld(it.getCoord())).distance);
        worst = std::max(worst, std::abs(std::abs(double(*it)) - d) / h);
        ++n;
    }
    EXPECT_GT(n, 0u) << what;
    EXPECT_LE(worst, 1e-4) << what;
}

/// The stride of compareSignsToWindingNumber() that samples about `samples` voxels (active ones,
/// or with `inactive` every voxel of the leaves).
uint64_t strideFor(const openvdb::FloatGrid& grid, uint64_t samples, bool inactive)
{
    const uint64_t n = inactive ? grid.tree().leafCount() * 512 + grid.tree().nonLeafCount() * 4096 : grid.activeVoxelCount();
    return std::max<uint64_t>(1, n / samples);
}

/// Same tree: topology, every value (voxels and tiles) and active state.
void expectSameTree(const openvdb::FloatTree& a, const openvdb::FloatTree& b, const std::string& what)
{
    EXPECT_TRUE(a.hasSameTopology(b)) << what;
    EXPECT_EQ(a.activeVoxelCount(), b.activeVoxelCount()) << what;
    uint64_t differ = 0;
    openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(b);
    for (auto it = a.cbeginValueAll(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        if (acc.getValue(c) != *it || acc.isValueOn(c) != it.isValueOn()) ++differ;
    }
    EXPECT_EQ(differ, 0u) << what;
}

} // namespace

// ------------------------------------------------------------------ the fast winding number

TEST(FastWindingNumber, SolidAngleConventions)
{
    // counter-clockwise seen from +z: its normal points to +z; a point below sees it positive
    const Vec3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
    EXPECT_GT(triangleSolidAngle(a, b, c, Vec3d(0.2, 0.2, -0.1)), 0.0);
    EXPECT_LT(triangleSolidAngle(a, b, c, Vec3d(0.2, 0.2, 0.1)), 0.0);
    EXPECT_EQ(triangleSolidAngle(a, b, c, Vec3d(0.2, 0.2, 0.0)), 0.0); // on the triangle: principal value
    EXPECT_EQ(triangleSolidAngle(a, b, c, Vec3d(3.0, 2.0, 0.0)), 0.0); // in its plane
    // just below the middle: almost a hemisphere
    EXPECT_NEAR(triangleSolidAngle(a, b, c, Vec3d(0.25, 0.25, -1e-9)), 2.0 * kPi, 1e-6);
}

TEST(FastWindingNumber, ClosedMeshIsOneInsideZeroOutsideAndInvertedMinusOne)
{
    const TriangleMesh knot = makeTorusKnot();
    const FastWindingNumber fwn(knot);
    const ExactReference ref(knot);
    EXPECT_EQ(fwn.currentEdges(), 0u);
    EXPECT_EQ(fwn.triangles(), knot.triangles.size());
    const Vec3d on = torusKnotPoint(2, 3, 1.0, 0.7);
    EXPECT_NEAR(fwn(on), 1.0, 1e-2);
    EXPECT_NEAR(ref.windingNumber(on), 1.0, 1e-12);
    EXPECT_NEAR(fwn(Vec3d(0.0, 0.0, 3.0)), 0.0, 1e-2);
    EXPECT_NEAR(ref.windingNumber(Vec3d(0.0, 0.0, 0.0)), 0.0, 1e-12);
    const FastWindingNumber inv(flipped(knot));
    EXPECT_NEAR(inv(on), -1.0, 1e-2);
    // the gradient of a closed mesh's winding number is zero, and so are its bounds
    EXPECT_EQ(fwn.gradient(Vec3d(0.1, 0.2, 0.3)).length(), 0.0);
    EXPECT_EQ(fwn.gradientBound(Vec3d(-2.0), Vec3d(2.0)), 0.0);
    EXPECT_EQ(fwn.hessianBound(Vec3d(-2.0), Vec3d(2.0)), 0.0);
}

TEST(FastWindingNumber, MatchesTheExactWindingNumberWithinItsBound)
{
    // random points in the box and near the surface of closed, open and soup meshes: the
    // estimate is within its rigorous truncation bound of the exact value, and within the
    // accuracy documented for the defaults (beta 2, order 3)
    std::vector<Case> cases = brokenCases();
    cases.push_back({"torus knot", makeTorusKnot()});
    cases.push_back({"triangle soup",
                     makeRandomTriangles(300, 7, BBoxd(Vec3d(-1.0), Vec3d(1.0)), 0.4)});
    double worstDefault = 0.0;
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const ExactReference ref(c.mesh);
        std::mt19937_64 rng(11);
        const BBoxd b = c.mesh.bounds();
        std::vector<Vec3d> pts;
        for (int i = 0; i < 300; ++i) {
            Vec3d p;
            for (int k = 0; k < 3; ++k)
                p[k] = std::uniform_real_distribution<double>(b.min()[k] - 0.2, b.max()[k] + 0.2)(rng);
            pts.push_back(p);
            const Vec3I& t = c.mesh.triangles[rng() % c.mesh.triangles.size()];
            std::normal_distribution<double> g(0.0, 0.01);
            pts.push_back(c.mesh.points[t[0]] + Vec3d(g(rng), g(rng), g(rng)));
        }
        std::vector<double> exactW(pts.size());
        for (size_t i = 0; i < pts.size(); ++i) exactW[i] = ref.windingNumber(pts[i]);
        for (int order = 1; order <= 3; ++order)
            for (double beta : {1.5, 2.0, 4.0}) {
                FastWindingNumberOptions o;
                o.order = order;
                o.accuracy = beta;
                const FastWindingNumber fwn(c.mesh, o);
                for (size_t i = 0; i < pts.size(); ++i) {
                    const Vec3d& p = pts[i];
                    const FastWindingNumber::Estimate e = fwn.evaluate(p);
                    const double exact = exactW[i];
                    if (order == 1 && beta == 1.5 && i % 10 == 0) EXPECT_NEAR(fwn.exact(p), exact, 1e-12);
                    EXPECT_LE(std::abs(e.value - exact), e.errorBound + 1e-12) << "order " << order << " beta " << beta;
                    EXPECT_EQ(fwn(p), e.value);
                    if (order == 3 && beta == 2.0) worstDefault = std::max(worstDefault, std::abs(e.value - exact));
                }
            }
    }
    EXPECT_LE(worstDefault, 1e-2); // the accuracy FastWindingNumber.h and docs/algorithm.md state
    std::printf("fast winding number, defaults: max |error| %.3g on %zu meshes\n", worstDefault, cases.size());
}

TEST(FastWindingNumber, GradientIsTheBiotSavartFieldAndItsBoundsHold)
{
    const TriangleMesh m = sphereWithHole();
    const FastWindingNumber fwn(m);
    EXPECT_GT(fwn.currentEdges(), 0u);
    std::mt19937_64 rng(3);
    for (int i = 0; i < 60; ++i) {
        Vec3d q;
        for (int k = 0; k < 3; ++k) q[k] = std::uniform_real_distribution<double>(-1.3, 1.3)(rng);
        const Vec3d g = fwn.gradient(q);
        Vec3d fd;
        const double e = 1e-6;
        for (int k = 0; k < 3; ++k) {
            Vec3d a = q, b = q;
            a[k] += e;
            b[k] -= e;
            fd[k] = (fwn.exact(a) - fwn.exact(b)) / (2.0 * e);
        }
        EXPECT_NEAR((g - fd).length(), 0.0, 1e-5 * (1.0 + g.length()));
        // bounds over a small box around q hold at sampled points of the box
        const Vec3d lo = q - Vec3d(0.05), hi = q + Vec3d(0.05);
        const double G = fwn.gradientBound(lo, hi), H = fwn.hessianBound(lo, hi);
        for (int s = 0; s < 8; ++s) {
            const Vec3d p(s & 4 ? hi[0] : lo[0], s & 2 ? hi[1] : lo[1], s & 1 ? hi[2] : lo[2]);
            EXPECT_LE(fwn.gradient(p).length(), G * (1.0 + 1e-9));
            const Vec3d dg = fwn.gradient(p) - fwn.gradient(q);
            EXPECT_LE(dg.length(), H * (p - q).length() * (1.0 + 1e-6));
        }
    }
}

TEST(FastWindingNumber, FastGradientIsWithinItsBoundOfTheExactOne)
{
    // the edge tree's gradient (far subtrees as one current element) against the exact sum over
    // every edge: within its reported bound everywhere, exact near the boundary (no subtree is
    // far), and the bound small far away (closed loops of current fall off as 1/r^3)
    TriangleMesh m = sphereWithHole(4);
    append(m, openSheet());
    const FastWindingNumber fwn(m);
    ASSERT_GT(fwn.currentEdges(), 16u); // deep enough an edge tree to have far subtrees
    std::mt19937_64 rng(11);
    double worstRatio = 0.0, farBound = 0.0;
    int approximated = 0;
    for (int i = 0; i < 400; ++i) {
        Vec3d q;
        const double r = i < 200 ? 1.6 : 6.0;
        for (int k = 0; k < 3; ++k) q[k] = std::uniform_real_distribution<double>(-r, r)(rng);
        double err = -1.0;
        const Vec3d fast = fwn.gradient(q, err), exact = fwn.gradient(q);
        ASSERT_GE(err, 0.0);
        const double diff = (fast - exact).length();
        EXPECT_LE(diff, err + 1e-12 * (1.0 + exact.length())) << "at " << q;
        if (err > 1e-12) { ++approximated; worstRatio = std::max(worstRatio, diff / err); }
        if (i >= 200 && q.length() > 4.0) farBound = std::max(farBound, err / std::max(exact.length(), 1e-300));
    }
    EXPECT_GT(approximated, 50); // the far field was used
    EXPECT_LT(worstRatio, 1.0);
    std::printf("fast gradient: %d of 400 points used far subtrees; worst |error| / bound %.3g; far bound / |grad| %.3g\n",
                approximated, worstRatio, farBound);
}

TEST(FastWindingNumber, UnweldedSeamsCarryNoCurrent)
{
    // a closed sphere cut into two patches whose seam vertices are duplicated (a teapot's or a
    // kit-bashed model's seams): the coincident seam edges carry opposite currents, which cancel
    const TriangleMesh s = makeIcosphere(Vec3d(0.0), 1.0, 3);
    TriangleMesh m;
    m.points = s.points;
    const uint32_t n = uint32_t(s.points.size());
    m.points.insert(m.points.end(), s.points.begin(), s.points.end()); // copies: index + n
    for (const Vec3I& t : s.triangles) {
        const bool upper = (s.points[t[0]] + s.points[t[1]] + s.points[t[2]])[2] > 0.0;
        m.triangles.push_back(upper ? Vec3I(t[0] + n, t[1] + n, t[2] + n) : t);
    }
    EXPECT_GT(validateMesh(m).boundaryEdges, 0u); // by index, the seam is a boundary
    const FastWindingNumber fwn(m);
    EXPECT_EQ(fwn.currentEdges(), 0u);
    EXPECT_NEAR(fwn(Vec3d(0.1, 0.2, 0.05)), 1.0, 1e-2);
    EXPECT_NEAR(fwn(Vec3d(0.0, 0.0, 1.5)), 0.0, 1e-2);
    EXPECT_EQ(fwn.gradientBound(Vec3d(-0.5), Vec3d(0.5)), 0.0);
}

TEST(FastWindingNumber, BadOptionsAreRefused)
{
    const TriangleMesh m = makeIcosphere(Vec3d(0.0), 1.0, 1);
    FastWindingNumberOptions o;
    o.accuracy = 1.0;
    EXPECT_THROW(FastWindingNumber(m, o), InvalidArgumentError);
    o.accuracy = 2.0;
    o.order = 4;
    EXPECT_THROW(FastWindingNumber(m, o), InvalidArgumentError);
    o.order = 3;
    o.leafSize = 0;
    EXPECT_THROW(FastWindingNumber(m, o), InvalidArgumentError);
    const std::vector<double> w = fastWindingNumbers(m, {Vec3d(0.0), Vec3d(5.0)});
    ASSERT_EQ(w.size(), 2u);
    EXPECT_NEAR(w[0], 1.0, 1e-2);
    EXPECT_NEAR(w[1], 0.0, 1e-2);
}

// ------------------------------------------------------------------ winding signs of the band

TEST(WindingSign, GeneratedBrokenMeshesHaveNoDecisiveSignErrors)
{
    // every active voxel, and (sampled) inactive voxels of the leaves and every tile: where
    // ||w| - 1/2| > 0.25, negative exactly where |w| > 1/2; magnitudes exact
    for (const Case& c : brokenCases()) {
        SCOPED_TRACE(c.name);
        MeshToLevelSetStats stats;
        const auto grid = meshToLevelSet(c.mesh, options(SignMode::Winding, 56), &stats);
        EXPECT_EQ(stats.sign, SignMode::Winding);
        const ExactReference ref(c.mesh);
        const WindingSignReport active = compareSignsToWindingNumber(*grid, ref, 0.25, strideFor(*grid, 15000, false), false);
        EXPECT_GT(active.decisive, 0u);
        EXPECT_EQ(active.signErrors, 0u);
        const WindingSignReport all = compareSignsToWindingNumber(*grid, ref, 0.25, strideFor(*grid, 15000, true), true);
        EXPECT_EQ(all.signErrors, 0u);
        expectExactMagnitudes(*grid, ref, c.name);
        EXPECT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
        ASSERT_TRUE(grid->getMetadata<openvdb::StringMetadata>(kSignMetadata));
        EXPECT_EQ(grid->metaValue<std::string>(kSignMetadata), "winding");
        // the pseudonormal is wrong on most of these, for the record
        const auto pn = meshToLevelSet(c.mesh, options(SignMode::Pseudonormal, 56));
        const WindingSignReport p = compareSignsToWindingNumber(*pn, ref, 0.25, strideFor(*pn, 15000, false), false);
        std::printf("%-28s winding: 0 of %llu decisive active voxels wrong; pseudonormal: %llu wrong; "
                    "%llu evaluations for %llu active voxels\n",
                    c.name.c_str(), (unsigned long long)active.decisive, (unsigned long long)p.signErrors,
                    (unsigned long long)stats.windingEvaluations, (unsigned long long)stats.activeVoxels);
    }
}

TEST(WindingSign, SphereWithHoleAtSeveralResolutionsAndBands)
{
    const TriangleMesh m = sphereWithHole(2);
    const ExactReference ref(m);
    for (int voxels : {24, 80}) {
        for (double band : {1.0, 3.0, 9.0}) {
            SCOPED_TRACE("voxels " + std::to_string(voxels) + ", band " + std::to_string(band));
            MeshToLevelSetOptions o = options(SignMode::Winding, voxels);
            o.exteriorWidth = band;
            o.interiorWidth = band;
            const auto grid = meshToLevelSet(m, o);
            const WindingSignReport r = compareSignsToWindingNumber(*grid, ref, 0.25, strideFor(*grid, 10000, true), true);
            EXPECT_GT(r.decisive, 0u);
            EXPECT_EQ(r.signErrors, 0u);
        }
    }
}

TEST(WindingSign, InvertedCopyGivesTheSameField)
{
    for (const TriangleMesh& m : {makeTorusKnot(2, 3, 1.0, 0.25, 96, 12), sphereWithHole()}) {
        SCOPED_TRACE(m.source);
        const auto a = meshToLevelSet(m, options(SignMode::Winding, 64));
        const auto b = meshToLevelSet(flipped(m), options(SignMode::Winding, 64));
        EXPECT_TRUE(a->tree().hasSameTopology(b->tree()));
        uint64_t signs = 0;
        double worst = 0.0;
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(b->tree());
        for (auto it = a->tree().cbeginValueAll(); it; ++it) {
            const float vb = acc.getValue(it.getCoord());
            if ((vb < 0.0f) != (*it < 0.0f)) ++signs;
            worst = std::max(worst, double(std::abs(vb - *it)));
        }
        EXPECT_EQ(signs, 0u);
        EXPECT_LE(worst / a->voxelSize()[0], 1e-5); // the closest-point arithmetic runs its corners in another order
    }
    // Auto notices a closed mesh that is inside out and signs it by the winding number
    MeshToLevelSetStats stats;
    const auto inv = meshToLevelSet(flipped(makeTorusKnot(2, 3, 1.0, 0.25, 96, 12)), options(SignMode::Auto, 48), &stats);
    EXPECT_EQ(stats.sign, SignMode::Winding);
    EXPECT_NE(stats.signReason.find("inside out"), std::string::npos) << stats.signReason;
    EXPECT_LT(inv->tree().getValue(openvdb::Coord::round(inv->worldToIndex(torusKnotPoint(2, 3, 1.0, 0.3)))), 0.0f);
}

TEST(WindingSign, ClosedMeshesGiveThePseudonormalSigns)
{
    std::vector<Case> closed = {{"torus knot", makeTorusKnot()},
                                {"box", makeBox(Vec3d(-0.93, -0.51, -0.37), Vec3d(0.71, 0.49, 0.83), 3)},
                                {"torus", makeTorus(Vec3d(0.1, 0.0, -0.2), 0.7, 0.2, 64, 24)},
                                {"icosphere", makeIcosphere(Vec3d(0.3, 0.1, 0.0), 0.8, 4)}};
    if (!levelforge_test::sharedDataDir().empty()) {
        for (const char* f : {"meshes/watertight/spot.obj", "meshes/watertight/fertility.off"}) {
            const std::string path = levelforge_test::sharedDataDir() + "/" + f;
            if (std::filesystem::exists(path)) closed.push_back({f, readMesh(path)});
        }
    }
    for (const Case& c : closed) {
        SCOPED_TRACE(c.name);
        for (double band : {3.0, 10.0}) {
            MeshToLevelSetOptions o = options(SignMode::Winding, 96);
            o.exteriorWidth = o.interiorWidth = band;
            MeshToLevelSetStats ws;
            const auto w = meshToLevelSet(c.mesh, o, &ws);
            o.sign = SignMode::Pseudonormal;
            const auto p = meshToLevelSet(c.mesh, o);
            o.sign = SignMode::Auto;
            MeshToLevelSetStats as;
            const auto a = meshToLevelSet(c.mesh, o, &as);
            EXPECT_EQ(as.sign, SignMode::Pseudonormal) << as.signReason;
            expectSameTree(p->tree(), a->tree(), "auto = pseudonormal");
            // the same active voxels and values; inactive signs the same (pseudonormal: flood fill)
            EXPECT_EQ(w->activeVoxelCount(), p->activeVoxelCount());
            // (voxels on the surface to rounding, |φ| <= 1e-9 voxel, are +0 in winding mode)
            uint64_t differ = 0;
            const float onSurface = float(1e-9 * p->voxelSize()[0]);
            openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(w->tree());
            for (auto it = p->tree().cbeginValueOn(); it; ++it) {
                const float v = acc.getValue(it.getCoord());
                if (!acc.isValueOn(it.getCoord())) ++differ;
                else if (v != *it && !(std::abs(*it) <= onSurface && v == 0.0f)) ++differ;
            }
            EXPECT_EQ(differ, 0u);
            uint64_t tileSigns = 0;
            for (auto it = w->tree().cbeginValueOff(); it; ++it) {
                const float v = p->tree().getValue(it.getCoord());
                if ((v < 0.0f) != (*it < 0.0f) && std::abs(v) > onSurface) ++tileSigns;
            }
            EXPECT_EQ(tileSigns, 0u);
            EXPECT_EQ(ws.currentEdges, 0u);
            // w is piecewise constant: one estimate per leaf, and one per voxel group whose
            // crossing count was too close to call
            EXPECT_LE(ws.windingIndividual * 100, ws.windingGroups);
        }
    }
}

TEST(WindingSign, SameResultForOneAndTwoThreads)
{
    for (const TriangleMesh& m : {sphereWithHole(), twoBoxes(), openSheet()}) {
        SCOPED_TRACE(m.source);
        openvdb::FloatGrid::Ptr one, two;
        MeshToLevelSetStats s1, s2;
        MeshToLevelSetOptions o = options(SignMode::Winding, 72);
        o.fillInterior = true;
        {
            tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
            one = meshToLevelSet(m, o, &s1);
        }
        {
            tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
            two = meshToLevelSet(m, o, &s2);
        }
        expectSameTree(one->tree(), two->tree(), m.source);
        EXPECT_EQ(s1.windingEvaluations, s2.windingEvaluations);
        EXPECT_EQ(s1.filledVoxels, s2.filledVoxels);
    }
}

TEST(WindingSign, AutoChoosesByValidation)
{
    MeshToLevelSetStats s;
    meshToLevelSet(makeTorusKnot(), options(SignMode::Auto, 48), &s);
    EXPECT_EQ(s.sign, SignMode::Pseudonormal);
    EXPECT_NE(s.signReason.find("closed"), std::string::npos) << s.signReason;
    meshToLevelSet(sphereWithHole(), options(SignMode::Auto, 48), &s);
    EXPECT_EQ(s.sign, SignMode::Winding);
    EXPECT_NE(s.signReason.find("boundary"), std::string::npos) << s.signReason;
    meshToLevelSet(twoBoxes(), options(SignMode::Auto, 48), &s);
    EXPECT_EQ(s.sign, SignMode::Pseudonormal); // closed parts; their intersection is not looked for
    // a report given by the caller is used as it is
    const TriangleMesh open = sphereWithHole();
    const MeshReport report = validateMesh(open);
    MeshToLevelSetOptions o = options(SignMode::Auto, 32);
    o.validation = &report;
    meshToLevelSet(open, o, &s);
    EXPECT_EQ(s.sign, SignMode::Winding);
    EXPECT_EQ(signModeFromString("winding"), SignMode::Winding);
    EXPECT_STREQ(toString(SignMode::Unsigned), "unsigned");
    EXPECT_THROW(signModeFromString("flood"), InvalidArgumentError);
}

TEST(WindingSign, SharedOpenAndBrokenMeshes)
{
    LF_SKIP_WITHOUT_SHARED_DATA();
    const std::string dir = levelforge_test::sharedDataDir() + "/meshes/open_or_broken/";
    int found = 0;
    for (const char* f : {"bunny.obj", "suzanne.obj", "teapot.obj", "cgal_elephant-with-holes.off", "assimp_spider.obj",
                          "trimesh_soup.stl", "trimesh_joined_tetrahedra.obj", "openscad_issue1580-zero-area-triangle.stl"}) {
        const std::string path = dir + f;
        if (!std::filesystem::exists(path)) continue;
        ++found;
        SCOPED_TRACE(f);
        const TriangleMesh m = readMesh(path);
        MeshToLevelSetStats stats;
        const auto grid = meshToLevelSet(m, options(SignMode::Winding, 64), &stats);
        const ExactReference ref(m);
        // about 1500 active voxels, and 1500 voxels of the leaves (active or not) and every tile
        const uint64_t stride = strideFor(*grid, 1500, false);
        const WindingSignReport r = compareSignsToWindingNumber(*grid, ref, 0.25, stride, false);
        const WindingSignReport all = compareSignsToWindingNumber(*grid, ref, 0.25, strideFor(*grid, 1500, true), true);
        EXPECT_EQ(r.signErrors, 0u);
        EXPECT_EQ(all.signErrors, 0u);
        const auto pn = meshToLevelSet(m, options(SignMode::Pseudonormal, 64));
        const WindingSignReport p = compareSignsToWindingNumber(*pn, ref, 0.25, stride, false);
        std::printf("%-44s winding 0 of %llu decisive wrong (+%llu inactive/tiles); pseudonormal %llu of %llu wrong\n", f,
                    (unsigned long long)r.decisive, (unsigned long long)all.decisive,
                    (unsigned long long)p.signErrors, (unsigned long long)p.decisive);
    }
    if (found == 0) LF_SHARED_DATA_MISSING(dir << " holds none of the open/broken meshes");
}

// ------------------------------------------------------------------ unsigned

TEST(UnsignedDistance, ExactForOpenSurfacesAndNotALevelSet)
{
    for (const TriangleMesh& m : {openSheet(), sphereWithHole(2), makeRandomTriangles(60, 5, BBoxd(Vec3d(-1.0), Vec3d(1.0)), 0.5)}) {
        SCOPED_TRACE(m.source);
        MeshToLevelSetOptions o = options(SignMode::Unsigned, 40);
        o.exteriorWidth = 2.5;
        MeshToLevelSetStats stats;
        const auto grid = meshToLevelSet(m, o, &stats);
        EXPECT_EQ(stats.sign, SignMode::Unsigned);
        EXPECT_EQ(grid->getGridClass(), openvdb::GRID_UNKNOWN);
        EXPECT_EQ(grid->metaValue<std::string>(kSignMetadata), "unsigned");
        const double h = grid->voxelSize()[0];
        const ExactReference ref(m);
        double worst = 0.0;
        uint64_t negative = 0;
        for (auto it = grid->tree().cbeginValueAll(); it; ++it) {
            if (*it < 0.0f) ++negative;
            if (!it.isValueOn()) continue;
            const double d = std::abs(ref.bruteForce(grid->indexToWorld(it.getCoord())).distance);
            worst = std::max(worst, std::abs(double(*it) - d) / h);
            EXPECT_LT(d / h, 2.5 + 1e-6);
        }
        EXPECT_EQ(negative, 0u);
        EXPECT_LE(worst, 1e-4);
        // every voxel within the band is active: the face-neighbours of the band are outside it
        uint64_t missing = 0;
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(grid->tree());
        for (auto it = grid->tree().cbeginValueOn(); it; ++it)
            for (const openvdb::Coord& dc : {openvdb::Coord(1, 0, 0), openvdb::Coord(-1, 0, 0), openvdb::Coord(0, 1, 0),
                                             openvdb::Coord(0, -1, 0), openvdb::Coord(0, 0, 1), openvdb::Coord(0, 0, -1)}) {
                const openvdb::Coord q = it.getCoord() + dc;
                if (acc.isValueOn(q)) continue;
                if (std::abs(ref.query(grid->indexToWorld(q)).distance) / h < 2.5 - 1e-6) ++missing;
            }
        EXPECT_EQ(missing, 0u);
    }
}

// ------------------------------------------------------------------ fill interior

TEST(FillInterior, EveryInsideVoxelIsActiveAndNegative)
{
    std::vector<Case> cases = {{"torus (pseudonormal)", makeTorus(Vec3d(0.0), 0.7, 0.3, 32, 12)},
                               {"sphere with a hole (winding)", sphereWithHole(2)},
                               {"double-walled shell (winding)", hollowShell(2)}};
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        MeshToLevelSetOptions o = options(SignMode::Auto, 64);
        o.fillInterior = true;
        MeshToLevelSetStats stats;
        const auto grid = meshToLevelSet(c.mesh, o, &stats);
        EXPECT_GT(stats.filledVoxels, 0u);
        if (c.name.rfind("sphere", 0) == 0) // 32 voxels of radius: whole 8³ tiles inside
            EXPECT_GT(grid->tree().activeTileCount(), 0u) << "a whole tile inside is an active tile";
        EXPECT_TRUE(grid->metaValue<bool>(kFillInteriorMetadata));
        const ExactReference ref(c.mesh);
        const double h = grid->voxelSize()[0];
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(grid->tree());
        openvdb::CoordBBox all = grid->evalActiveVoxelBoundingBox();
        all.expand(2);
        uint64_t inside = 0, bad = 0, outsideActiveDeep = 0;
        for (int x = all.min().x(); x <= all.max().x(); x += 2)
            for (int y = all.min().y(); y <= all.max().y(); y += 2)
                for (int z = all.min().z(); z <= all.max().z(); z += 3) {
                    const openvdb::Coord ijk(x, y, z);
                    const double w = std::abs(ref.windingNumber(grid->indexToWorld(ijk)));
                    if (std::abs(w - 0.5) <= 0.05) continue; // the estimate's verdict there
                    const float v = acc.getValue(ijk);
                    if (v == 0.0f) continue; // on the surface
                    if (w > 0.5) {
                        ++inside;
                        if (!(v < 0.0f) || !acc.isValueOn(ijk)) ++bad;
                    } else {
                        if (!(v > 0.0f)) ++bad;
                        if (acc.isValueOn(ijk) && v > float(3.0 * h) + 1e-6f) ++outsideActiveDeep;
                    }
                }
        EXPECT_GT(inside, 1000u);
        EXPECT_EQ(bad, 0u);
        EXPECT_EQ(outsideActiveDeep, 0u);
        // the band keeps its exact values
        expectExactMagnitudes(*grid, ref, c.name + " (band)");
    }
}

TEST(FillInterior, IsTheBandPlusInteriorAndBadCombinationsAreRefused)
{
    const TriangleMesh m = makeIcosphere(Vec3d(0.0), 1.0, 3);
    MeshToLevelSetOptions o = options(SignMode::Pseudonormal, 48);
    const auto band = meshToLevelSet(m, o);
    o.fillInterior = true;
    const auto filled = meshToLevelSet(m, o);
    // every band voxel is there with its value; everything else active is −background
    const float bg = filled->background();
    uint64_t missing = 0, deep = 0;
    for (auto it = band->tree().cbeginValueOn(); it; ++it)
        if (filled->tree().getValue(it.getCoord()) != *it || !filled->tree().isValueOn(it.getCoord())) ++missing;
    for (auto it = filled->tree().cbeginValueOn(); it; ++it)
        if (!band->tree().isValueOn(it.getCoord()) && *it != -bg) ++deep;
    EXPECT_EQ(missing, 0u);
    EXPECT_EQ(deep, 0u);
    // unsigned has no inside
    o.sign = SignMode::Unsigned;
    EXPECT_THROW(meshToLevelSet(m, o), InvalidArgumentError);
    o.sign = SignMode::Winding;
    o.windingAccuracy = 0.5;
    EXPECT_THROW(meshToLevelSet(m, o), InvalidArgumentError);
}

// ------------------------------------------------------------------ the pipeline

TEST(WindingSign, PipelineWithExpansionSignsTheWidenedBandAndTiles)
{
    const TriangleMesh m = sphereWithHole(2);
    const ExactReference ref(m);
    for (bool fill : {false, true}) {
        MeshToSdfOptions o;
        o.voxelCount = 48;
        o.expansion = Expansion::Vector;
        o.exteriorWidth = o.interiorWidth = 8.0;
        o.fillInterior = fill;
        MeshToSdfStats stats;
        const auto grid = meshToSdf(m, o, &stats);
        EXPECT_EQ(stats.sign, SignMode::Winding);
        const WindingSignReport r = compareSignsToWindingNumber(*grid, ref, 0.25, 2, true);
        EXPECT_GT(r.decisive, 0u);
        EXPECT_EQ(r.signErrors, 0u) << "fill " << fill;
        EXPECT_EQ(grid->metaValue<std::string>(kSignMetadata), "winding");
    }
    // fast sweeping makes up a zero crossing across a hole: auto keeps pseudonormal signs there
    // (as before the sign modes), and winding is refused
    MeshToSdfOptions o;
    o.voxelCount = 32;
    o.expansion = Expansion::Sweep;
    o.exteriorWidth = o.interiorWidth = 6.0;
    MeshToSdfStats stats;
    meshToSdf(m, o, &stats);
    EXPECT_EQ(stats.sign, SignMode::Pseudonormal);
    EXPECT_NE(stats.signReason.find("fast sweeping"), std::string::npos) << stats.signReason;
    o.sign = SignMode::Winding;
    EXPECT_THROW(meshToSdf(m, o), InvalidArgumentError);
    o.sign = SignMode::Auto;
    meshToSdf(makeTorusKnot(), o, &stats); // closed: pseudonormal
    EXPECT_EQ(stats.sign, SignMode::Pseudonormal);
    EXPECT_NE(stats.signReason.find("closed and consistently oriented"), std::string::npos) << stats.signReason;
    // combinations that cannot work
    o = MeshToSdfOptions();
    o.voxelCount = 32;
    o.sign = SignMode::Winding;
    o.method = BandMethod::Scan;
    EXPECT_THROW(meshToSdf(m, o), InvalidArgumentError);
    o.method = BandMethod::Chang;
    o.sign = SignMode::Unsigned;
    o.expansion = Expansion::Vector;
    EXPECT_THROW(meshToSdf(m, o), InvalidArgumentError);
    o.expansion = Expansion::None;
    o.fillInterior = true;
    EXPECT_THROW(meshToSdf(m, o), InvalidArgumentError);
    // unsigned through the pipeline: not a level set, metadata says so
    o.fillInterior = false;
    const auto udf = meshToSdf(m, o);
    EXPECT_EQ(udf->getGridClass(), openvdb::GRID_UNKNOWN);
    EXPECT_EQ(udf->metaValue<std::string>(kSignMetadata), "unsigned");
}

// ------------------------------------------------ stray open triangles (a bad export's vertex)

namespace {

/// A unit icosphere and a thin open triangle from beside it to `reach` units away, obliquely
/// (direction (1, 0.3, 0.2)): the bounding box of its long edges holds the whole sphere. With
/// `second`, another such triangle on the other side.
TriangleMesh sphereWithStray(double reach, bool second = false)
{
    TriangleMesh m = makeIcosphere(Vec3d(0.0), 1.0, 3);
    const auto add = [&m, reach](const Vec3d& a, const Vec3d& dir) {
        const uint32_t base = uint32_t(m.points.size());
        m.points.push_back(a);
        m.points.push_back(a + Vec3d(0.0, 0.01, 0.004));
        m.points.push_back(a + dir.unit() * reach);
        m.triangles.emplace_back(base, base + 1, base + 2);
    };
    add(Vec3d(1.25, 0.0, 0.0), Vec3d(1.0, 0.3, 0.2));
    if (second) add(Vec3d(-1.25, 0.1, 0.0), Vec3d(-1.0, 0.2, -0.3));
    m.source = second ? "<sphere and two stray triangles>" : "<sphere and a stray triangle>";
    return m;
}

} // namespace

TEST(FastWindingNumber, SegmentBoxDistanceIsExact)
{
    // against the minimum over 20,001 points of the segment (above the truth by at most half a
    // step times the slope, 1); segmentMeetsBox agrees with a zero distance
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    const auto pointBox = [](const Vec3d& p, const Vec3d& lo, const Vec3d& hi) {
        double d2 = 0.0;
        for (int k = 0; k < 3; ++k) {
            const double e = p[k] < lo[k] ? lo[k] - p[k] : (p[k] > hi[k] ? p[k] - hi[k] : 0.0);
            d2 += e * e;
        }
        return std::sqrt(d2);
    };
    int touching = 0;
    for (int i = 0; i < 400; ++i) {
        const Vec3d a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng));
        Vec3d lo(u(rng), u(rng), u(rng)), hi = lo;
        for (int k = 0; k < 3; ++k) hi[k] += std::abs(u(rng)) * 1.5;
        double brute = std::numeric_limits<double>::infinity();
        const int n = 20000;
        for (int s = 0; s <= n; ++s) brute = std::min(brute, pointBox(a + (b - a) * (double(s) / n), lo, hi));
        const double d = FastWindingNumberAccess::segmentBoxDistance(a, b, lo, hi);
        EXPECT_LE(d, brute + 1e-12) << i;
        EXPECT_GE(d, brute - 0.5 * (b - a).length() / n - 1e-9) << i;
        const bool meets = FastWindingNumberAccess::segmentMeetsBox(a, b, lo, hi);
        EXPECT_EQ(meets, d == 0.0) << i << " distance " << d;
        touching += meets ? 1 : 0;
    }
    EXPECT_GT(touching, 20); // both cases seen
}

TEST(FastWindingNumber, BoundsBesideALongObliqueEdgeStayFiniteAndHold)
{
    // The stray triangle's long edges have a bounding box holding the sphere: bounds from the
    // distance to that box were infinite everywhere near the sphere, and every voxel there was
    // evaluated on its own (minutes for a vertex 1000 diagonals away).
    const TriangleMesh m = sphereWithStray(300.0);
    const FastWindingNumber fwn(m);
    ASSERT_EQ(fwn.currentEdges(), 3u);
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> u(-1.1, 1.1);
    for (int i = 0; i < 60; ++i) {
        const Vec3d q(u(rng), u(rng) - 0.5, u(rng) - 0.5); // beside the sphere, below the stray
        const Vec3d lo = q - Vec3d(0.05), hi = q + Vec3d(0.05);
        const double G = fwn.gradientBound(lo, hi), H = fwn.hessianBound(lo, hi);
        ASSERT_TRUE(std::isfinite(G)) << i;
        ASSERT_TRUE(std::isfinite(H)) << i;
        for (int s = 0; s < 8; ++s) {
            const Vec3d p(s & 4 ? hi[0] : lo[0], s & 2 ? hi[1] : lo[1], s & 1 ? hi[2] : lo[2]);
            EXPECT_LE(fwn.gradient(p).length(), G * (1.0 + 1e-9));
            EXPECT_LE((fwn.gradient(p) - fwn.gradient(q)).length(), H * (p - q).length() * (1.0 + 1e-6));
        }
    }
}

TEST(WindingSign, ALoneOpenTriangleIsLeftOutOfTheWindingNumber)
{
    // |w| of one triangle stays below 1/2, the sphere's is 0 or 1: leaving the triangle out is
    // exact, and the rest has no boundary current (one estimate per group, no model)
    const TriangleMesh m = sphereWithStray(5.0);
    MeshToLevelSetStats stats;
    MeshToLevelSetOptions o = options(SignMode::Auto, 64);
    const auto grid = meshToLevelSet(m, o, &stats);
    EXPECT_EQ(stats.sign, SignMode::Winding);
    EXPECT_EQ(stats.currentEdges, 0u);
    EXPECT_NE(stats.signReason.find("triangle 1280"), std::string::npos) << stats.signReason;
    EXPECT_EQ(stats.windingIndividual, 0u);
    const ExactReference ref(m);
    const WindingSignReport active = compareSignsToWindingNumber(*grid, ref, 0.05, strideFor(*grid, 20000, false), false);
    EXPECT_GT(active.decisive, 1000u);
    EXPECT_EQ(active.signErrors, 0u);
    const WindingSignReport all = compareSignsToWindingNumber(*grid, ref, 0.05, strideFor(*grid, 20000, true), true);
    EXPECT_EQ(all.signErrors, 0u);
    expectExactMagnitudes(*grid, ref, m.source);
    // the band along the stray triangle is outside on both sides
    const openvdb::Coord c = grid->transform().worldToIndexNodeCentered(openvdb::Vec3d(3.0, 0.5, 0.35));
    uint64_t near = 0, negative = 0;
    for (auto it = grid->tree().cbeginValueOn(); it; ++it) {
        if ((it.getCoord() - c).asVec3d().length() > 6.0) continue;
        ++near;
        negative += *it < 0.0f ? 1 : 0;
    }
    EXPECT_GT(near, 0u);
    EXPECT_EQ(negative, 0u);

    // not for a hole of three edges (a closed mesh less one triangle), nor two stray triangles
    TriangleMesh holed = makeIcosphere(Vec3d(0.0), 1.0, 3);
    holed.triangles.erase(holed.triangles.begin() + 17);
    MeshToLevelSetStats hs;
    meshToLevelSet(holed, options(SignMode::Winding, 32), &hs);
    EXPECT_EQ(hs.currentEdges, 3u);
    EXPECT_EQ(hs.signReason.find("left out"), std::string::npos);
    MeshToLevelSetStats ts;
    meshToLevelSet(sphereWithStray(5.0, true), options(SignMode::Winding, 32), &ts);
    EXPECT_EQ(ts.currentEdges, 6u);
}

TEST(WindingSign, TwoStrayTrianglesAreSignedExactlyAndLocally)
{
    // two stray triangles (nothing is left out): the leaves they cross have a boundary current
    // through them; the local exact tier (the few triangles near the leaf summed exactly, a
    // first-order model of the rest) decides them without an estimate per voxel, so the
    // estimates per active voxel do not grow with the strays' length
    uint64_t alone[2] = {0, 0}, active[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        const TriangleMesh m = sphereWithStray(k == 0 ? 3.0 : 12.0, true);
        SCOPED_TRACE(k);
        MeshToLevelSetStats stats;
        MeshToLevelSetOptions o = options(SignMode::Winding, 0);
        o.voxelCount = 0;
        o.voxelSize = 0.1;
        const auto grid = meshToLevelSet(m, o, &stats);
        EXPECT_EQ(stats.currentEdges, 6u);
        alone[k] = stats.windingIndividual;
        active[k] = stats.activeVoxels;
        if (k == 1) continue;
        const ExactReference ref(m);
        const WindingSignReport a = compareSignsToWindingNumber(*grid, ref, 0.05, strideFor(*grid, 20000, false), false);
        EXPECT_GT(a.decisive, 1000u);
        EXPECT_EQ(a.signErrors, 0u);
        const WindingSignReport all = compareSignsToWindingNumber(*grid, ref, 0.05, strideFor(*grid, 20000, true), true);
        EXPECT_EQ(all.signErrors, 0u);
        expectExactMagnitudes(*grid, ref, m.source);
    }
    std::printf("two stray triangles, 3 and 12 long: %llu and %llu estimates alone for %llu and %llu active voxels\n",
                (unsigned long long)alone[0], (unsigned long long)alone[1], (unsigned long long)active[0],
                (unsigned long long)active[1]);
    // (before: 12,565 and 70,352, 1.3 and 4.8 per active voxel: every voxel along the strays
    // estimated alone, and more the longer they are)
    EXPECT_GT(active[1], active[0] + 4000);
    for (int k = 0; k < 2; ++k) EXPECT_LT(double(alone[k]), 0.5 * double(active[k])) << k;
    EXPECT_LT(double(alone[1]) / double(active[1]), 1.6 * double(alone[0]) / double(active[0]));
}

TEST(WindingSign, TheTilePassStopsWhenInterrupted)
{
    // the winding sign's passes poll at 97 %, the main road's distances below 96 %
    struct StopAfter : openvdb::util::NullInterrupter
    {
        int calls = 0;
        bool wasInterrupted(int percent) override { return percent == 97 && ++calls > 1; }
    } stop;
    const TriangleMesh m = sphereWithStray(5.0, true);
    MeshToLevelSetOptions o = options(SignMode::Unsigned, 64);
    const auto grid = meshToLevelSet(m, o);
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    const FastWindingNumber fwn(m);
    EXPECT_THROW(signInactiveByWindingNumber(*grid, fwn, m.bounds(), nullptr, &stop), InterruptedError);
    EXPECT_GT(stop.calls, 1);
    // and the main road's winding sign stops too
    StopAfter again;
    o.sign = SignMode::Winding;
    o.interrupter = &again;
    EXPECT_THROW(meshToLevelSet(m, o), InterruptedError);
}
