// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_device — the main road on the CPU and on a Vulkan device, same process, same
// mesh, voxel size and band: in-process conversion time and whole-process time (read the mesh
// file + convert + write the .vdb), the grids compared bit for bit, transfer vs wait time,
// device memory. The CPU runs with --cpu-threads (default 2, the CI machine), the device path
// with --threads (default: all).
//
//   levelforge_bench_device MESH [--subdivide N] [--voxel-count N ...] [--half-width W]
//                           [--cpu-threads N] [--threads N] [--repeat N] [--skip-cpu]
//
// With --subdivide, the subdivided mesh is written once as a binary PLY beside the output and
// the whole-process runs read that file.
#include "BenchLoop.h"
#include "BenchUtil.h"

#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/gpu/VulkanSlabBackend.h>
#include <levelforge/scan/TetScanConversion.h>

#include <openvdb/openvdb.h>
#include <tbb/global_control.h>

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Run
{
    double convert = 1e30, whole = 1e30;
    levelforge::MeshToLevelSetStats stats;
    openvdb::FloatGrid::Ptr grid;
};

Run runOnce(const std::string& meshFile, const levelforge::MeshToLevelSetOptions& o, const std::string& out, int repeat)
{
    Run best;
    for (int r = 0; r < repeat; ++r) {
        const auto t0 = Clock::now();
        const levelforge::TriangleMesh mesh = levelforge::readMesh(meshFile);
        levelforge::MeshToLevelSetStats s;
        const auto t1 = Clock::now();
        auto grid = levelforge::meshToLevelSet(mesh, o, &s);
        const double convert = since(t1);
        levelforge::writeGridsAtomic(out, openvdb::GridPtrVec{grid});
        const double whole = since(t0);
        if (whole < best.whole) { best.whole = whole; best.convert = convert; best.stats = s; }
        best.grid = grid;
    }
    return best;
}

uint64_t differences(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b)
{
    if (a.activeVoxelCount() != b.activeVoxelCount()) return ~uint64_t(0);
    uint64_t bad = 0;
    auto acc = b.getConstAccessor();
    for (auto it = a.tree().cbeginLeaf(); it; ++it)
        for (auto v = it->cbeginValueAll(); v; ++v) {
            float value;
            const bool on = acc.probeValue(v.getCoord(), value);
            if (on != v.isValueOn() || std::memcmp(&value, &*v, sizeof(float)) != 0) ++bad;
        }
    return bad;
}
} // namespace

int main(int argc, char** argv)
{
    CLI::App app{"levelforge main road: CPU vs Vulkan device, in process and whole process"};
    std::string meshPath, outDir = "bench-device-out";
    int subdivide = 0, cpuThreads = 2, threads = 0, repeat = 1;
    std::vector<int> counts{512};
    double halfWidth = 3.0;
    bool skipCpu = false, skipDevice = false, scan = false;
    app.add_option("mesh", meshPath, "mesh file (OBJ, PLY, STL, OFF)")->required();
    app.add_option("--subdivide", subdivide, "Loop subdivision levels first (OpenMesh)")->check(CLI::Range(0, 4));
    app.add_option("--voxel-count", counts, "voxels along the longest axis (several: one row each)");
    app.add_option("--half-width", halfWidth, "band half-width, voxels");
    app.add_option("--cpu-threads", cpuThreads, "TBB threads of the CPU path (0: all)");
    app.add_option("--threads", threads, "TBB threads of the device path (0: all)");
    app.add_option("--repeat", repeat, "best of N")->check(CLI::Range(1, 20));
    app.add_option("--out", outDir, "folder for the written files");
    app.add_flag("--skip-cpu", skipCpu, "device path only");
    app.add_flag("--skip-device", skipDevice, "CPU path only");
    app.add_flag("--scan", scan, "also T4 scan conversion (OBB shells): CpuSlabBackend vs VulkanSlabBackend, in process");
    CLI11_PARSE(app, argc, argv);
    openvdb::initialize();
    std::filesystem::create_directories(outDir);
    try {
        const levelforge::VulkanDeviceList list = levelforge::listVulkanDevices();
        for (const auto& d : list.devices)
            std::cout << "device " << d.index << ": " << d.name << " (" << d.type << ", "
                      << double(d.deviceLocalBytes) / double(1u << 30) << " GiB, fp64 " << (d.float64 ? "yes" : "no")
                      << (d.chosen ? ", chosen" : "") << ")\n";
        if (!list.problem.empty()) std::cout << "vulkan: " << list.problem << "\n";
        std::string file = meshPath;
        if (subdivide > 0) {
            auto t0 = Clock::now();
            const levelforge::TriangleMesh sub = levelforge_bench::loopSubdivide(levelforge::readMesh(meshPath), subdivide);
            file = outDir + "/" + std::filesystem::path(meshPath).stem().string() + "_loop" + std::to_string(subdivide) + ".ply";
            levelforge::writeMesh(sub, file);
            std::cout << "mesh: " << meshPath << " Loop x" << subdivide << " -> " << file << ", " << sub.triangles.size()
                      << " triangles (" << since(t0) << " s)\n";
        }
        for (const int count : counts) {
            levelforge::MeshToLevelSetOptions o;
            o.voxelCount = count;
            o.exteriorWidth = o.interiorWidth = halfWidth;
            Run cpu;
            if (!skipCpu) {
                o.device = levelforge::ComputeDevice::Cpu;
                tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(cpuThreads > 0 ? cpuThreads : 1 << 16));
                cpu = runOnce(file, o, outDir + "/cpu.vdb", repeat);
            }
            if (skipDevice) {
                std::printf("\nvoxel count %d, band %g: cpu (%d threads): convert %.3f s, whole process %.3f s (distance %.3f s, "
                            "%s active voxels)\n", count, halfWidth, cpuThreads, cpu.convert, cpu.whole,
                            cpu.stats.secondsDistance, std::to_string(cpu.stats.activeVoxels).c_str());
                continue;
            }
            o.device = levelforge::ComputeDevice::Vulkan;
            Run dev;
            {
                tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads > 0 ? threads : 1 << 16));
                dev = runOnce(file, o, outDir + "/device.vdb", repeat);
            }
            const auto& s = dev.stats;
            std::printf("\nvoxel count %d, band %g: %s active voxels, %s candidate leaves\n", count, halfWidth,
                        std::to_string(s.activeVoxels).c_str(), std::to_string(s.candidateLeaves).c_str());
            if (!skipCpu)
                std::printf("  cpu (%d threads):     convert %8.3f s, whole process %8.3f s (distance %.3f s, %.2f evaluations/voxel)\n",
                            cpuThreads, cpu.convert, cpu.whole, cpu.stats.secondsDistance, cpu.stats.evaluationsPerActiveVoxel());
            std::printf("  %s (%d threads): convert %8.3f s, whole process %8.3f s (distance %.3f s)\n", s.device.c_str(), threads,
                        dev.convert, dev.whole, s.secondsDistance);
            std::printf("    device: %llu batches, %.3g voxel-triangle pairs, up %.1f MiB, down %.1f MiB, peak %.1f MiB; "
                        "CPU waited %.3f s, staging copies %.3f s\n",
                        (unsigned long long)s.deviceBatches, double(s.devicePairs), double(s.deviceBytesUp) / 1048576.0,
                        double(s.deviceBytesDown) / 1048576.0, double(s.devicePeakBytes) / 1048576.0, s.secondsDeviceWait,
                        s.secondsDeviceCopy);
            std::printf("    stages: hierarchy %.3f, candidates %.3f, distance %.3f, finish %.3f s\n", s.secondsHierarchy,
                        s.secondsCandidates, s.secondsDistance, s.secondsFinish);
            if (!skipCpu) {
                const uint64_t bad = differences(*cpu.grid, *dev.grid);
                std::printf("  speed-up: convert %.2fx, whole process %.2fx; grids %s\n", cpu.convert / dev.convert,
                            cpu.whole / dev.whole,
                            bad == 0 ? "bit-identical" : ("DIFFER in " + std::to_string(bad) + " voxels").c_str());
            }
            std::fflush(stdout);
            if (scan) {
                const levelforge::TriangleMesh mesh = levelforge::readMesh(file);
                levelforge::TetScanOptions so;
                so.voxelCount = count;
                so.exteriorWidth = so.interiorWidth = halfWidth;
                levelforge::TetScanStats cs, gs;
                double ct = 0;
                openvdb::FloatGrid::Ptr cg;
                {
                    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(cpuThreads > 0 ? cpuThreads : 1 << 16));
                    const auto t0 = Clock::now();
                    cg = levelforge::meshToLevelSetScan(mesh, so, &cs);
                    ct = since(t0);
                }
                tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads > 0 ? threads : 1 << 16));
                levelforge::VulkanSlabBackend backend;
                so.backend = &backend;
                const auto t0 = Clock::now();
                const auto gg = levelforge::meshToLevelSetScan(mesh, so, &gs);
                const double gt = since(t0);
                const auto bs = backend.stats();
                const uint64_t bad = differences(*cg, *gg);
                std::printf("  T4 scan (obb): cpu %.3f s (fill %.3f s), vulkan %.3f s (fill %.3f s, waited %.3f s, %llu batches, %llu items, "
                            "peak %.1f MiB): %.2fx; grids %s\n",
                            ct, cs.secondsFill, gt, gs.secondsFill, bs.secondsWait, (unsigned long long)bs.batches,
                            (unsigned long long)bs.items, double(bs.peakDeviceBytes) / 1048576.0, ct / gt,
                            bad == 0 ? "bit-identical" : ("DIFFER in " + std::to_string(bad) + " voxels").c_str());
                std::fflush(stdout);
            }
        }
    } catch (const std::exception& e) {
        std::cerr << "levelforge_bench_device: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
