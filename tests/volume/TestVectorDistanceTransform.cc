// SPDX-License-Identifier: Apache-2.0
// Tests for VectorDistanceTransform.h against the exact EDT (ExactDistanceTransform.h, itself
// tested against brute force) and analytic distances: single seeds (binary and fractional), the
// paper's error wake (§3.2), the 80^3 sphere of Tables 5–6, sub-voxel planar shells, anisotropic
// spacing, thread-count determinism, a literal reading of the pass tables (bit for bit), bad
// inputs and interruption.
#include <levelforge/volume/VectorDistanceTransform.h>

#include <levelforge/volume/ChamferDistanceTransform.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/volume/ExactDistanceTransform.h>
#include <levelforge/volume/VolumeFeatures.h>

#include "volume/VectorDistanceTransformInternal.h" // pass tables, AVX2 switch

#include "TestUtil.h" // LF_SKIP_WITHOUT_AVX2

#include <gtest/gtest.h>

#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <map>
#include <set>
#include <tuple>

using namespace levelforge;

namespace {

constexpr VectorTransformMethod kMethods[] = {VectorTransformMethod::EVDT, VectorTransformMethod::EVDTFullGrid,
                                              VectorTransformMethod::VCVDT4, VectorTransformMethod::VCVDT8};
constexpr float kInf = std::numeric_limits<float>::infinity();

ScalarVolume transform(const VectorVolume& seeds, VectorTransformMethod m, int threads = 0)
{
    VectorVolume v = seeds;
    VectorTransformOptions o;
    o.method = m;
    o.threads = threads;
    vectorDistanceTransform(v, o);
    return vectorLength(v);
}

ScalarVolume transform(const MaskVolume& features, VectorTransformMethod m)
{
    return transform(initVectorVolume(features), m);
}

/// inside = |world position - centre| <= radius.
MaskVolume ball(const openvdb::Coord& dims, const openvdb::Vec3d& spacing, const openvdb::Vec3d& centre, double radius)
{
    MaskVolume in(dims, 0, spacing);
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i)
                in(i, j, k) = (in.worldPosition(i, j, k) - centre).length() <= radius ? 1 : 0;
    return in;
}

ClosestVector seedVector(const openvdb::Vec3d& v, const openvdb::Vec3d& spacing)
{
    const float x = float(v[0]), y = float(v[1]), z = float(v[2]);
    return ClosestVector{x, y, z, vectorLengthSquared(x, y, z, openvdb::Vec3f(spacing))};
}

/// One seed in every `every` voxels on average, at random voxels: binary (zero vectors) or
/// fractional (sub-voxel offsets in [-0.5, 0.5)).
VectorVolume randomSeeds(const openvdb::Coord& dims, const openvdb::Vec3d& sp, bool fractional, size_t every,
                         std::mt19937& rng)
{
    std::uniform_real_distribution<float> frac(-0.5f, 0.5f);
    VectorVolume seeds(dims, ClosestVector{kInf, kInf, kInf, kInf}, sp);
    std::uniform_int_distribution<size_t> pick(0, seeds.data.size() - 1);
    const int n = std::max<int>(1, int(seeds.data.size() / every));
    for (int i = 0; i < n; ++i) {
        ClosestVector& c = seeds.data[pick(rng)];
        if (fractional) c = seedVector(openvdb::Vec3d(frac(rng), frac(rng), frac(rng)), sp);
        else c = ClosestVector{0.f, 0.f, 0.f, 0.f};
    }
    return seeds;
}

/// Calls run(options) for method m with `lanes` lanes, in an arena (and global_control) of that size.
template<class Run>
void withLanes(VectorTransformMethod m, int lanes, openvdb::util::NullInterrupter* interrupter, const Run& run)
{
    tbb::global_control allow(tbb::global_control::max_allowed_parallelism, size_t(lanes));
    tbb::task_arena arena(lanes);
    arena.execute([&] {
        VectorTransformOptions o;
        o.method = m;
        o.threads = lanes;
        o.interrupter = interrupter;
        run(o);
    });
}

/// Transforms v in place with `lanes` lanes.
void transformWithLanes(VectorVolume& v, VectorTransformMethod m, int lanes, VectorTransformStats* st = nullptr,
                        openvdb::util::NullInterrupter* interrupter = nullptr)
{
    withLanes(m, lanes, interrupter, [&](const VectorTransformOptions& o) { vectorDistanceTransform(v, o, st); });
}

} // namespace

TEST(VectorDistanceTransform, InitAndLength)
{
    MaskVolume f(openvdb::Coord(3, 2, 2), 0, openvdb::Vec3d(1, 2, 3), openvdb::Vec3d(-1, 0, 1));
    f(1, 1, 0) = 1;
    const VectorVolume v = initVectorVolume(f);
    EXPECT_EQ(v.dims, f.dims);
    EXPECT_EQ(v.spacing, f.spacing);
    EXPECT_EQ(v.origin, f.origin);
    EXPECT_EQ(v(1, 1, 0).d2, 0.0f);
    EXPECT_EQ(v(1, 1, 0).x, 0.0f);
    EXPECT_TRUE(std::isinf(v(0, 0, 0).x) && std::isinf(v(0, 0, 0).d2));
    const ScalarVolume l = vectorLength(v);
    EXPECT_EQ(l(1, 1, 0), 0.0f);
    EXPECT_TRUE(std::isinf(l(2, 1, 1)));
}

TEST(VectorDistanceTransform, SingleSeedsAreExact)
{
    // One binary feature: every method reaches every voxel with that feature's vector.
    MaskVolume f(openvdb::Coord(14, 11, 9), 0, openvdb::Vec3d(1.0, 1.5, 0.75));
    f(9, 3, 6) = 1;
    const ScalarVolume exact = exactDistanceTransform(f);
    // One fractional seed: the stored vectors must point at the same world point everywhere.
    VectorVolume frac(f.dims, ClosestVector{kInf, kInf, kInf, kInf}, f.spacing);
    const openvdb::Vec3d off(0.3, -0.45, 0.2);
    frac(4, 7, 2) = seedVector(off, f.spacing);
    for (VectorTransformMethod m : kMethods) {
        const auto c = compareDistanceFields(transform(f, m), exact);
        EXPECT_EQ(c.voxelsWithError, 0u) << vectorTransformMethodName(m);
        VectorVolume v = frac;
        VectorTransformOptions o;
        o.method = m;
        VectorTransformStats st;
        vectorDistanceTransform(v, o, &st);
        EXPECT_EQ(st.seeds, 1u);
        EXPECT_EQ(st.unreached, 0u);
        for (int k = 0; k < 9; ++k)
            for (int j = 0; j < 11; ++j)
                for (int i = 0; i < 14; ++i) {
                    const ClosestVector& cv = v(i, j, k);
                    // p + v = the seed point (4, 7, 2) + off, in voxel units
                    ASSERT_NEAR(i + cv.x, 4 + off[0], 1e-5) << vectorTransformMethodName(m);
                    ASSERT_NEAR(j + cv.y, 7 + off[1], 1e-5);
                    ASSERT_NEAR(k + cv.z, 2 + off[2], 1e-5);
                    const openvdb::Vec3d w((4 + off[0] - i) * 1.0, (7 + off[1] - j) * 1.5, (2 + off[2] - k) * 0.75);
                    ASSERT_NEAR(std::sqrt(cv.d2), w.length(), 1e-5 * std::max(1.0, w.length()));
                }
    }
}

// §3.2 / Fig. 12: three feature voxels on a diagonal (in the direction the passes run) in one
// z-plane. The middle feature's Voronoi tile in that plane is the anti-diagonal x + y = 12, one
// voxel thin and only diagonally connected; the error wake lives there.
TEST(VectorDistanceTransform, ErrorWakeOfTheTwoSliceEVDT)
{
    const int n = 16;
    MaskVolume f(openvdb::Coord(n), 0);
    f(5, 5, 8) = f(6, 6, 8) = f(7, 7, 8) = 1;
    const ScalarVolume exact = exactDistanceTransform(f);
    std::map<VectorTransformMethod, std::set<std::tuple<int, int, int>>> wrong;
    for (VectorTransformMethod m : kMethods) {
        const ScalarVolume d = transform(f, m);
        for (int k = 0; k < n; ++k)
            for (int j = 0; j < n; ++j)
                for (int i = 0; i < n; ++i) {
                    const float e = d(i, j, k) - exact(i, j, k);
                    ASSERT_GE(e, -1e-5f); // vectors point at real features: never too short
                    if (e > 1e-4f) {
                        wrong[m].insert({i, j, k});
                        EXPECT_EQ(i + j, 12) << vectorTransformMethodName(m) << " at " << i << "," << j << "," << k;
                    }
                }
    }
    const auto& evdt = wrong[VectorTransformMethod::EVDT];
    const auto& full = wrong[VectorTransformMethod::EVDTFullGrid];
    // Two vector slices: the backward sweep never sees the forward sweep's vectors; the wake
    // runs off the line in every slice except the feature plane itself.
    EXPECT_EQ(evdt.size(), 60u);
    for (const auto& p : evdt) EXPECT_NE(std::get<2>(p), 8);
    // The same six passes on the full grid make different errors: the storage is the cause.
    EXPECT_NE(evdt, full);
    // Our reading of the 4-neighbour masks cannot enter the one-voxel-thin diagonal tile far
    // from the line (Danielsson's 4SED limitation): EVDT full grid and VCVDT4 miss it in
    // every slice (4 resp. 8 columns of 16), while the 8-pass VCVDT is exact.
    EXPECT_EQ(full.size(), 64u);
    EXPECT_EQ(wrong[VectorTransformMethod::VCVDT4].size(), 128u);
    EXPECT_TRUE(wrong[VectorTransformMethod::VCVDT8].empty());

    // The anti-diagonal arrangement (against the pass direction) makes no error at all.
    MaskVolume g(openvdb::Coord(n), 0);
    g(7, 5, 8) = g(6, 6, 8) = g(5, 7, 8) = 1;
    const ScalarVolume exactG = exactDistanceTransform(g);
    for (VectorTransformMethod m : kMethods)
        EXPECT_EQ(compareDistanceFields(transform(g, m), exactG).voxelsWithError, 0u) << vectorTransformMethodName(m);

    // Four features: the two-slice wake grows beyond the full-grid error.
    f(8, 8, 8) = 1;
    const ScalarVolume exact4 = exactDistanceTransform(f);
    const auto e4 = compareDistanceFields(transform(f, VectorTransformMethod::EVDT), exact4);
    const auto f4 = compareDistanceFields(transform(f, VectorTransformMethod::EVDTFullGrid), exact4);
    EXPECT_GT(e4.maxError, 1.5f * f4.maxError);
    EXPECT_GT(e4.averageErrorPerVoxel, f4.averageErrorPerVoxel);
}

// Tables 5 and 6: the 80^3 sphere (Table 3: 80^3; we take centre 39.5, radius 29.5, whose
// exact distance range ends at the paper's 39.268), features = transverse voxels, signed by
// Eq. 5-6, average error per voxel against the signed exact EDT.
TEST(VectorDistanceTransform, SphereAccuracyAgainstPaperTables)
{
    const MaskVolume inside = ball(openvdb::Coord(80), openvdb::Vec3d(1.0), openvdb::Vec3d(39.5), 29.5);
    const MaskVolume f = transverseFeatures(inside);
    const DenseVolume<int8_t> sign = classification(inside, f);
    const ScalarVolume exact = applySign(exactDistanceTransform(f), sign);
    std::map<VectorTransformMethod, DistanceTransformComparison> r;
    for (VectorTransformMethod m : kMethods) {
        r[m] = compareDistanceFields(applySign(transform(f, m), sign), exact);
        std::printf("[ sphere 80^3 ] %-13s avg %.6f  error [%.3f, %.3f]  distance [%.3f, %.3f]\n",
                    vectorTransformMethodName(m), r[m].averageErrorPerVoxel, r[m].minError, r[m].maxError,
                    r[m].minDistance, r[m].maxDistance);
    }
    EXPECT_NEAR(exact.data[0], 39.268f, 1e-3f);
    EXPECT_LE(r[VectorTransformMethod::EVDTFullGrid].averageErrorPerVoxel, 0.005282); // Table 5
    EXPECT_LE(r[VectorTransformMethod::VCVDT4].averageErrorPerVoxel, 0.002734);       // Table 5
    // Table 6 gives 0.000559 for its sphere; ours measures 0.000687 (the paper's sphere is not
    // specified exactly; the centre 40 / radius 27.5 sphere gives 0.000542). Within 25 %:
    EXPECT_LE(r[VectorTransformMethod::VCVDT8].averageErrorPerVoxel, 1.25 * 0.000559);
    EXPECT_GE(r[VectorTransformMethod::VCVDT8].minError, -0.27f); // Table 6: -0.268 .. 0.268
    EXPECT_LE(r[VectorTransformMethod::VCVDT8].maxError, 0.27f);
    // The paper's ordering: full grid beats two slices, 8 passes beat everything.
    EXPECT_LT(r[VectorTransformMethod::EVDTFullGrid].averageErrorPerVoxel, r[VectorTransformMethod::EVDT].averageErrorPerVoxel);
    EXPECT_LT(r[VectorTransformMethod::VCVDT8].averageErrorPerVoxel, r[VectorTransformMethod::EVDTFullGrid].averageErrorPerVoxel);
    EXPECT_LT(r[VectorTransformMethod::VCVDT8].averageErrorPerVoxel, r[VectorTransformMethod::VCVDT4].averageErrorPerVoxel);
}

TEST(VectorDistanceTransform, SubVoxelShellAxisAlignedPlaneIsExact)
{
    // Plane x = 10.3 voxels; shell = voxels within 1.5 voxels, each holding its exact closest
    // point. Every voxel's closest point is reached along x: all methods are exact.
    for (const openvdb::Vec3d& s : {openvdb::Vec3d(1.0), openvdb::Vec3d(0.8, 1.0, 2.5)}) {
        VectorVolume v(openvdb::Coord(24, 9, 7), ClosestVector{kInf, kInf, kInf, kInf}, s);
        for (int k = 0; k < 7; ++k)
            for (int j = 0; j < 9; ++j)
                for (int i = 9; i <= 11; ++i) v(i, j, k) = seedVector(openvdb::Vec3d(10.3 - i, 0, 0), s);
        for (VectorTransformMethod m : kMethods) {
            const ScalarVolume d = transform(v, m);
            for (int k = 0; k < 7; ++k)
                for (int j = 0; j < 9; ++j)
                    for (int i = 0; i < 24; ++i) ASSERT_NEAR(d(i, j, k), std::abs(10.3 - i) * s[0], 2e-5);
        }
    }
}

TEST(VectorDistanceTransform, SubVoxelShellTiltedPlane)
{
    // A tilted plane; shell = voxels within 1 voxel, with exact closest points (fractional
    // vectors). Propagated distances never undercut the plane distance, and exceed it only by
    // the discreteness of the seed set (closest seed vs foot point: about t^2 / 2d).
    const openvdb::Coord dims(40, 36, 32);
    openvdb::Vec3d n(1.0, 0.4, 0.25);
    n.normalize();
    const double c0 = 14.8;
    VectorVolume v(dims, ClosestVector{kInf, kInf, kInf, kInf});
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i) {
                const double d = n.dot(openvdb::Vec3d(i, j, k)) - c0;
                if (std::abs(d) <= 1.0) v(i, j, k) = seedVector(-d * n, v.spacing);
            }
    for (VectorTransformMethod m : {VectorTransformMethod::EVDTFullGrid, VectorTransformMethod::VCVDT8}) {
        const ScalarVolume dist = transform(v, m);
        double sum = 0, mx = 0;
        uint64_t count = 0;
        for (int k = 0; k < dims.z(); ++k)
            for (int j = 0; j < dims.y(); ++j)
                for (int i = 0; i < dims.x(); ++i) {
                    const openvdb::Vec3d p(i, j, k);
                    const double dp = n.dot(p) - c0;
                    const openvdb::Vec3d foot = p - dp * n;
                    const double e = dist(i, j, k) - std::abs(dp);
                    ASSERT_GE(e, -1e-4);
                    if (foot[0] < 1 || foot[1] < 1 || foot[2] < 1 || foot[0] > dims.x() - 2 ||
                        foot[1] > dims.y() - 2 || foot[2] > dims.z() - 2)
                        continue; // the closest plane point is outside the volume: no seed there
                    sum += e;
                    mx = std::max(mx, e);
                    ++count;
                }
        EXPECT_GT(count, 20000u);
        EXPECT_LT(mx, 0.25) << vectorTransformMethodName(m);
        EXPECT_LT(sum / double(count), 0.05) << vectorTransformMethodName(m); // measured 0.035
    }
}

TEST(VectorDistanceTransform, AnisotropicSpacing)
{
    const openvdb::Vec3d s(1.0, 1.0, 2.5);
    const MaskVolume inside = ball(openvdb::Coord(48, 48, 20), s, openvdb::Vec3d(23.5, 23.5, 23.75), 17.0);
    const MaskVolume f = transverseFeatures(inside);
    const ScalarVolume exact = exactDistanceTransform(f);
    for (VectorTransformMethod m : kMethods) {
        const auto c = compareDistanceFields(transform(f, m), exact);
        EXPECT_GE(c.minError, -1e-4f) << vectorTransformMethodName(m);
        EXPECT_LT(c.maxError, 0.7f) << vectorTransformMethodName(m);
        EXPECT_LT(c.averageErrorPerVoxel, 0.007) << vectorTransformMethodName(m);
    }
    const auto c8 = compareDistanceFields(transform(f, VectorTransformMethod::VCVDT8), exact);
    EXPECT_LT(c8.maxError, 0.28f);
    EXPECT_LT(c8.averageErrorPerVoxel, 0.001);
    // Ignoring the spacing would be far off: the same mask with unit spacing differs a lot.
    MaskVolume iso = f;
    iso.spacing = openvdb::Vec3d(1.0);
    EXPECT_GT(compareDistanceFields(transform(iso, VectorTransformMethod::VCVDT8), exact).averageErrorPerVoxel, 0.5);
}

TEST(VectorDistanceTransform, BitIdenticalForAnyThreadCount)
{
    // A fractional shell (sphere surface closest points) in a volume with wide slices.
    const openvdb::Coord dims(96, 64, 24);
    const openvdb::Vec3d s(1.0, 1.1, 1.7), centre(45.3, 30.1, 20.2);
    VectorVolume seeds(dims, ClosestVector{kInf, kInf, kInf, kInf}, s);
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i) {
                const openvdb::Vec3d p = seeds.worldPosition(i, j, k), d = p - centre;
                const double r = d.length();
                if (std::abs(r - 15.0) <= 1.8) {
                    const openvdb::Vec3d foot = centre + d * (15.0 / r);
                    const openvdb::Vec3d w = foot - p;
                    seeds(i, j, k) = seedVector(openvdb::Vec3d(w[0] / s[0], w[1] / s[1], w[2] / s[2]), s);
                }
            }
    for (VectorTransformMethod m : {VectorTransformMethod::VCVDT4, VectorTransformMethod::VCVDT8}) {
        VectorVolume ref = seeds;
        {
            tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
            VectorTransformOptions one;
            one.method = m;
            one.threads = 0; // automatic: all the threads global_control allows (here 1)
            VectorTransformStats st;
            vectorDistanceTransform(ref, one, &st);
            EXPECT_EQ(st.lanes, 1);
        }
        for (int lanes : {2, 3}) { // more lanes than cores only makes the spin-waits slow
            VectorVolume v = seeds;
            VectorTransformStats st;
            transformWithLanes(v, m, lanes, &st);
            EXPECT_EQ(st.lanes, lanes);
            ASSERT_EQ(0, std::memcmp(v.data.data(), ref.data.data(), ref.data.size() * sizeof(ClosestVector)))
                << vectorTransformMethodName(m) << " lanes " << lanes;
        }
    }
}

TEST(VectorDistanceTransform, Avx2KernelMatchesTheBaselineBitForBit)
{
    // The AVX2 build of the kernel (x86-64 CPUs with AVX2) must reproduce the baseline build
    // exactly, for every method: odd and tiny dims, unit and anisotropic spacing, binary and
    // fractional seeds, 1..3 lanes. Without AVX2 that would compare the baseline with itself
    // (and with its wavefront): skipped, visibly.
    LF_SKIP_WITHOUT_AVX2();
    ASSERT_TRUE(vector_transform_internal::avx2KernelAvailable()) << "the CPU has AVX2 but the library does not use its AVX2 build";
    std::mt19937 rng(2026);
    const openvdb::Coord dimsList[] = {openvdb::Coord(1, 1, 1),   openvdb::Coord(5, 3, 4),   openvdb::Coord(8, 8, 8),
                                       openvdb::Coord(9, 17, 5),  openvdb::Coord(23, 7, 11), openvdb::Coord(40, 33, 9),
                                       openvdb::Coord(131, 19, 6)};
    const openvdb::Vec3d spacings[] = {openvdb::Vec3d(1.0), openvdb::Vec3d(0.7, 1.3, 1.1), openvdb::Vec3d(2.5)};
    for (const auto& dims : dimsList)
        for (const auto& sp : spacings)
            for (bool fractional : {false, true}) {
                const VectorVolume seeds = randomSeeds(dims, sp, fractional, 97, rng);
                for (VectorTransformMethod m : kMethods) {
                    VectorVolume ref = seeds;
                    vector_transform_internal::setAvx2KernelEnabled(false);
                    {
                        VectorTransformOptions o;
                        o.method = m;
                        o.threads = 1;
                        vectorDistanceTransform(ref, o);
                    }
                    vector_transform_internal::setAvx2KernelEnabled(true);
                    for (int lanes : {1, 2, 3}) {
                        VectorVolume v = seeds;
                        transformWithLanes(v, m, lanes);
                        ASSERT_EQ(0, std::memcmp(v.data.data(), ref.data.data(), ref.data.size() * sizeof(ClosestVector)))
                            << vectorTransformMethodName(m) << " dims " << dims << " spacing " << sp << " fractional "
                            << fractional << " lanes " << lanes
                            << " avx2 " << vector_transform_internal::avx2KernelAvailable();
                    }
                }
            }
}

namespace {

/// The pass tables read literally (VectorDistanceTransform.h): every sweep, slice, pass (each
/// perRow pass right after its pass on the same row) and voxel in raster order; each listed
/// neighbour inside the volume gives the candidate V(q) + o, which replaces V(p) when its
/// d2 = X*X + (Y*Y + Z*Z) is strictly smaller. No layout tricks, no lanes, no SIMD.
void referenceSweep(VectorVolume& v, const vector_transform_internal::SweepDef& sw)
{
    const int nx = v.dims.x(), ny = v.dims.y(), nz = v.dims.z();
    const float sx = float(v.spacing[0]), sy = float(v.spacing[1]), sz = float(v.spacing[2]);
    auto runRow = [&](const vector_transform_internal::PassDef& p, int y, int z) {
        for (int k = 0; k < nx; ++k) {
            const int x = p.xOrder > 0 ? k : nx - 1 - k;
            ClosestVector& c = v(x, y, z);
            for (int i = 0; i < p.neighbourCount; ++i) {
                const auto& o = p.neighbours[i];
                const int qx = x + o.x, qy = y + o.y, qz = z + o.z;
                if (qx < 0 || qy < 0 || qz < 0 || qx >= nx || qy >= ny || qz >= nz) continue;
                const ClosestVector n = v(qx, qy, qz);
                const float cx = n.x + float(o.x), cy = n.y + float(o.y), cz = n.z + float(o.z);
                const float X = cx * sx, Y = cy * sy, Z = cz * sz;
                const float d2 = X * X + (Y * Y + Z * Z);
                if (d2 < c.d2) c = ClosestVector{cx, cy, cz, d2};
            }
        }
    };
    for (int i = 0; i < nz; ++i) {
        const int z = sw.zOrder > 0 ? i : nz - 1 - i;
        for (int p = 0; p < sw.passCount; ++p) {
            if (sw.passes[p].perRow) continue;
            for (int r = 0; r < ny; ++r) {
                const int y = sw.passes[p].yOrder > 0 ? r : ny - 1 - r;
                runRow(sw.passes[p], y, z);
                for (int q = p + 1; q < sw.passCount && sw.passes[q].perRow; ++q) runRow(sw.passes[q], y, z);
            }
        }
    }
}

VectorVolume referenceTransform(const VectorVolume& seeds, VectorTransformMethod method)
{
    const auto& m = vector_transform_internal::methodDef(method);
    if (!m.twoSlices) {
        VectorVolume v = seeds;
        referenceSweep(v, m.sweeps[0]);
        referenceSweep(v, m.sweeps[1]);
        return v;
    }
    VectorVolume f = seeds, b = seeds; // each sweep from the input, the shorter vector wins
    referenceSweep(f, m.sweeps[0]);
    referenceSweep(b, m.sweeps[1]);
    for (size_t i = 0; i < f.data.size(); ++i)
        if (b.data[i].d2 < f.data[i].d2) f.data[i] = b.data[i];
    return f;
}

} // namespace

TEST(VectorDistanceTransform, MatchesALiteralReadingOfThePassTables)
{
    // The optimised transform (grouped layout, SIMD candidates, column lanes) must give exactly
    // the bits of the literal raster order, for every method, row widths around the group size
    // of 8, fractional seeds, anisotropic spacing and 1..3 lanes.
    std::mt19937 rng(7);
    const openvdb::Coord dimsList[] = {openvdb::Coord(1, 1, 1),  openvdb::Coord(7, 5, 4),   openvdb::Coord(8, 3, 3),
                                       openvdb::Coord(9, 17, 5), openvdb::Coord(35, 6, 7),  openvdb::Coord(100, 9, 12),
                                       openvdb::Coord(131, 19, 6)};
    const openvdb::Vec3d spacings[] = {openvdb::Vec3d(1.0), openvdb::Vec3d(0.6, 1.7, 1.2)};
    for (const auto& dims : dimsList)
        for (const auto& sp : spacings)
            for (bool fractional : {false, true}) {
                const VectorVolume seeds = randomSeeds(dims, sp, fractional, 61, rng);
                for (VectorTransformMethod m : kMethods) {
                    const VectorVolume ref = referenceTransform(seeds, m);
                    for (int lanes : {1, 2, 3}) {
                        VectorVolume v = seeds;
                        transformWithLanes(v, m, lanes);
                        ASSERT_EQ(0, std::memcmp(v.data.data(), ref.data.data(), ref.data.size() * sizeof(ClosestVector)))
                            << vectorTransformMethodName(m) << " dims " << dims << " spacing " << sp << " fractional "
                            << fractional << " lanes " << lanes;
                    }
                }
            }
}

TEST(VectorDistanceTransform, InterruptionLeavesWholeVectors)
{
    // The transform reorders rows into a grouped working layout as it goes; stopped part-way
    // (forward or backward sweep, 1 or 2 lanes) it must still leave whole ClosestVectors: every
    // finite vector with its own squared length, every other voxel all +inf.
    MaskVolume features(openvdb::Coord(70, 23, 12), 0);
    features(5, 7, 3) = 1;
    features(61, 20, 9) = 1;
    const VectorVolume seeds = initVectorVolume(features);
    struct StopAt : openvdb::util::NullInterrupter
    {
        std::atomic<int> calls{0}; // polled from the lanes too
        int at = 0;
        bool wasInterrupted(int) override { return ++calls >= at; }
    };
    for (VectorTransformMethod m : kMethods)
        for (int at : {2, 5, 15, 20})
            for (int lanes : {1, 2}) {
                VectorVolume v = seeds;
                StopAt stop;
                stop.at = at;
                EXPECT_THROW(transformWithLanes(v, m, lanes, nullptr, &stop), InterruptedError)
                    << vectorTransformMethodName(m);
                size_t finite = 0;
                for (const ClosestVector& c : v.data) {
                    if (std::isinf(c.d2)) {
                        ASSERT_TRUE(std::isinf(c.x) && std::isinf(c.y) && std::isinf(c.z));
                        continue;
                    }
                    ++finite;
                    ASSERT_EQ(c.d2, vectorLengthSquared(c.x, c.y, c.z, openvdb::Vec3f(1.0f)))
                        << vectorTransformMethodName(m) << " stopped at call " << at << ", lanes " << lanes;
                }
                EXPECT_GE(finite, 2u);
            }
}

TEST(VectorDistanceTransform, MaskEntryMatchesTheVectorVolumeRouteBitForBit)
{
    // vectorDistanceTransform(MaskVolume) keeps 16-bit integer vectors between the sweeps and
    // recomputes d2; it must give exactly vectorLength() of the in-place transform: every method,
    // row widths around the group size, unit and anisotropic spacing, 1-3 lanes, the stats too.
    std::mt19937 rng(7);
    struct Case
    {
        openvdb::Coord dims;
        openvdb::Vec3d spacing;
        size_t every; // one feature voxel per `every` voxels
    };
    const Case cases[] = {{openvdb::Coord(1, 1, 1), openvdb::Vec3d(1), 1},
                          {openvdb::Coord(7, 5, 3), openvdb::Vec3d(1), 40},
                          {openvdb::Coord(37, 9, 11), openvdb::Vec3d(0.7, 1.3, 2.1), 150},
                          {openvdb::Coord(131, 19, 6), openvdb::Vec3d(1), 4000},
                          {openvdb::Coord(64, 33, 17), openvdb::Vec3d(1.0, 1.0, 2.5), 300}};
    for (const Case& c : cases) {
        MaskVolume f(c.dims, 0, c.spacing);
        std::uniform_int_distribution<size_t> pick(0, f.data.size() - 1);
        for (size_t i = 0; i < std::max<size_t>(1, f.data.size() / c.every); ++i) f.data[pick(rng)] = 1;
        for (VectorTransformMethod m : kMethods)
            for (int lanes : {1, 2, 3}) {
                VectorVolume v = initVectorVolume(f);
                VectorTransformStats ref;
                transformWithLanes(v, m, lanes, &ref);
                const ScalarVolume expected = vectorLength(v);
                VectorTransformStats st;
                ScalarVolume d;
                withLanes(m, lanes, nullptr, [&](const VectorTransformOptions& o) { d = vectorDistanceTransform(f, o, &st); });
                ASSERT_EQ(d.dims, f.dims);
                ASSERT_EQ(d.spacing, f.spacing);
                ASSERT_EQ(d.data.size(), expected.data.size());
                ASSERT_EQ(0, std::memcmp(d.data.data(), expected.data.data(), d.data.size() * sizeof(float)))
                    << vectorTransformMethodName(m) << " dims " << c.dims << " lanes " << lanes;
                EXPECT_EQ(st.seeds, ref.seeds);
                EXPECT_EQ(st.unreached, ref.unreached);
                EXPECT_EQ(st.lanes, ref.lanes);
                EXPECT_EQ(st.voxels, f.voxelCount());
            }
    }
    // No feature at all: everything unreached, +inf.
    MaskVolume none(openvdb::Coord(9, 4, 3), 0);
    VectorTransformStats st;
    const ScalarVolume d = vectorDistanceTransform(none, VectorTransformOptions(), &st);
    EXPECT_EQ(st.unreached, none.voxelCount());
    for (float x : d.data) EXPECT_EQ(x, kInf);
}

TEST(VectorDistanceTransform, MaskEntryReachesEveryVoxelOfALongLine)
{
    // Vectors as long as the volume (|x| = 2999 with one feature at the end of a 3000-voxel row)
    // must survive the 16-bit store exactly.
    MaskVolume f(openvdb::Coord(3000, 2, 2), 0);
    f(2999, 1, 1) = 1;
    const ScalarVolume d = vectorDistanceTransform(f);
    ASSERT_EQ(0, std::memcmp(d.data.data(), transform(f, VectorTransformMethod::VCVDT8).data.data(),
                             d.data.size() * sizeof(float)));
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 3000; i += 7) {
                const double dx = 2999 - i, dy = 1 - j, dz = 1 - k;
                EXPECT_NEAR(d(i, j, k), std::sqrt(dx * dx + dy * dy + dz * dz), 1e-3) << i << " " << j << " " << k;
            }
}

TEST(VectorDistanceTransform, NoSeedsStayInfinite)
{
    VectorVolume v(openvdb::Coord(5, 6, 7), ClosestVector{kInf, kInf, kInf, kInf});
    for (VectorTransformMethod m : kMethods) {
        VectorVolume w = v;
        VectorTransformOptions o;
        o.method = m;
        VectorTransformStats st;
        vectorDistanceTransform(w, o, &st);
        EXPECT_EQ(st.unreached, w.voxelCount());
        for (const auto& c : w.data) EXPECT_TRUE(std::isinf(c.d2));
    }
}

TEST(VectorDistanceTransform, BadInputsAndInterrupt)
{
    VectorVolume empty;
    EXPECT_THROW(vectorDistanceTransform(empty), InvalidArgumentError);
    EXPECT_THROW(initVectorVolume(MaskVolume()), InvalidArgumentError);
    VectorVolume v = initVectorVolume(MaskVolume(openvdb::Coord(4), 1));
    v.spacing = openvdb::Vec3d(1, 1, 0);
    EXPECT_THROW(vectorDistanceTransform(v), InvalidArgumentError);
    v.spacing = openvdb::Vec3d(std::nan(""), 1, 1);
    EXPECT_THROW(vectorDistanceTransform(v), InvalidArgumentError);
    v.spacing = openvdb::Vec3d(1);
    v.data.pop_back();
    EXPECT_THROW(vectorDistanceTransform(v), InvalidArgumentError);
    EXPECT_THROW(vectorLength(v), InvalidArgumentError);
    EXPECT_THROW(vectorDistanceTransform(MaskVolume()), InvalidArgumentError);
    MaskVolume badMask(openvdb::Coord(4), 1, openvdb::Vec3d(1, -1, 1));
    EXPECT_THROW(vectorDistanceTransform(badMask), InvalidArgumentError);

    struct Stop : openvdb::util::NullInterrupter
    {
        bool wasInterrupted(int) override { return true; }
    } stop;
    for (VectorTransformMethod m : kMethods) {
        VectorVolume w = initVectorVolume(MaskVolume(openvdb::Coord(6), 1));
        VectorTransformOptions o;
        o.method = m;
        o.interrupter = &stop;
        EXPECT_THROW(vectorDistanceTransform(w, o), InterruptedError) << vectorTransformMethodName(m);
        EXPECT_THROW(vectorDistanceTransform(MaskVolume(openvdb::Coord(6), 1), o), InterruptedError)
            << vectorTransformMethodName(m);
    }
}
