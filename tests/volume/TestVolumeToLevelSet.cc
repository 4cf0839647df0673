// SPDX-License-Identifier: Apache-2.0
// volumeToLevelSet / volumeSignedDistance: every method in a loop against the exact field
// (binary: exact EDT; sub-voxel: analytic sphere), signs, band, anisotropic transforms, bad
// options, and the volume-to-sdf / dt-report CLI.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/io/VolumeIO.h>
#include <levelforge/volume/VolumeToLevelSet.h>

#include <openvdb/tools/LevelSetSphere.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>

using namespace levelforge;

TEST(VolumeToLevelSet, SubvoxelVectorMethodsMatchTheAnalyticSphere)
{
    const Vec3d c(31.4, 32.3, 30.8);
    const double R = 24.0;
    const ScalarVolume f = makeSphereField(openvdb::Coord(64), c, R);
    for (VolumeDistanceMethod m : {VolumeDistanceMethod::EVDTFullGrid, VolumeDistanceMethod::VCVDT4,
                                   VolumeDistanceMethod::VCVDT8, VolumeDistanceMethod::Exact}) {
        VolumeToLevelSetOptions o;
        o.method = m;
        o.subvoxel = true;
        const ScalarVolume d = volumeSignedDistance(f, o);
        double sum = 0, mx = 0;
        uint64_t sign = 0;
        for (size_t i = 0; i < d.data.size(); ++i) {
            const double exact = -double(f.data[i]); // negative inside
            const double e = std::abs(d.data[i] - exact);
            sum += e;
            mx = std::max(mx, e);
            if (std::abs(exact) > 0.1 && (exact < 0) != (d.data[i] < 0)) ++sign;
        }
        const double mean = sum / double(d.data.size());
        std::cout << "[ " << volumeDistanceMethodName(m) << " sub-voxel, sphere R 24 in 64^3 ] mean " << mean
                  << " max " << mx << " voxel\n";
        EXPECT_EQ(sign, 0u);
        EXPECT_LT(mean, 0.05) << volumeDistanceMethodName(m);
        EXPECT_LT(mx, 0.6) << volumeDistanceMethodName(m); // Voronoi-corner errors (paper §3.2)
    }
}

TEST(VolumeToLevelSet, BinaryMethodsAgainstTheExactEdt)
{
    const ScalarVolume f = makeSphereField(openvdb::Coord(48), Vec3d(23.3, 24.1, 23.7), 15.0);
    VolumeToLevelSetOptions o;
    o.subvoxel = false;
    o.method = VolumeDistanceMethod::Exact;
    const ScalarVolume exact = volumeSignedDistance(f, o);
    struct Bound { VolumeDistanceMethod m; double mean; };
    // the chamfer metrics overestimate (city-block most); the vector transforms are nearly exact
    for (const Bound& b : {Bound{VolumeDistanceMethod::CityBlock, 6.0}, Bound{VolumeDistanceMethod::Chessboard, 4.0},
                           Bound{VolumeDistanceMethod::QuasiEuclidean3, 2.0}, Bound{VolumeDistanceMethod::Complete3, 1.0},
                           Bound{VolumeDistanceMethod::QuasiEuclidean5, 0.3}, Bound{VolumeDistanceMethod::EVDT, 0.01},
                           Bound{VolumeDistanceMethod::EVDTFullGrid, 0.005}, Bound{VolumeDistanceMethod::VCVDT4, 0.005},
                           Bound{VolumeDistanceMethod::VCVDT8, 0.003}}) {
        o.method = b.m;
        const ScalarVolume d = volumeSignedDistance(f, o);
        double sum = 0;
        uint64_t sign = 0;
        for (size_t i = 0; i < d.data.size(); ++i) {
            sum += std::abs(d.data[i] - exact.data[i]);
            if ((d.data[i] < 0) != (exact.data[i] < 0)) ++sign;
        }
        const double mean = sum / double(d.data.size());
        std::cout << "[ " << volumeDistanceMethodName(b.m) << " binary ] mean error " << mean << "\n";
        EXPECT_EQ(sign, 0u) << volumeDistanceMethodName(b.m);
        EXPECT_LT(mean, b.mean) << volumeDistanceMethodName(b.m);
    }
}

TEST(VolumeToLevelSet, LevelSetKeepsSpacingBandAndSigns)
{
    const Vec3d spacing(0.5, 0.5, 1.25), c(11.7, 12.2, 12.9);
    const ScalarVolume f = makeSphereField(openvdb::Coord(48, 48, 20), c, 8.0, spacing);
    VolumeToLevelSetOptions o;
    o.subvoxel = true;
    o.exteriorWidth = 4;
    o.interiorWidth = 2;
    VolumeToLevelSetStats st;
    auto g = volumeToLevelSet(f, o, &st);
    EXPECT_EQ(g->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_NEAR(g->voxelSize()[0], 0.5, 1e-12);
    EXPECT_NEAR(g->voxelSize()[2], 1.25, 1e-12);
    EXPECT_FLOAT_EQ(g->background(), 2.0f); // 4 voxels of the smallest spacing
    EXPECT_EQ(st.activeVoxels, g->activeVoxelCount());
    auto acc = g->getConstAccessor();
    uint64_t n = 0;
    for (int k = 0; k < 20; ++k)
        for (int j = 0; j < 48; ++j)
            for (int i = 0; i < 48; ++i) {
                const Vec3d w = g->indexToWorld(openvdb::Coord(i, j, k));
                ASSERT_LT((w - f.worldPosition(i, j, k)).length(), 1e-9);
                const double exact = (w - c).length() - 8.0;
                const bool on = acc.isValueOn(openvdb::Coord(i, j, k));
                if (exact < 1.8 && exact > -0.8) ASSERT_TRUE(on) << i << " " << j << " " << k;
                if (on) {
                    ASSERT_NEAR(acc.getValue(openvdb::Coord(i, j, k)), exact, 0.25) << i << " " << j << " " << k;
                    ++n;
                } else {
                    ASSERT_EQ(acc.getValue(openvdb::Coord(i, j, k)) < 0, exact < 0) << i << " " << j << " " << k;
                }
            }
    EXPECT_GT(n, 2000u);
}

TEST(VolumeToLevelSet, BadOptionsGiveClearErrors)
{
    const ScalarVolume f = makeSphereField(openvdb::Coord(16), Vec3d(7.5), 5.0);
    VolumeToLevelSetOptions o;
    o.subvoxel = true;
    o.method = VolumeDistanceMethod::Complete3;
    EXPECT_THROW(volumeToLevelSet(f, o), InvalidArgumentError);
    o.method = VolumeDistanceMethod::VCVDT8;
    o.iso = 100.0f; // no surface
    EXPECT_THROW(volumeToLevelSet(f, o), InvalidArgumentError);
    o.iso = 0.0f;
    o.exteriorWidth = std::nan("");
    EXPECT_THROW(volumeToLevelSet(f, o), InvalidArgumentError);
    o.exteriorWidth = 3;
    o.maxVoxels = 100;
    EXPECT_THROW(volumeToLevelSet(f, o), ResourceLimitError);
    EXPECT_THROW(volumeDistanceMethodFromName("vcvdt16"), InvalidArgumentError);
    // a volume whose data does not match its dims, and a NaN sample on the binary path
    ScalarVolume bad = f;
    bad.data.resize(100);
    o.maxVoxels = 0;
    EXPECT_THROW(volumeToLevelSet(bad, o), InvalidArgumentError);
    ScalarVolume nan = f;
    nan(3, 4, 5) = std::nanf("");
    o.subvoxel = false;
    try {
        volumeToLevelSet(nan, o);
        FAIL() << "NaN accepted";
    } catch (const InvalidArgumentError& e) {
        EXPECT_NE(std::string(e.what()).find("(3, 4, 5)"), std::string::npos) << e.what();
    }
    EXPECT_EQ(volumeDistanceMethodFromName("evdt-grid"), VolumeDistanceMethod::EVDTFullGrid);
}

#ifdef LEVELFORGE_CLI_PATH
namespace {
int run(const std::string& args, const std::filesystem::path& dir, std::string* err = nullptr)
{
    const std::string e = (dir / "err.txt").string();
    const int st = std::system((std::string("'") + LEVELFORGE_CLI_PATH + "' " + args + " > '" +
                                (dir / "out.txt").string() + "' 2> '" + e + "'").c_str());
    if (err) {
        std::ifstream in(e);
        err->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}
std::string slurp(const std::filesystem::path& p)
{
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}
} // namespace

TEST(VolumeToSdfCli, NiftiToLevelSetAndErrors)
{
    const auto dir = levelforge_test::scratchDir("volume_to_sdf_cli");
    const std::string nii = (dir / "ball.nii.gz").string(), out = (dir / "ball.vdb").string();
    writeNifti(nii, makeSphereField(openvdb::Coord(40, 40, 24), Vec3d(19.5, 20.2, 23.4), 12.0, Vec3d(1, 1, 2)));
    std::string err;
    ASSERT_EQ(run("volume-to-sdf '" + nii + "' '" + out + "' --iso 0 --subvoxel --quiet", dir, &err), 0) << err;
    auto grids = readGrids(out);
    auto g = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
    ASSERT_TRUE(g);
    EXPECT_NEAR(g->voxelSize()[2], 2.0, 1e-9);
    EXPECT_EQ(g->metaValue<std::string>("levelforge:method"), "satherley-jones-vcvdt8-subvoxel");
    // bad: chamfer with --subvoxel, missing file, unknown method — one error line, no output
    const std::string bad = (dir / "bad.vdb").string();
    EXPECT_EQ(run("volume-to-sdf '" + nii + "' '" + bad + "' --method complete-3 --subvoxel --quiet", dir, &err), 1) << err;
    EXPECT_NE(err.find("levelforge: error:"), std::string::npos) << err;
    EXPECT_EQ(run("volume-to-sdf '" + (dir / "none.nii").string() + "' '" + bad + "' --quiet", dir, &err), 1) << err;
    EXPECT_NE(err.find("none.nii"), std::string::npos) << err;
    EXPECT_EQ(run("volume-to-sdf '" + nii + "' '" + bad + "' --method vcvdt16", dir, &err), 2) << err;
    EXPECT_FALSE(std::filesystem::exists(bad));
}

TEST(VolumeToSdfCli, SparseVdbInput)
{
    // A double-precision level-set sphere in a .vdb: --sparse keeps it sparse, signs by --invert.
    const auto dir = levelforge_test::scratchDir("volume_to_sdf_sparse");
    const std::string in = (dir / "ball.vdb").string(), out = (dir / "ball_sdf.vdb").string();
    {
        auto f = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(6.3f, openvdb::Vec3f(0.2f, -0.4f, 0.1f), 0.25f, 3.0f);
        auto d = openvdb::DoubleGrid::create(std::make_shared<openvdb::DoubleTree>(f->tree()));
        d->setTransform(f->transform().copy());
        d->setName("sdf");
        openvdb::io::File file(in);
        file.write({d});
        file.close();
    }
    std::string err;
    ASSERT_EQ(run("volume-to-sdf '" + in + "' '" + out + "' --iso 0 --invert --subvoxel --sparse --exterior-band 8 --quiet",
                  dir, &err), 0) << err;
    const std::string text = slurp(dir / "out.txt");
    EXPECT_NE(text.find("grid 'sdf' (float64"), std::string::npos) << text;
    EXPECT_NE(text.find("widened by the sparse vcvdt8"), std::string::npos) << text;
    auto grids = readGrids(out);
    auto g = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
    ASSERT_TRUE(g);
    EXPECT_EQ(g->metaValue<std::string>("levelforge:method"), "satherley-jones-vcvdt8-subvoxel-sparse");
    EXPECT_NEAR(g->voxelSize()[0], 0.25, 1e-12);
    double mx = 0;
    for (auto it = g->cbeginValueOn(); it; ++it) {
        const double exact = (g->indexToWorld(it.getCoord()) - openvdb::Vec3d(0.2, -0.4, 0.1)).length() - 6.3;
        mx = std::max(mx, std::abs(double(*it) - exact) / 0.25);
    }
    EXPECT_LT(mx, 0.1);
    EXPECT_GT(g->activeVoxelCount(), 30000u);
    // --sparse on a non-.vdb input, or without --subvoxel: one error line, no output.
    const std::string nii = (dir / "ball.nii").string(), bad = (dir / "bad.vdb").string();
    writeNifti(nii, makeSphereField(openvdb::Coord(16), Vec3d(7.5), 5.0));
    EXPECT_EQ(run("volume-to-sdf '" + nii + "' '" + bad + "' --subvoxel --sparse --quiet", dir, &err), 1) << err;
    EXPECT_NE(err.find("ball.nii: not a .vdb file"), std::string::npos) << err;
    EXPECT_EQ(run("volume-to-sdf '" + in + "' '" + bad + "' --sparse --quiet", dir, &err), 2) << err;
    EXPECT_NE(err.find("--subvoxel"), std::string::npos) << err;
    EXPECT_EQ(run("volume-to-sdf '" + in + "' '" + bad + "' --sparse --subvoxel --iso 100 --quiet", dir, &err), 1) << err;
    EXPECT_NE(err.find("ball.vdb: grid 'sdf': no surface at iso-value 100"), std::string::npos) << err;
    EXPECT_FALSE(std::filesystem::exists(bad));
}

TEST(VolumeToSdfCli, DtReportPrintsEveryTransform)
{
    const auto dir = levelforge_test::scratchDir("dt_report_cli");
    ASSERT_EQ(run("dt-report builtin:sphere --quiet", dir), 0);
    const std::string out = slurp(dir / "out.txt");
    for (const char* m : {"Euclidean", "City-block", "Chess board", "Quasi-Euclidean 3", "Complete 3",
                          "Quasi-Euclidean 5", "EVDT", "VCVDT4", "VCVDT8"})
        EXPECT_NE(out.find(m), std::string::npos) << m << "\n" << out;
}
#endif
