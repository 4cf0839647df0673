// SPDX-License-Identifier: Apache-2.0
// levelforge operator `dt-report`: every distance transform of Satherley & Jones against the
// exact Euclidean field, in the columns of the paper's tables (1, 2, 4–7).
#include "Interrupt.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorText.h"

#include <levelforge/volume/ChamferDistanceTransform.h>
#include <levelforge/core/Exceptions.h>
#include <levelforge/volume/ExactDistanceTransform.h>
#include <levelforge/reference/ExactReference.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VolumeIO.h>
#include <levelforge/volume/VolumeToLevelSet.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <ostream>
#include <string>

namespace levelforge::ops {

ScalarVolume loadVolumeArg(OperatorArgs& args, const std::string& input, VolumeInfo& info); // VolumeToSdf.cc

namespace {

bool isMeshPath(const std::string& path)
{
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext == ".obj" || ext == ".off" || ext == ".ply" || ext == ".stl";
}

/// A mesh sampled as a field: minus its signed distance at the voxel centres (inside >= 0),
/// `count` samples along the longest side of the bounding box plus 2 on each side.
ScalarVolume meshField(const TriangleMesh& mesh, int count)
{
    const BBoxd b = mesh.bounds();
    const Vec3d ext = b.extents();
    const double longest = std::max({ext[0], ext[1], ext[2]});
    if (!(longest > 0.0) || !std::isfinite(longest))
        throw InvalidMeshError(mesh.source + ": the bounding box has zero or non-finite size");
    const double h = longest / double(count - 5);
    openvdb::Coord dims;
    for (int a = 0; a < 3; ++a) dims[a] = int(std::ceil(ext[a] / h)) + 5;
    const double samples = double(dims.x()) * double(dims.y()) * double(dims.z());
    if (samples > double(uint64_t(1) << 31))
        throw ResourceLimitError(mesh.source + ": " + std::to_string(uint64_t(samples)) +
                                 " samples at this --voxel-count, more than the limit of 2^31");
    ScalarVolume f(dims, 0.0f, Vec3d(h), b.min() - Vec3d(2.0 * h));
    const ExactReference ref(mesh);
    tbb::parallel_for(tbb::blocked_range<int>(0, dims.z()), [&](const tbb::blocked_range<int>& r) {
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < dims.y(); ++j)
                for (int i = 0; i < dims.x(); ++i) f(i, j, k) = float(-ref.query(f.worldPosition(i, j, k)).distance);
    });
    return f;
}

void printRow(std::ostream& os, const DistanceTransformComparison& r, const std::string& extraTime = "")
{
    char buf[512];
    std::snprintf(buf, sizeof(buf), "| %s | %.3f%s | %.3f | %.3f | %.3f | %.3f | %.6f |\n", r.method.c_str(), r.seconds,
                  extraTime.c_str(), r.minDistance, r.maxDistance, r.minError, r.maxError, r.averageErrorPerVoxel);
    os << buf;
}

void cookDtReport(OperatorArgs& args)
{
    using Clock = std::chrono::steady_clock;
    const std::string& input = args.input("input");
    const bool quiet = args.getBool("quiet");
    VolumeInfo info;
    ScalarVolume field;
    float iso = float(args.getFloat("iso"));
    bool below = args.getBool("invert");
    if (isMeshPath(input)) {
        field = meshField(readMeshInput(args, input), int(args.getInt("voxel-count")));
        iso = 0.0f;
        below = false;
        info.format = "mesh";
    } else {
        field = loadVolumeArg(args, input, info);
    }
    const double h = std::min({field.spacing[0], field.spacing[1], field.spacing[2]});
    std::ostream& os = args.out();
    os << "dt-report: " << input << " (" << info.format << "), " << field.dims.x() << " x " << field.dims.y()
       << " x " << field.dims.z() << " = " << field.voxelCount() << " voxels, spacing " << field.spacing
       << ", iso " << iso << (below ? " (inside below)" : "") << "\n"
       << "Distances and errors in voxels (of the smallest spacing); error = computed - exact; "
          "average |error| over all voxels.\n\n";
    auto inVoxels = [h](DistanceTransformComparison r) {
        r.minDistance = float(r.minDistance / h);
        r.maxDistance = float(r.maxDistance / h);
        r.minError = float(r.minError / h);
        r.maxError = float(r.maxError / h);
        r.averageErrorPerVoxel /= h;
        return r;
    };
    os << "| transform | time (s) | distance min | distance max | error min | error max | average error per voxel |\n"
       << "|---|---|---|---|---|---|---|\n";
    SubvoxelShellOptions so;
    so.iso = iso;
    so.insideBelow = below;
    if (!args.getBool("subvoxel")) {
        // Tables 1, 2, 4–6: binary features, signed by Eq. 5–6, against the exact EDT
        const MaskVolume inside = insideFlags(field, so);
        DistanceTransformReportOptions ro;
        CliProgress progress(10, !quiet);
        ro.interrupter = &progress;
        for (const auto& r : distanceTransformReport(inside, ro)) printRow(os, inVoxels(r));
        return;
    }
    // Table 7: binary and shell-seeded transforms against the sub-voxel accurate Euclidean field
    VolumeToLevelSetOptions o;
    o.iso = iso;
    o.insideBelow = below;
    o.method = VolumeDistanceMethod::Exact;
    o.subvoxel = true;
    o.maxVoxels = 0;
    auto t0 = Clock::now();
    const ScalarVolume exact = volumeSignedDistance(field, o);
    DistanceTransformComparison er = compareDistanceFields(exact, exact);
    er.method = "True Euclidean (sub-voxel surface, BVH)";
    er.seconds = secondsSince(t0);
    printRow(os, inVoxels(er));
    for (bool sub : {false, true}) {
        for (VolumeDistanceMethod m : {VolumeDistanceMethod::CityBlock, VolumeDistanceMethod::EVDT,
                                       VolumeDistanceMethod::EVDTFullGrid, VolumeDistanceMethod::VCVDT4,
                                       VolumeDistanceMethod::VCVDT8}) {
            if (sub && m == VolumeDistanceMethod::CityBlock) continue;
            o.method = m;
            o.subvoxel = sub;
            VolumeToLevelSetStats st;
            const ScalarVolume d = volumeSignedDistance(field, o, &st);
            DistanceTransformComparison r = compareDistanceFields(d, exact);
            r.method = std::string(volumeDistanceMethodName(m)) + (sub ? " (shell)" : " (binary)");
            r.seconds = st.secondsTransform;
            std::string extra;
            if (sub) {
                char buf[64];
                std::snprintf(buf, sizeof(buf), " + %.3f shell", st.secondsClassify);
                extra = buf;
            }
            printRow(os, inVoxels(r), extra);
        }
    }
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("dt-report",
                 "Compare every distance transform with the exact Euclidean field (Satherley-Jones "
                 "tables)")
        .description(
            "Runs the chamfer family, EVDT (two-slice and full grid), VCVDT 4 and 8 passes on a\n"
            "volume (or a mesh sampled at --voxel-count) and prints, like the paper's tables,\n"
            "each transform's time, distance range, error range and average error per voxel\n"
            "against the exact Euclidean field: binary features vs the exact EDT (Tables 1,\n"
            "2, 4-6), or with --subvoxel the binary and shell-seeded transforms vs the exact\n"
            "distance to the interpolated surface (Table 7).")
        .input("input", "Volume (.nii, .nii.gz, .inr, .den, .raw, .vdb, builtin:sphere) or mesh (.obj, .off, .ply, .stl)")
        .param(Param::floating("iso", "Iso Value", "Samples >= iso are inside").defaultValue(0.0))
        .param(Param::flag("invert", "Invert", "Samples <= iso are inside instead"))
        .param(Param::flag("subvoxel", "Sub-voxel", "Table 7: compare with the sub-voxel accurate field"))
        .param(Param::integer("voxel-count", "Voxel Count", "Mesh input: samples along the longest side")
                   .defaultValue(60)
                   .range(8, 4096))
        .param(Param::string("vdb-grid", "Input VDB Grid", "Grid to read from a .vdb input"))
        .param(Param::string("raw-dims", "Raw Dimensions", "Raw input: samples along x,y,z"))
        .param(Param::string("raw-type", "Raw Type", "Raw input: sample type").defaultValue("uint8"))
        .param(Param::string("raw-spacing", "Raw Spacing", "Raw input: voxel spacing x,y,z").defaultValue("1,1,1"))
        .param(Param::integer("raw-header-bytes", "Raw Header Bytes", "Raw input: bytes before the samples")
                   .defaultValue(0)
                   .range(0, double(int64_t(1) << 40)))
        .param(Param::flag("raw-big-endian", "Raw Big Endian", "Raw input: big-endian samples"))
        .param(Param::flag("quiet", "Quiet", "Print no progress on stderr"))
        .example("levelforge dt-report builtin:sphere")
        .example("levelforge dt-report chess_pawn.stl --voxel-count 60")
        .example("levelforge dt-report skull.inr --iso 2.9 --subvoxel")
        .cook(cookDtReport));

} // namespace levelforge::ops
