// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the vector distance transforms (and their white-box tests): the pass
///        tables that define VCVDT4, VCVDT8, EVDT and EVDTFullGrid, the shape the row kernel
///        requires of them, and the switch between the AVX2 and baseline builds of the kernel.
///
/// The tables are our reading of Satherley & Jones, "Vector-City Vector Distance Transform"
/// (2001), §2.2/§3, and of Mullikin (1992) for EVDT; the public header
/// <levelforge/volume/VectorDistanceTransform.h> states them in prose.
#pragma once

#include <levelforge/volume/VectorDistanceTransform.h>

#include <cstdint>

namespace levelforge::vector_transform_internal {

/// A neighbour position relative to the visited voxel, in voxels.
struct Offset
{
    int8_t x, y, z;
};

/// One in-slice pass. Rows are visited in order yOrder (+1: y = 0..ny-1, -1: y = ny-1..0) and
/// each row in order xOrder. Candidates V(p + o) + o are tried in the listed order (strictly
/// smaller d2 wins). A pass with perRow = true runs on each row immediately after the previous
/// pass has finished that row (EVDT's F2/B2), in the previous pass's row order.
/// Every pass lists at most: the vertical neighbour (0,0,-zOrder), the previous row
/// (0,-yOrder,0), and last the previous voxel in the row (-xOrder,0,0).
struct PassDef
{
    int8_t yOrder;
    int8_t xOrder;
    bool perRow;
    uint8_t neighbourCount;
    Offset neighbours[3];
};

/// A sweep over the slices in order zOrder (+1: z = 0..nz-1), each slice visited by the passes
/// in order.
struct SweepDef
{
    int8_t zOrder;
    uint8_t passCount;
    PassDef passes[4];
};

struct MethodDef
{
    VectorTransformMethod method;
    bool twoSlices;     ///< sweeps start separately from the input, two slice buffers each
    SweepDef sweeps[2]; ///< forward, backward
};

// clang-format off
inline constexpr MethodDef kVCVDT4 = {VectorTransformMethod::VCVDT4, false, {
    {+1, 2, {{+1, +1, false, 3, {{0, 0, -1}, {0, -1, 0}, {-1, 0, 0}}},    // F1
             {-1, -1, false, 2, {{0, +1, 0}, {+1, 0, 0}}}}},              // F2
    {-1, 2, {{-1, -1, false, 3, {{0, 0, +1}, {0, +1, 0}, {+1, 0, 0}}},    // B1
             {+1, +1, false, 2, {{0, -1, 0}, {-1, 0, 0}}}}}}};            // B2

inline constexpr MethodDef kVCVDT8 = {VectorTransformMethod::VCVDT8, false, {
    {+1, 4, {{+1, +1, false, 3, {{0, 0, -1}, {0, -1, 0}, {-1, 0, 0}}},    // P1
             {+1, -1, false, 2, {{0, -1, 0}, {+1, 0, 0}}},                // P2
             {-1, -1, false, 2, {{0, +1, 0}, {+1, 0, 0}}},                // P3
             {-1, +1, false, 2, {{0, +1, 0}, {-1, 0, 0}}}}},              // P4
    {-1, 4, {{+1, +1, false, 3, {{0, 0, +1}, {0, -1, 0}, {-1, 0, 0}}},    // P1
             {+1, -1, false, 2, {{0, -1, 0}, {+1, 0, 0}}},                // P2
             {-1, -1, false, 2, {{0, +1, 0}, {+1, 0, 0}}},                // P3
             {-1, +1, false, 2, {{0, +1, 0}, {-1, 0, 0}}}}}}};            // P4

inline constexpr SweepDef kEVDTForward =
    {+1, 3, {{+1, +1, false, 3, {{0, 0, -1}, {0, -1, 0}, {-1, 0, 0}}},    // F1
             {+1, -1, true,  1, {{+1, 0, 0}}},                            // F2 (after each F1 row)
             {-1, -1, false, 2, {{0, +1, 0}, {+1, 0, 0}}}}};              // F3
inline constexpr SweepDef kEVDTBackward =
    {-1, 3, {{-1, -1, false, 3, {{0, 0, +1}, {0, +1, 0}, {+1, 0, 0}}},    // B1
             {-1, +1, true,  1, {{-1, 0, 0}}},                            // B2 (after each B1 row)
             {+1, +1, false, 2, {{0, -1, 0}, {-1, 0, 0}}}}};              // B3
inline constexpr MethodDef kEVDT = {VectorTransformMethod::EVDT, true, {kEVDTForward, kEVDTBackward}};
inline constexpr MethodDef kEVDTFullGrid = {VectorTransformMethod::EVDTFullGrid, false,
                                            {kEVDTForward, kEVDTBackward}};
// clang-format on

/// The pass table of a method.
constexpr const MethodDef& methodDef(VectorTransformMethod m)
{
    return m == VectorTransformMethod::VCVDT4         ? kVCVDT4
           : m == VectorTransformMethod::VCVDT8       ? kVCVDT8
           : m == VectorTransformMethod::EVDTFullGrid ? kEVDTFullGrid
                                                      : kEVDT;
}

// Every pass must have the shape the kernel implements: candidates in the order vertical
// (0,0,±1), previous row (0,-yOrder,0), previous voxel of the row (-xOrder,0,0), the last one
// always present; a perRow pass has only the in-row neighbour.
constexpr bool passShapeOk(const PassDef& p, int zOrder)
{
    if (p.neighbourCount < 1 || p.neighbourCount > 3) return false;
    if ((p.xOrder != 1 && p.xOrder != -1) || (p.yOrder != 1 && p.yOrder != -1)) return false;
    const Offset last = p.neighbours[p.neighbourCount - 1];
    if (last.x != -p.xOrder || last.y != 0 || last.z != 0) return false;
    int i = 0;
    if (i < p.neighbourCount - 1 && p.neighbours[i].z != 0) {
        if (p.neighbours[i].z != -zOrder || p.neighbours[i].x != 0 || p.neighbours[i].y != 0) return false;
        ++i;
    }
    if (i < p.neighbourCount - 1) {
        if (p.neighbours[i].y != -p.yOrder || p.neighbours[i].x != 0 || p.neighbours[i].z != 0) return false;
        ++i;
    }
    if (i != p.neighbourCount - 1) return false;
    if (p.perRow && p.neighbourCount != 1) return false;
    return true;
}

constexpr bool methodShapeOk(const MethodDef& m)
{
    for (int s = 0; s < 2; ++s) {
        const SweepDef& sw = m.sweeps[s];
        if (sw.passCount < 1 || sw.passCount > 4 || sw.passes[0].perRow) return false;
        for (int p = 0; p < sw.passCount; ++p) {
            if (!passShapeOk(sw.passes[p], sw.zOrder)) return false;
            if (sw.passes[p].perRow && sw.passes[p].yOrder != sw.passes[p - 1].yOrder) return false;
            // Only the first pass reads the previous slice (the grouped layout relies on it).
            for (int i = 0; p > 0 && i < sw.passes[p].neighbourCount; ++i)
                if (sw.passes[p].neighbours[i].z != 0) return false;
        }
    }
    return m.sweeps[0].zOrder == 1 && m.sweeps[1].zOrder == -1;
}

static_assert(methodShapeOk(kVCVDT4), "VCVDT4 pass table");
static_assert(methodShapeOk(kVCVDT8), "VCVDT8 pass table");
static_assert(methodShapeOk(kEVDT), "EVDT pass table");
static_assert(methodShapeOk(kEVDTFullGrid), "EVDT full grid pass table");

/// Whether the per-row kernel runs its AVX2 build on this CPU (x86-64 with AVX2). Both builds
/// perform the same IEEE single-precision operations (the element-wise candidates 8 lanes wide
/// with AVX2, as two 4-lane halves in the baseline; no FMA), so results are bit-identical; only
/// the speed differs.
bool avx2KernelAvailable();

/// Testing hook: false forces the baseline build of the kernel (process-wide; not for use while
/// a transform runs on another thread).
void setAvx2KernelEnabled(bool enabled);

} // namespace levelforge::vector_transform_internal
