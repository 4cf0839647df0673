// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_scan: T4 scan conversion (Erleben & Dohlmann), each tetrahedral shell,
// side by side with the exact Chang path (levelforge::meshToLevelSet) and
// openvdb::tools::meshToLevelSet at equal band, all measured against the exact reference.
//
//   levelforge_bench_scan [--res 128,256] [--band 3] [--stride 7] [--repeat 1] [--warmup 1] [--no-openvdb]
//                         [--conservative] mesh.obj ...
//   levelforge_bench_scan --png shells.png [--res 64] [--band 4]     (Figure 28-style picture)
//
// Methods: chang; scan with the covering shells (ShellCoverage::Complete: the eps-prism that
// pseudonormal/thin/offset complete to, and obb); scan with the paper's hulls (ShellCoverage::
// Paper: pseudonormal, thin, offset), with --conservative also pseudonormal / offset with
// conservative (cell-overlap) rasterization; openvdb. Table: one markdown row per (mesh,
// resolution, method): seconds (best of --repeat, default 1, after --warmup untimed runs of the
// same call, default 1, so that no method is charged for first-touch page faults, the thread
// pool or code paging that an earlier method already paid),
// tetrahedra per face, overlap factor (voxels rasterized per active voxel), active voxels,
// missing voxels (inactive face-neighbours of the result whose exact distance lies inside the
// band), mean / max error over every `stride`-th active voxel (voxels), sign errors. With OpenVDB,
// each levelforge method is then printed as one machine-readable line (SPEED label=<mesh>@<res>/
// <method> ... anchor=openvdb_meshToLevelSet ..., BenchUtil.h) for scripts/bench --smoke.
//
// --png: a 2 x 2 panel of the four shells on a 16-sided cylinder (the paper's Figure 28 uses a
// cylinder): the plane y = 0 through the axis; red = negative, blue = positive (brightness falls
// with |d|), yellow = voxel of the exact band that the shell missed, green = present but wrong
// (> 1e-4 voxel from the exact distance), dark grey = outside the band; the paper's hulls
// (ShellCoverage::Paper). Written with libpng.
#include <levelforge/reference/ExactReference.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/scan/TetScanConversion.h>

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <levelforge/core/Exceptions.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

using namespace levelforge;
#include "BenchPng.h"
#include "BenchUtil.h"
using levelforge_bench::parseList;
using levelforge_bench::since;
using Clock = std::chrono::steady_clock;

using levelforge_bench::writePng;

namespace {



TriangleMesh makeCylinder(int sides, double radius, double height)
{
    TriangleMesh m;
    const uint32_t n = uint32_t(sides);
    for (int k = 0; k < 2; ++k)
        for (int i = 0; i < sides; ++i) {
            const double a = 2 * M_PI * i / sides;
            m.points.push_back(Vec3d(radius * std::cos(a), radius * std::sin(a), k ? height / 2 : -height / 2));
        }
    m.points.push_back(Vec3d(0, 0, -height / 2));
    m.points.push_back(Vec3d(0, 0, height / 2));
    const uint32_t cb = 2 * n, ct = 2 * n + 1;
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t j = (i + 1) % n;
        m.triangles.push_back(Vec3I(ct, n + i, n + j));
        m.triangles.push_back(Vec3I(cb, j, i));
        m.triangles.push_back(Vec3I(i, j, n + j));
        m.triangles.push_back(Vec3I(i, n + j, n + i));
    }
    m.source = "<cylinder>";
    return m;
}

int renderShells(const std::string& path, int res, float band)
{
    const TriangleMesh mesh = makeCylinder(16, 1.0, 2.0);
    const ExactReference ref(mesh);
    const double h = 2.0 / res;
    const int half = int(std::ceil(1.0 / h + band + 2));
    const int cell = std::max(2, 320 / (2 * half + 1)), pw = (2 * half + 1) * cell, gap = 8;
    const int W = 2 * pw + gap, H = 2 * pw + gap;
    std::vector<unsigned char> img(size_t(W) * H * 3, 255);
    const ShellMethod shells[4] = {ShellMethod::PseudoNormal, ShellMethod::Thin, ShellMethod::Offset, ShellMethod::Obb};
    for (int s = 0; s < 4; ++s) {
        TetScanOptions o;
        o.voxelSize = h;
        o.exteriorWidth = o.interiorWidth = band;
        o.shell = shells[s];
        o.coverage = ShellCoverage::Paper; // the paper's hulls, as its Figure 28 shows them
        TetScanStats st;
        const auto g = meshToLevelSetScan(mesh, o, &st);
        auto acc = g->getConstAccessor();
        uint64_t missing = 0, wrong = 0;
        const int ox = (s % 2) * (pw + gap), oy = (s / 2) * (pw + gap);
        for (int i = -half; i <= half; ++i)
            for (int k = -half; k <= half; ++k) {
                const openvdb::Coord c(i, 0, k);
                const double d = ref.signedDistance(g->indexToWorld(c)) / h;
                const bool inBand = d < band - 1e-6 && d > -band + 1e-6;
                float v;
                unsigned char r = 60, gg = 60, b = 60;
                if (acc.probeValue(c, v)) {
                    const double vv = v / h, t = std::min(1.0, std::abs(vv) / band);
                    const unsigned char lvl = (unsigned char)(255 - 170 * t);
                    if (std::abs(vv - d) > 1e-4) { r = 0; gg = 200; b = 0; ++wrong; }
                    else if (vv < 0) { r = lvl; gg = 30; b = 30; }
                    else { r = 30; gg = 30; b = lvl; }
                } else if (inBand) {
                    r = 255; gg = 220; b = 0;
                    ++missing;
                }
                for (int py = 0; py < cell; ++py)
                    for (int px = 0; px < cell; ++px) {
                        const int X = ox + (i + half) * cell + px, Y = oy + (half - k) * cell + py;
                        unsigned char* p = &img[(size_t(Y) * W + X) * 3];
                        p[0] = r; p[1] = gg; p[2] = b;
                    }
            }
        std::printf("panel %d (%s): tetrahedra/face %.2f, overlap %.2f, missing in slice %llu, wrong in slice %llu\n",
                    s, toString(shells[s]), st.tetrahedraPerFace(), st.overlapFactor(), (unsigned long long)missing,
                    (unsigned long long)wrong);
    }
    writePng(path, W, H, img);
    std::printf("wrote %s (%d x %d): top-left pseudonormal, top-right thin, bottom-left offset, bottom-right obb\n",
                path.c_str(), W, H);
    return 0;
}

struct Row
{
    std::string method;
    double seconds = 0, tetsPerFace = 0, overlap = 0;
    BandErrorReport err;
    uint64_t active = 0;
};

} // namespace

int main(int argc, char** argv)
{
    std::vector<double> resolutions{128, 256};
    double band = 3.0;
    uint64_t stride = 7;
    int repeat = 1, warmup = 1;
    bool withOpenVdb = true, withConservative = false;
    std::string png;
    std::vector<std::string> meshes;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--res") && i + 1 < argc) resolutions = parseList(argv[++i]);
        else if (!std::strcmp(argv[i], "--band") && i + 1 < argc) band = std::stod(argv[++i]);
        else if (!std::strcmp(argv[i], "--stride") && i + 1 < argc) stride = std::stoull(argv[++i]);
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) repeat = std::max(1, std::stoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--warmup") && i + 1 < argc) warmup = std::max(0, std::stoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--png") && i + 1 < argc) png = argv[++i];
        else if (!std::strcmp(argv[i], "--no-openvdb")) withOpenVdb = false;
        else if (!std::strcmp(argv[i], "--conservative")) withConservative = true;
        else meshes.push_back(argv[i]);
    }
    openvdb::initialize();
    if (!png.empty()) return renderShells(png, int(resolutions.front() > 128 ? 64 : resolutions.front()), float(band));
    if (meshes.empty()) {
        std::fprintf(stderr, "usage: levelforge_bench_scan [--res 128,256] [--band 3] [--stride 7] [--repeat 1] [--warmup 1] "
                             "[--no-openvdb] [--conservative] mesh...\n       levelforge_bench_scan --png out.png [--res 64] [--band 4]\n");
        return 2;
    }
    std::string speedLines; // printed after the table
    std::printf("| mesh | triangles | res | method | seconds | tets/face | overlap | active voxels | missing | "
                "mean / max err (voxels) | sign err |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const std::string& path : meshes) {
        const TriangleMesh mesh = readMesh(path);
        const ExactReference ref(mesh);
        const std::string name = std::filesystem::path(path).stem().string();
        for (double res : resolutions) {
            MeshToLevelSetOptions mo;
            mo.voxelCount = int(res);
            mo.exteriorWidth = mo.interiorWidth = float(band);
            const double h = resolveVoxelSize(mesh, mo);
            std::vector<Row> rows;
            auto timed = [&](const std::string& method, auto&& fn) {
                Row r;
                r.method = method;
                openvdb::FloatGrid::Ptr g;
                r.seconds = 1e300;
                for (int k = 0; k < warmup; ++k) {
                    Row scratch;
                    (void)fn(scratch); // untimed
                }
                for (int k = 0; k < repeat; ++k) {
                    g.reset();
                    const auto t0 = Clock::now();
                    g = fn(r);
                    r.seconds = std::min(r.seconds, since(t0));
                }
                r.active = g->activeVoxelCount();
                r.err = compareToReference(*g, ref, band, band, stride);
                rows.push_back(r);
            };
            timed("chang (exact)", [&](Row&) { return meshToLevelSet(mesh, mo); });
            struct Scan { ShellMethod shell; ShellCoverage coverage; bool conservative; const char* label; };
            std::vector<Scan> scans = {
                {ShellMethod::PseudoNormal, ShellCoverage::Complete, false, "scan eps-prism (complete)"},
                {ShellMethod::Obb, ShellCoverage::Complete, false, "scan obb"},
                {ShellMethod::PseudoNormal, ShellCoverage::Paper, false, "scan pseudonormal (paper)"},
                {ShellMethod::Thin, ShellCoverage::Paper, false, "scan thin (paper)"},
                {ShellMethod::Offset, ShellCoverage::Paper, false, "scan offset (paper)"}};
            if (withConservative) {
                scans.push_back({ShellMethod::PseudoNormal, ShellCoverage::Paper, true, "scan pseudonormal (paper) +conservative"});
                scans.push_back({ShellMethod::Offset, ShellCoverage::Paper, true, "scan offset (paper) +conservative"});
            }
            for (const Scan& sc : scans) {
                timed(sc.label, [&, m = sc.shell, conservative = sc.conservative, coverage = sc.coverage](Row& r) {
                    TetScanOptions so;
                    so.coverage = coverage;
                    so.conservative = conservative;
                    so.voxelCount = int(res);
                    so.exteriorWidth = so.interiorWidth = float(band);
                    so.shell = m;
                    TetScanStats st;
                    auto g = meshToLevelSetScan(mesh, so, &st);
                    r.tetsPerFace = st.tetrahedraPerFace();
                    r.overlap = st.overlapFactor();
                    return g;
                });
            }
            if (withOpenVdb) {
                std::vector<openvdb::Vec3s> pts;
                std::vector<openvdb::Vec3I> tris;
                for (const auto& p : mesh.points) pts.emplace_back(float(p[0]), float(p[1]), float(p[2]));
                for (const auto& t : mesh.triangles) tris.emplace_back(t[0], t[1], t[2]);
                const auto xform = openvdb::math::Transform::createLinearTransform(h);
                timed("openvdb::tools::meshToLevelSet", [&](Row&) {
                    return openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*xform, pts, tris, float(band));
                });
            }
            for (const Row& r : rows) {
                char tpf[32] = "-", ov[32] = "-";
                if (r.tetsPerFace > 0) std::snprintf(tpf, sizeof tpf, "%.2f", r.tetsPerFace);
                if (r.overlap > 0) std::snprintf(ov, sizeof ov, "%.2f", r.overlap);
                std::printf("| %s | %zu | %d | %s | %.3f | %s | %s | %llu | %llu | %.2e / %.2e | %llu |\n", name.c_str(),
                            mesh.triangleCount(), int(res), r.method.c_str(), r.seconds, tpf, ov,
                            (unsigned long long)r.active, (unsigned long long)r.err.missingVoxels, r.err.meanError,
                            r.err.maxError, (unsigned long long)r.err.signErrors);
            }
            if (withOpenVdb) {
                const Row& anchor = rows.back();
                for (size_t k = 0; k + 1 < rows.size(); ++k)
                    speedLines += levelforge_bench::speedLine(name + "@" + std::to_string(int(res)) + "/" + rows[k].method,
                                                              rows[k].seconds, "openvdb_meshToLevelSet", anchor.seconds);
            }
            std::fflush(stdout);
        }
    }
    if (!speedLines.empty()) std::printf("\n%s", speedLines.c_str());
    return 0;
}
