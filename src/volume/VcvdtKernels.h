// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the vector distance transforms: the grouped working layout, the 8-wide
///        vector helpers, and the per-row kernel (element-wise candidates and in-row chain) in
///        its baseline and AVX2 builds, picked once per transform by Kernel.
///
/// Working layout. For the duration of a transform each row is kept in groups of 8 voxels along
/// x (AoSoA): group g of a row holds x[8], y[8], z[8], d2[8] (a row's last group of
/// w = nx - 8g < 8 voxels has the same layout with stride w). The bytes of a group are the bytes
/// of its 8 ClosestVectors, so the in-place route adds no memory (VectorDistanceTransform.cc
/// reorders the volume's rows in and out of this layout; VcvdtMaskEntry.cc fills slice buffers
/// in it directly).
#pragma once

#include "volume/VectorDistanceTransformInternal.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define LEVELFORGE_PREFETCH(p) _mm_prefetch((p), _MM_HINT_T0)
#else
#define LEVELFORGE_PREFETCH(p) __builtin_prefetch((p))
#endif

#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
/// The AVX2 builds of the row kernel and of the mask entry's row conversions exist.
#define LEVELFORGE_VDT_AVX 1
#endif

#define LEVELFORGE_AI inline __attribute__((always_inline))

namespace levelforge::vector_transform_internal {

inline constexpr float kInf = std::numeric_limits<float>::infinity();

/// The voxel spacing in single precision, as the passes use it.
struct Spacing
{
    float sx, sy, sz;
};

/// Voxels per group of the working layout.
constexpr int kGroup = 8;

/// Voxels in group g of a row of nx voxels (8, or fewer in the row's last group).
inline int groupWidth(int g, int nx) { return std::min(kGroup, nx - g * kGroup); }

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
using v8f = float __attribute__((vector_size(32)));
using v8i = int32_t __attribute__((vector_size(32)));

LEVELFORGE_AI v8f load8(const float* p)
{
    v8f v;
    std::memcpy(&v, p, sizeof(v));
    return v;
}
LEVELFORGE_AI void store8(float* p, const v8f& v) { std::memcpy(p, &v, sizeof(v)); }

/// Whether any lane of a comparison result is set.
LEVELFORGE_AI bool anyLane(const v8i& m)
{
    uint64_t bits[4];
    std::memcpy(bits, &m, sizeof(bits));
    return (bits[0] | bits[1] | bits[2] | bits[3]) != 0;
}
#pragma GCC diagnostic pop

/// The chain carried along a row: the previous voxel's final vector and its Y*Y + Z*Z.
struct Carry
{
    float x = kInf, y = kInf, z = kInf, yz = kInf;
};

/// One row's share of a pass, on the grouped layout: rows are nx voxels = 4 * nx floats.
struct RowTask
{
    float* row;
    const float* prevRow; // null: no previous-row candidate (first row, or not in the pass)
    const float* vertRow; // null: no vertical candidate
    float oy, oz;
    int xs;
    int g0, g1; // groups of the span
    int nx;
};

/// The kernel build (baseline or AVX2) chosen once per transform (VcvdtKernels.cc).
struct Kernel
{
    /// The element-wise part of a pass on a row task: the vertical candidate (previous slice,
    /// offset oz) and the previous-row candidate (offset oy), in the table order, neither of
    /// which depends on the row's own chain. Writes each voxel's Y*Y + Z*Z to yz[x].
    void (*candidates)(const RowTask&, float* yz, const Spacing&, bool unit);
    /// The sequential part of a pass on a row task, in x order t.xs (+1 / -1), starting from
    /// the carry (the voxel before the span in pass order, or +inf) and leaving the span's last
    /// voxel in it.
    void (*chain)(const RowTask&, const float* yz, Carry& carry, const Spacing&, bool unit);
    Spacing s{1, 1, 1};
    bool unit = true;  // all spacings are exactly 1 (the multiplications are skipped)
    bool avx2 = false; // the AVX2 builds are in use (also picks MaskIo's row conversions)

    /// The AVX2 build on x86-64 CPUs with AVX2 (unless setAvx2KernelEnabled(false)), else the
    /// baseline build.
    explicit Kernel(const Spacing& sp);
};

} // namespace levelforge::vector_transform_internal
