// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_device_edt — the dense exact EDT (Felzenszwalb & Huttenlocher;
// exactDistanceTransform(), ExactDistanceTransform.h) on the CPU and on a Vulkan device, same
// process, same masks: time of each, the device's transfer (host copies and copy submissions)
// vs kernel (waiting) time, slabs, dispatches, device memory, and the distances compared bit for
// bit. Masks: a sphere shell (the feature voxels of a ball) and random points, N^3 each.
//
//   levelforge_bench_device_edt [--size N] [--cpu-threads T] [--budget MIB] [--repeat R]
//                               [--density D] [--skip-cpu]
//
// The CPU runs with T threads (tbb::global_control; default 2, the CI machine). The device runs
// twice: with --budget MiB of device memory (default 256: slabs at 512^3) and with the automatic
// budget (the whole volume resident when it fits); --budget 0 runs only the automatic one. Exit status 1 when the device's distances
// differ from the CPU's in any voxel (or there is no device), else 0.
#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/volume/ExactDistanceTransform.h>

#include <openvdb/openvdb.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>
#include <string>

namespace {
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

/// The voxels within half a voxel of a sphere of radius 0.4 n, centre off the grid.
levelforge::MaskVolume sphereShell(int n)
{
    levelforge::MaskVolume m(openvdb::Coord(n), uint8_t(0));
    const double c = 0.5 * n + 0.31, r = 0.4 * n;
    for (int k = 0; k < n; ++k)
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const double d = std::sqrt((i - c) * (i - c) + (j - c + 0.17) * (j - c + 0.17) + (k - c - 0.11) * (k - c - 0.11));
                if (std::abs(d - r) < 0.5) m(i, j, k) = 1;
            }
    return m;
}

levelforge::MaskVolume randomPoints(int n, double density)
{
    levelforge::MaskVolume m(openvdb::Coord(n), uint8_t(0));
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (uint8_t& v : m.data) v = u(rng) < density ? 1 : 0;
    return m;
}

uint64_t differing(const levelforge::ScalarVolume& a, const levelforge::ScalarVolume& b)
{
    uint64_t bad = 0;
    for (size_t i = 0; i < a.data.size(); ++i)
        if (std::memcmp(&a.data[i], &b.data[i], sizeof(float)) != 0) ++bad;
    return bad;
}

void usage()
{
    std::fprintf(stderr, "usage: levelforge_bench_device_edt [--size N] [--cpu-threads T] [--budget MIB] "
                         "[--repeat R] [--density D] [--skip-cpu]\n");
}

} // namespace

int main(int argc, char** argv)
{
    int size = 512, cpuThreads = 2, repeat = 1;
    double budgetMiB = 256.0, density = 1e-4;
    bool skipCpu = false;
    for (int a = 1; a < argc; ++a) {
        const std::string s = argv[a];
        auto next = [&]() -> const char* {
            if (a + 1 >= argc) { usage(); std::exit(2); }
            return argv[++a];
        };
        if (s == "--size") size = std::atoi(next());
        else if (s == "--cpu-threads") cpuThreads = std::atoi(next());
        else if (s == "--budget") budgetMiB = std::atof(next());
        else if (s == "--repeat") repeat = std::max(1, std::atoi(next()));
        else if (s == "--density") density = std::atof(next());
        else if (s == "--skip-cpu") skipCpu = true;
        else { usage(); return 2; }
    }
    if (size < 1 || cpuThreads < 1) { usage(); return 2; }
    std::setvbuf(stdout, nullptr, _IOLBF, 0); // progress in logs as it comes
    openvdb::initialize();
    const levelforge::VulkanDeviceList list = levelforge::listVulkanDevices();
    std::string device = "(none: " + list.problem + ")";
    for (const auto& d : list.devices)
        if (d.chosen) device = d.name + " (" + d.type + ", " + std::to_string(d.deviceLocalBytes >> 20) + " MiB)";
    std::printf("dense exact EDT, %d^3 voxels; CPU: %d threads; Vulkan device: %s\n", size, cpuThreads, device.c_str());

    // the device's context and kernel start-up, outside the timings
    {
        levelforge::ExactTransformOptions o;
        o.device = levelforge::ComputeDevice::Vulkan;
        try {
            levelforge::exactDistanceTransform(levelforge::MaskVolume(openvdb::Coord(4), uint8_t(1)), o);
        } catch (const levelforge::DeviceError& e) {
            std::printf("no Vulkan device: %s\n", e.what());
            return 1;
        }
    }
    bool identical = true;
    struct Case { const char* name; levelforge::MaskVolume mask; };
    const auto t0 = Clock::now();
    Case cases[] = {{"sphere shell", sphereShell(size)}, {"random points", randomPoints(size, density)}};
    std::printf("masks built in %.2f s\n", since(t0));
    for (Case& c : cases) {
        uint64_t features = 0;
        for (uint8_t v : c.mask.data) features += v ? 1 : 0;
        std::printf("\n%s: %llu feature voxels\n", c.name, static_cast<unsigned long long>(features));
        levelforge::ScalarVolume cpu;
        double cpuSeconds = 1e30;
        if (!skipCpu) {
            tbb::global_control threads(tbb::global_control::max_allowed_parallelism, size_t(cpuThreads));
            for (int r = 0; r < repeat; ++r) {
                const auto t = Clock::now();
                cpu = levelforge::exactDistanceTransform(c.mask);
                cpuSeconds = std::min(cpuSeconds, since(t));
            }
            std::printf("  cpu     %8.3f s\n", cpuSeconds);
        }
        for (const double budget : {budgetMiB, 0.0}) {
            levelforge::ExactTransformOptions o;
            o.device = levelforge::ComputeDevice::Vulkan;
            o.deviceMemoryBudget = uint64_t(budget * 1048576.0);
            levelforge::ExactTransformStats best;
            double seconds = 1e30;
            levelforge::ScalarVolume gpu;
            for (int r = 0; r < repeat; ++r) {
                levelforge::ExactTransformStats s;
                const auto t = Clock::now();
                gpu = levelforge::exactDistanceTransform(c.mask, o, &s);
                const double sec = since(t);
                if (sec < seconds) { seconds = sec; best = s; }
            }
            std::printf("  vulkan  %8.3f s  (budget %s: transfers %.3f s, kernels %.3f s, other %.3f s; %llu slabs, "
                        "%llu dispatches, %llu submissions; up %.1f MiB, down %.1f MiB, peak device memory %.1f MiB)",
                        seconds, budget > 0 ? (std::to_string(int(budget)) + " MiB").c_str() : "automatic",
                        best.secondsTransfer, best.secondsCompute, seconds - best.secondsTransfer - best.secondsCompute,
                        static_cast<unsigned long long>(best.slabs), static_cast<unsigned long long>(best.dispatches),
                        static_cast<unsigned long long>(best.submissions), double(best.bytesUp) / 1048576.0,
                        double(best.bytesDown) / 1048576.0, double(best.peakDeviceBytes) / 1048576.0);
            if (!skipCpu) {
                const uint64_t bad = differing(cpu, gpu);
                identical = identical && bad == 0;
                std::printf("%s", bad == 0 ? "  bit-identical to the CPU" : "");
                if (bad) std::printf("  DIFFERS from the CPU in %llu voxels", static_cast<unsigned long long>(bad));
                if (cpuSeconds < 1e30) std::printf(", speed-up %.2fx", cpuSeconds / seconds);
            }
            std::printf("\n");
            if (budget == 0.0) break;
        }
    }
    return identical ? 0 : 1;
}
