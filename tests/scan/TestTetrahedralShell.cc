// SPDX-License-Identifier: Apache-2.0
// Tests for TetrahedralShell.h: the small convex hull, the thin-shell root system (Eq. 6-11),
// the OBB shell (contains the whole eps-neighbourhood of its face) and the tetrahedron slicer
// of TetScanConversion.h (cases A, B, C of §3.1).
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/MeshShapes.h>
#include <levelforge/core/PseudoNormals.h>
#include <levelforge/scan/TetScanConversion.h>
#include <levelforge/scan/TetrahedralShell.h>
#include "scan/TetrahedralShellInternal.h"
#include "scan/TetScanInternal.h"
#include <levelforge/core/TriangleDistance.h>

#include <cmath>
#include <random>

using namespace levelforge;

namespace {

double uniform(std::mt19937_64& rng, double lo, double hi)
{
    return lo + (hi - lo) * (double(rng() >> 11) * 0x1.0p-53);
}

/// Barycentric inside test for a tetrahedron, with a tolerance.
bool insideTet(const Tetrahedron& t, const Vec3d& p, double tol = 1e-9)
{
    const double v = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).dot(t.p[3] - t.p[0]);
    if (v == 0.0) return false;
    for (int k = 0; k < 4; ++k) {
        std::array<Vec3d, 4> q = t.p;
        q[k] = p;
        const double vk = (q[1] - q[0]).cross(q[2] - q[0]).dot(q[3] - q[0]);
        if (vk / v < -tol) return false;
    }
    return true;
}

bool insideAny(const std::vector<Tetrahedron>& tets, const Vec3d& p, double tol = 1e-9)
{
    for (const Tetrahedron& t : tets)
        if (insideTet(t, p, tol)) return true;
    return false;
}

/// A random point of triangle v plus an offset of length r in a random direction.
Vec3d pointNearTriangle(std::mt19937_64& rng, const Vec3d v[3], double r)
{
    double a = uniform(rng, 0, 1), b = uniform(rng, 0, 1);
    if (a + b > 1) { a = 1 - a; b = 1 - b; }
    const Vec3d base = v[0] + (v[1] - v[0]) * a + (v[2] - v[0]) * b;
    Vec3d dir;
    do dir = Vec3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    while (dir.length() < 1e-6);
    dir.normalize();
    return base + dir * r;
}

bool insidePolygon(const std::array<double, 4>& x, const std::array<double, 4>& y, int n, double px, double py)
{
    CrossSection cs;
    cs.count = uint32_t(n);
    std::copy(x.begin(), x.end(), cs.x.begin());
    std::copy(y.begin(), y.end(), cs.y.begin());
    double xl, xr;
    if (!crossSectionSpan(cs, py, 1e-9, xl, xr)) return false;
    return px >= xl - 1e-9 && px <= xr + 1e-9;
}

} // namespace

TEST(TetrahedralShell, ConvexHullOfCubeWithInteriorPoints)
{
    std::vector<Vec3d> pts;
    for (int i = 0; i < 8; ++i) pts.push_back(Vec3d(i & 1, (i >> 1) & 1, (i >> 2) & 1));
    pts.push_back(Vec3d(0.5, 0.5, 0.5));
    pts.push_back(Vec3d(0.2, 0.7, 0.1));
    pts.push_back(Vec3d(1, 1, 1)); // duplicate
    const auto faces = shell_internal::convexHull(pts);
    EXPECT_EQ(faces.size(), 12u); // 6 square facets, each fan-triangulated once
    std::vector<Tetrahedron> tets;
    shell_internal::hullTetrahedra(pts, 0, tets);
    double vol = 0.0;
    for (const auto& t : tets) vol += shell_internal::volume(t);
    EXPECT_NEAR(vol, 1.0, 1e-12);
    // Flat point sets have no hull.
    EXPECT_TRUE(shell_internal::convexHull({Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0), Vec3d(1, 1, 0)}).empty());
}

TEST(TetrahedralShell, ConvexHullOfRandomPointsContainsAllAndIsConvex)
{
    std::mt19937_64 rng(7);
    for (int trial = 0; trial < 200; ++trial) {
        std::vector<Vec3d> pts;
        const int n = 4 + trial % 9;
        for (int i = 0; i < n; ++i) pts.push_back(Vec3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1)));
        std::vector<Tetrahedron> tets;
        shell_internal::hullTetrahedra(pts, 0, tets);
        ASSERT_FALSE(tets.empty());
        for (const Vec3d& p : pts) EXPECT_TRUE(insideAny(tets, p, 1e-7));
        // Every hull facet has all points on one side.
        for (const auto& f : shell_internal::convexHull(pts)) {
            const Vec3d nrm = (pts[f[1]] - pts[f[0]]).cross(pts[f[2]] - pts[f[0]]);
            int pos = 0, neg = 0;
            for (const Vec3d& p : pts) {
                const double s = nrm.dot(p - pts[f[0]]);
                pos += s > 1e-9;
                neg += s < -1e-9;
            }
            EXPECT_TRUE(pos == 0 || neg == 0);
        }
        // Random points inside the hull (convex combinations) are covered by the tetrahedra.
        for (int s = 0; s < 20; ++s) {
            Vec3d q(0.0);
            double wsum = 0.0;
            for (const Vec3d& p : pts) {
                const double w = uniform(rng, 0, 1);
                q += p * w;
                wsum += w;
            }
            EXPECT_TRUE(insideAny(tets, q / wsum, 1e-9));
        }
    }
}

TEST(TetrahedralShell, ThinShellRootSystem)
{
    const std::array<Vec3d, 3> p = {Vec3d(0, 0, 0), Vec3d(1, 0, 0), Vec3d(0, 1, 0)};
    // Parallel normals: the prism never degenerates.
    const std::array<Vec3d, 3> up = {Vec3d(0, 0, 1), Vec3d(0, 0, 1), Vec3d(0, 0, 1)};
    EXPECT_TRUE(std::isinf(shell_internal::thinShellExtrusionLimit(p, up, -1.0)));
    EXPECT_TRUE(std::isinf(shell_internal::thinShellExtrusionLimit(p, up, +1.0)));
    // Normals converging outward (a concave valley seen from outside): the outward extrusion is
    // limited, the inward is not; at the limit one constraint row of Eq. 11 is zero.
    std::array<Vec3d, 3> n = {Vec3d(0.3, 0.3, 1), Vec3d(-0.6, 0.3, 1), Vec3d(0.3, -0.6, 1)};
    for (auto& v : n) v.normalize();
    const double eOut = shell_internal::thinShellExtrusionLimit(p, n, +1.0);
    const double eIn = shell_internal::thinShellExtrusionLimit(p, n, -1.0);
    ASSERT_TRUE(std::isfinite(eOut));
    EXPECT_GT(eOut, 0.0);
    EXPECT_TRUE(std::isinf(eIn) || eIn > eOut);
    std::array<Vec3d, 3> q;
    for (int k = 0; k < 3; ++k) q[k] = p[k] + n[k] * eOut;
    const Vec3d nq = (q[1] - q[0]).cross(q[2] - q[0]);
    double minDot = 1e300;
    for (int k = 0; k < 3; ++k) minDot = std::min(minDot, n[k].dot(nq));
    EXPECT_NEAR(minDot, 0.0, 1e-9);
}

TEST(TetrahedralShell, ObbContainsTheEpsNeighbourhood)
{
    std::mt19937_64 rng(11);
    for (int trial = 0; trial < 100; ++trial) {
        Vec3d v[3];
        for (auto& x : v) x = Vec3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
        if ((v[1] - v[0]).cross(v[2] - v[0]).length() < 1e-3) continue;
        const double eps = uniform(rng, 0.01, 0.5);
        std::vector<Tetrahedron> tets;
        shell_internal::obbTetrahedra(shell_internal::obbCorners(v[0], v[1], v[2], eps), 0, tets);
        ASSERT_EQ(tets.size(), 5u);
        for (int s = 0; s < 200; ++s)
            EXPECT_TRUE(insideAny(tets, pointNearTriangle(rng, v, eps * std::cbrt(uniform(rng, 0, 1))), 1e-9));
    }
}

TEST(TetrahedralShell, EpsilonPrismContainsTheEpsNeighbourhoodAndThePaperHulls)
{
    // The completion of ShellCoverage::Complete: the prism contains N_eps(T) (random points within
    // eps of random triangles, slivers included) and every point of the paper's hulls, and it is
    // not much larger than N_eps(T): no prism corner is farther than eps / cos(45°) + eps from T.
    std::mt19937_64 rng(12);
    int tested = 0;
    for (int trial = 0; trial < 200; ++trial) {
        Vec3d v[3];
        for (auto& x : v) x = Vec3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
        if (trial % 4 == 0) v[2] = v[0] + (v[1] - v[0]) * uniform(rng, 0.05, 0.95) + Vec3d(1e-3, -2e-3, 1e-3); // sliver
        if ((v[1] - v[0]).cross(v[2] - v[0]).length() < 1e-9) continue;
        const double eps = uniform(rng, 0.01, 0.5);
        const auto corners = shell_internal::epsilonPrism(v[0], v[1], v[2], eps);
        std::vector<Tetrahedron> tets;
        shell_internal::prismTetrahedra(corners, 7, tets);
        ASSERT_GE(tets.size(), 6u);
        ASSERT_LE(tets.size(), 12u);
        for (const auto& t : tets) EXPECT_EQ(t.triangle, 7u);
        for (const Vec3d& c : corners) {
            const double d = (closestPointOnTriangle(c, v[0], v[1], v[2]).point - c).length();
            EXPECT_LE(d, eps * (std::sqrt(2.0) + 1.0) + 1e-12);
            EXPECT_GE(d, eps * (1.0 - 1e-9));
        }
        Vec3d n = (v[1] - v[0]).cross(v[2] - v[0]);
        n.normalize();
        for (int s = 0; s < 300; ++s) {
            // Half the samples on the boundary of N_eps(T) (the hardest case), half inside.
            const double r = (s % 2) ? eps * (1.0 - 1e-12) : eps * std::cbrt(uniform(rng, 0, 1));
            EXPECT_TRUE(insideAny(tets, pointNearTriangle(rng, v, r), 1e-9)) << "trial " << trial;
            ++tested;
        }
        // Paper hull points: vertex +- eps * (any unit normal) and +- eps * face normal.
        for (int k = 0; k < 3; ++k) {
            Vec3d dir(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
            dir.normalize();
            EXPECT_TRUE(insideAny(tets, v[k] + dir * eps, 1e-9));
            EXPECT_TRUE(insideAny(tets, v[k] - n * eps, 1e-9));
        }
    }
    EXPECT_GT(tested, 10000);
}

TEST(TetrahedralShell, CompleteCoverageUsesThePrismPaperCoverageThePaperHull)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 1);
    const PseudoNormals normals(mesh);
    for (ShellMethod m : {ShellMethod::PseudoNormal, ShellMethod::Thin, ShellMethod::Offset}) {
        TetrahedralShellOptions opt;
        opt.method = m;
        opt.epsilon = 0.2;
        TetrahedralShellStats complete, paper;
        const auto a = buildTetrahedralShell(mesh, normals, opt, &complete);
        opt.coverage = ShellCoverage::Paper;
        const auto b = buildTetrahedralShell(mesh, normals, opt, &paper);
        EXPECT_EQ(complete.completedFaces, mesh.triangleCount()) << toString(m);
        EXPECT_EQ(paper.completedFaces, 0u) << toString(m);
        // Every corner of every paper tetrahedron lies inside the completed shell of its face.
        for (const auto& t : b)
            for (const Vec3d& p : t.p) {
                std::vector<Tetrahedron> own;
                for (const auto& u : a)
                    if (u.triangle == t.triangle) own.push_back(u);
                EXPECT_TRUE(insideAny(own, p, 1e-9)) << toString(m) << " face " << t.triangle;
            }
    }
    TetrahedralShellOptions obb;
    obb.epsilon = 0.2;
    TetrahedralShellStats s;
    buildTetrahedralShell(mesh, normals, obb, &s);
    EXPECT_EQ(s.completedFaces, 0u); // the box covers already
    EXPECT_EQ(shellCoverageFromString("paper"), ShellCoverage::Paper);
    EXPECT_STREQ(toString(ShellCoverage::Complete), "complete");
    EXPECT_THROW(shellCoverageFromString("exact"), InvalidArgumentError);
}

TEST(TetrahedralShell, EveryMethodTagsFacesAndIsDeterministic)
{
    const TriangleMesh mesh = makeIcosphere(Vec3d(0.0), 1.0, 2);
    const PseudoNormals normals(mesh);
    for (ShellMethod m : {ShellMethod::PseudoNormal, ShellMethod::Thin, ShellMethod::Offset, ShellMethod::Obb}) {
        TetrahedralShellOptions opt;
        opt.method = m;
        opt.epsilon = 0.1;
        TetrahedralShellStats stats;
        const auto a = buildTetrahedralShell(mesh, normals, opt, &stats);
        const auto b = buildTetrahedralShell(mesh, normals, opt);
        ASSERT_EQ(a.size(), b.size()) << toString(m);
        EXPECT_EQ(stats.faces, mesh.triangleCount());
        EXPECT_EQ(stats.tetrahedra, a.size());
        EXPECT_GE(stats.tetrahedraPerFace(), m == ShellMethod::Obb ? 5.0 : 4.0) << toString(m);
        std::vector<int> perFace(mesh.triangleCount(), 0);
        for (size_t i = 0; i < a.size(); ++i) {
            ASSERT_LT(a[i].triangle, mesh.triangleCount());
            ++perFace[a[i].triangle];
            EXPECT_EQ(a[i].triangle, b[i].triangle);
            for (int k = 0; k < 4; ++k) EXPECT_EQ(a[i].p[k], b[i].p[k]);
        }
        for (int c : perFace) EXPECT_GT(c, 0);
        // Every shell contains its own triangle (the face itself is always in the hull).
        for (uint32_t t = 0; t < mesh.triangleCount(); t += 7) {
            std::vector<Tetrahedron> own;
            for (const auto& tet : a)
                if (tet.triangle == t) own.push_back(tet);
            const Vec3I& tri = mesh.triangles[t];
            const Vec3d c = (mesh.points[tri[0]] + mesh.points[tri[1]] + mesh.points[tri[2]]) / 3.0;
            EXPECT_TRUE(insideAny(own, c, 1e-9)) << toString(m) << " face " << t;
        }
    }
    EXPECT_EQ(shellMethodFromString("thin"), ShellMethod::Thin);
    EXPECT_THROW(shellMethodFromString("prism"), InvalidArgumentError);
    TetrahedralShellOptions bad;
    bad.epsilon = 0.0;
    EXPECT_THROW(buildTetrahedralShell(mesh, normals, bad), InvalidArgumentError);
}

TEST(TetrahedralShell, SliceCasesMatchPointInTetrahedron)
{
    std::mt19937_64 rng(3);
    int cases[3] = {0, 0, 0};
    for (int trial = 0; trial < 300; ++trial) {
        Tetrahedron t;
        for (auto& p : t.p) p = Vec3d(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
        if (shell_internal::volume(t) < 1e-3) continue;
        std::array<double, 4> zs;
        for (int k = 0; k < 4; ++k) zs[k] = t.p[k][2];
        std::sort(zs.begin(), zs.end());
        for (int s = 0; s < 10; ++s) {
            const double z = uniform(rng, -1.1, 1.1);
            std::array<double, 4> x, y;
            const int n = scan_internal::sliceTetrahedron(t, z, x.data(), y.data());
            if (z < zs[0] || z > zs[3]) { EXPECT_EQ(n, 0); continue; }
            ASSERT_GE(n, 3);
            cases[z < zs[1] ? 0 : (z < zs[2] ? 1 : 2)]++;
            for (int q = 0; q < 30; ++q) {
                const Vec3d p(uniform(rng, -1, 1), uniform(rng, -1, 1), z);
                const bool a = insideTet(t, p, 0.0), b = insidePolygon(x, y, n, p[0], p[1]);
                if (a != b) {
                    // Only points within rounding of the boundary may disagree.
                    EXPECT_TRUE(insideTet(t, p, 1e-6) && !insideTet(t, p, -1e-6)) << "trial " << trial;
                }
            }
        }
    }
    EXPECT_GT(cases[0], 0);
    EXPECT_GT(cases[1], 0);
    EXPECT_GT(cases[2], 0);
}
