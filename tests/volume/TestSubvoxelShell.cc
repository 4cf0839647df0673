// SPDX-License-Identifier: Apache-2.0
// Sub-voxel shell (SubvoxelShell.h): closest points on the tetrahedral interpolation of analytic
// fields (sphere: < 0.05 voxel from the analytic distance; plane: exact), brute-force check of
// the window search, anisotropic spacing, the surface triangles, bad input.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/volume/SubvoxelShell.h>
#include <levelforge/core/TriangleDistance.h>

#include <cmath>
#include <iostream>
#include <limits>

using namespace levelforge;

namespace {

/// max |(|V| - |analytic|)| over the shell, in voxels of the smallest spacing
double shellError(const VectorVolume& v, const ScalarVolume& f, uint64_t& n)
{
    const double h = std::min({f.spacing[0], f.spacing[1], f.spacing[2]});
    double mx = 0;
    n = 0;
    for (size_t i = 0; i < v.data.size(); ++i) {
        if (!std::isfinite(v.data[i].d2)) continue;
        ++n;
        mx = std::max(mx, std::abs(std::sqrt(double(v.data[i].d2)) - std::abs(double(f.data[i]))) / h);
    }
    return mx;
}

} // namespace

TEST(SubvoxelShell, SphereFieldWithinFiveHundredthsOfAVoxel)
{
    for (double R : {10.0, 20.0, 28.0}) {
        const ScalarVolume f = makeSphereField(openvdb::Coord(64), Vec3d(31.3, 32.6, 31.8), R);
        SubvoxelShellOptions o;
        SubvoxelShellStats st;
        const VectorVolume v = subvoxelShell(f, o, &st);
        uint64_t n = 0;
        const double err = shellError(v, f, n);
        std::cout << "[ sphere R " << R << " ] shell " << n << " voxels, " << st.triangles
                  << " triangles, max error " << err << " voxel\n";
        EXPECT_GT(n, 1000u);
        EXPECT_EQ(n, st.shellVoxels);
        EXPECT_LT(err, 0.05) << R;
        // every voxel within one voxel of the sphere is in the shell
        for (size_t i = 0; i < f.data.size(); ++i)
            if (std::abs(f.data[i]) < 1.0f) ASSERT_TRUE(std::isfinite(v.data[i].d2)) << i;
    }
}

TEST(SubvoxelShell, LinearFieldIsExact)
{
    // f = n·x - c is reproduced exactly by linear interpolation: the surface is the plane
    const Vec3d nrm = Vec3d(0.3, -0.5, 0.81).unit();
    ScalarVolume f(openvdb::Coord(24), 0.0f);
    for (int k = 0; k < 24; ++k)
        for (int j = 0; j < 24; ++j)
            for (int i = 0; i < 24; ++i) f(i, j, k) = float(nrm.dot(Vec3d(i, j, k)) - 7.3);
    const VectorVolume v = subvoxelShell(f, {});
    // away from the volume's faces (where the plane is clipped) the closest point is the foot
    uint64_t n = 0;
    double mx = 0;
    for (int k = 4; k < 20; ++k)
        for (int j = 4; j < 20; ++j)
            for (int i = 4; i < 20; ++i) {
                const ClosestVector& c = v(i, j, k);
                if (!std::isfinite(c.d2)) continue;
                ++n;
                mx = std::max(mx, std::abs(std::sqrt(double(c.d2)) - std::abs(double(f(i, j, k)))));
            }
    EXPECT_LT(mx, 2e-4);
    EXPECT_GT(n, 300u);
    // the vectors point along -sign(f)·n
    for (size_t i = 0; i < v.data.size(); ++i) {
        const int x = int(i % 24), y = int((i / 24) % 24), z = int(i / 576);
        if (x < 4 || y < 4 || z < 4 || x >= 20 || y >= 20 || z >= 20) continue;
        if (!std::isfinite(v.data[i].d2) || std::abs(f.data[i]) < 0.1f) continue;
        const Vec3d d = Vec3d(v.data[i].x, v.data[i].y, v.data[i].z).unit();
        ASSERT_GT(-d.dot(nrm) * (f.data[i] > 0 ? 1 : -1), 0.999) << i;
    }
}

TEST(SubvoxelShell, WindowSearchFindsTheBruteForceClosestPoint)
{
    const ScalarVolume f = makeSphereField(openvdb::Coord(20, 22, 18), Vec3d(9.7, 10.2, 8.9), 6.3);
    const TriangleMesh surface = isoSurfaceTriangles(f, {});
    ASSERT_GT(surface.triangles.size(), 100u);
    const VectorVolume v = subvoxelShell(f, {});
    uint64_t checked = 0;
    for (int k = 0; k < f.dims.z(); ++k)
        for (int j = 0; j < f.dims.y(); ++j)
            for (int i = 0; i < f.dims.x(); ++i) {
                const ClosestVector& c = v(i, j, k);
                if (!std::isfinite(c.d2)) continue;
                const Vec3d p = f.worldPosition(i, j, k);
                double best = std::numeric_limits<double>::infinity();
                for (const Vec3I& t : surface.triangles)
                    best = std::min(best, closestPointOnTriangle(p, surface.points[t[0]], surface.points[t[1]],
                                                                 surface.points[t[2]]).distanceSqr);
                ASSERT_NEAR(std::sqrt(double(c.d2)), std::sqrt(best), 1e-5) << i << " " << j << " " << k;
                ++checked;
            }
    EXPECT_GT(checked, 500u);
    // the triangles lie on the interpolated surface: within the interpolation error of the sphere
    for (const Vec3d& p : surface.points) EXPECT_LT(std::abs((p - Vec3d(9.7, 10.2, 8.9)).length() - 6.3), 0.1);
}

TEST(SubvoxelShell, StronglyAnisotropicSpacingStillFindsTheClosestPoint)
{
    // CT-like spacing (0.5, 0.5, 5): the search window follows a world radius per axis
    const Vec3d spacing(0.5, 0.5, 5.0), c(7.6, 8.1, 20.3);
    const ScalarVolume f = makeSphereField(openvdb::Coord(32, 32, 9), c, 6.0, spacing);
    const TriangleMesh surface = isoSurfaceTriangles(f, {});
    const VectorVolume v = subvoxelShell(f, {});
    uint64_t checked = 0;
    for (int k = 0; k < f.dims.z(); ++k)
        for (int j = 0; j < f.dims.y(); j += 3)
            for (int i = 0; i < f.dims.x(); i += 3) {
                const ClosestVector& cv = v(i, j, k);
                if (!std::isfinite(cv.d2)) continue;
                const Vec3d p = f.worldPosition(i, j, k);
                double best = std::numeric_limits<double>::infinity();
                for (const Vec3I& t : surface.triangles)
                    best = std::min(best, closestPointOnTriangle(p, surface.points[t[0]], surface.points[t[1]],
                                                                 surface.points[t[2]]).distanceSqr);
                ASSERT_NEAR(std::sqrt(double(cv.d2)), std::sqrt(best), 1e-4) << i << " " << j << " " << k;
                ++checked;
            }
    EXPECT_GT(checked, 30u);
}

TEST(SubvoxelShell, AnisotropicSpacingIsExactInWorldUnits)
{
    const Vec3d spacing(1.0, 1.0, 2.5);
    const ScalarVolume f = makeSphereField(openvdb::Coord(48, 48, 20), Vec3d(23.6, 24.2, 24.7), 15.0, spacing);
    const VectorVolume v = subvoxelShell(f, {});
    uint64_t n = 0;
    const double err = shellError(v, f, n);
    std::cout << "[ anisotropic (1, 1, 2.5) ] shell " << n << ", max error " << err << " voxel\n";
    EXPECT_GT(n, 500u);
    EXPECT_LT(err, 0.12); // the coarse z spacing makes the interpolated sphere coarser
    // the stored offsets are in voxel units: world length recomputed from them equals sqrt(d2)
    for (const ClosestVector& c : v.data) {
        if (!std::isfinite(c.d2)) continue;
        const double w = std::sqrt(double(c.x) * c.x + double(c.y) * c.y + double(c.z * 2.5) * (c.z * 2.5));
        ASSERT_NEAR(w, std::sqrt(double(c.d2)), 1e-4);
    }
}

TEST(SubvoxelShell, InsideBelowFlipsTheInside)
{
    ScalarVolume f = makeSphereField(openvdb::Coord(24), Vec3d(11.5), 7.0);
    for (float& x : f.data) x = -x;
    SubvoxelShellOptions o;
    o.insideBelow = true;
    const MaskVolume in = insideFlags(f, o);
    EXPECT_EQ(in(12, 12, 12), 1);
    EXPECT_EQ(in(0, 0, 0), 0);
    uint64_t n = 0;
    EXPECT_LT(shellError(subvoxelShell(f, o), f, n), 0.05);
}

TEST(SubvoxelShell, BadVolumesGiveClearErrors)
{
    ScalarVolume f = makeSphereField(openvdb::Coord(8), Vec3d(3.5), 2.0);
    f(2, 3, 4) = std::numeric_limits<float>::quiet_NaN();
    try {
        subvoxelShell(f, {});
        FAIL() << "NaN accepted";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("(2, 3, 4)"), std::string::npos) << e.what();
    }
    EXPECT_THROW(subvoxelShell(ScalarVolume(), {}), InvalidArgumentError);
    ScalarVolume g = makeSphereField(openvdb::Coord(8), Vec3d(3.5), 2.0);
    g.spacing = Vec3d(1.0, 0.0, 1.0);
    EXPECT_THROW(subvoxelShell(g, {}), InvalidArgumentError);
}
