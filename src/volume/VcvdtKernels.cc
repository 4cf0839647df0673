// SPDX-License-Identifier: Apache-2.0
// The per-row kernel of the vector distance transforms (see VcvdtKernels.h): the element-wise
// candidates (8 voxels per SIMD step) and the in-row chain, in a baseline and an AVX2 build.
#include "volume/VcvdtKernels.h"

#include <atomic>

namespace levelforge::vector_transform_internal {

namespace {

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"

/// One candidate for 8 voxels at once: (nx, ny, nz) replaces (X, Y, Z, D) where its d2 is
/// strictly smaller. The same single-precision operations as the scalar step (no FMA), so
/// every lane gets the bits the scalar code would.
template<bool Unit>
LEVELFORGE_AI void tryCandidate8(v8f& X, v8f& Y, v8f& Z, v8f& D, v8f& YZ, v8i& changed, const v8f& nx,
                                 const v8f& ny, const v8f& nz, const Spacing& s)
{
    const v8f Xs = Unit ? nx : nx * s.sx, Ys = Unit ? ny : ny * s.sy, Zs = Unit ? nz : nz * s.sz;
    const v8f nyz = Ys * Ys + Zs * Zs;
    const v8f d2 = Xs * Xs + nyz;
    const v8i m = d2 < D;
    changed |= m;
    X = m ? nx : X;
    Y = m ? ny : Y;
    Z = m ? nz : Z;
    D = m ? d2 : D;
    YZ = m ? nyz : YZ;
}

template<bool Unit>
LEVELFORGE_AI void tryCandidate1(float& X, float& Y, float& Z, float& D, float& YZ, float nx, float ny, float nz,
                                 const Spacing& s)
{
    const float Xs = Unit ? nx : nx * s.sx, Ys = Unit ? ny : ny * s.sy, Zs = Unit ? nz : nz * s.sz;
    const float nyz = Ys * Ys + Zs * Zs;
    const float d2 = Xs * Xs + nyz;
    if (d2 < D) {
        X = nx;
        Y = ny;
        Z = nz;
        D = d2;
        YZ = nyz;
    }
}

/// The element-wise part of a pass on groups [g0, g1) of one row: the vertical candidate
/// (previous slice, offset oz) and the previous-row candidate (offset oy), in the table order,
/// neither of which depends on the row's own chain. Writes each voxel's Y*Y + Z*Z to yz[x].
template<bool Vert, bool Row, bool Unit>
LEVELFORGE_AI void rowCandidates(float* row, const float* prevRow, const float* vertRow, float* yz, int g0, int g1,
                                 int nx, float oy, float oz, const Spacing& s)
{
    for (int g = g0; g < g1; ++g) {
        const int w = groupWidth(g, nx);
        const size_t off = size_t(g) * kGroup * 4;
        float* c = row + off;
        float* yzg = yz + size_t(g) * kGroup;
        if (w == kGroup) {
            v8f X = load8(c), Y = load8(c + 8), Z = load8(c + 16), D = load8(c + 24);
            const v8f Ys = Unit ? Y : Y * s.sy, Zs = Unit ? Z : Z * s.sz;
            v8f YZ = Ys * Ys + Zs * Zs;
            v8i changed = v8i{};
            if constexpr (Vert) {
                const float* n = vertRow + off;
                tryCandidate8<Unit>(X, Y, Z, D, YZ, changed, load8(n), load8(n + 8), load8(n + 16) + oz, s);
            }
            if constexpr (Row) {
                const float* n = prevRow + off;
                tryCandidate8<Unit>(X, Y, Z, D, YZ, changed, load8(n), load8(n + 8) + oy, load8(n + 16), s);
            }
            if constexpr (Vert || Row) {
                // Most groups keep their vectors: writing only changed groups keeps the lines
                // clean (no write-back, no line shared with the next lane's range dirtied).
                if (anyLane(changed)) {
                    store8(c, X);
                    store8(c + 8, Y);
                    store8(c + 16, Z);
                    store8(c + 24, D);
                }
            }
            store8(yzg, YZ);
        } else {
            for (int l = 0; l < w; ++l) {
                float X = c[l], Y = c[w + l], Z = c[2 * w + l], D = c[3 * w + l];
                const float Ys = Unit ? Y : Y * s.sy, Zs = Unit ? Z : Z * s.sz;
                float YZ = Ys * Ys + Zs * Zs;
                if constexpr (Vert) {
                    const float* n = vertRow + off;
                    tryCandidate1<Unit>(X, Y, Z, D, YZ, n[l], n[w + l], n[2 * w + l] + oz, s);
                }
                if constexpr (Row) {
                    const float* n = prevRow + off;
                    tryCandidate1<Unit>(X, Y, Z, D, YZ, n[l], n[w + l] + oy, n[2 * w + l], s);
                }
                c[l] = X;
                c[w + l] = Y;
                c[2 * w + l] = Z;
                c[3 * w + l] = D;
                yzg[l] = YZ;
            }
        }
    }
}

/// One in-row step on voxel l of a group of width w: the previous voxel's vector moved by ox
/// against the voxel's current one.
template<bool Unit>
LEVELFORGE_AI void chainStep(float* c, const float* yzg, int l, int w, Carry& p, float ox, float sx)
{
    const float cx = p.x + ox;
    const float X = Unit ? cx : cx * sx;
    const float d2 = X * X + p.yz;
    if (d2 < c[3 * w + l]) {
        c[l] = cx;
        c[w + l] = p.y;
        c[2 * w + l] = p.z;
        c[3 * w + l] = d2;
        p.x = cx;
    } else {
        p.x = c[l];
        p.y = c[w + l];
        p.z = c[2 * w + l];
        p.yz = yzg[l];
    }
}

/// The chain through one group (w voxels at c, their Y*Y + Z*Z at yzg) in x order xs.
template<bool Unit>
LEVELFORGE_AI void chainGroup(float* c, const float* yzg, const int w, const int xs, Carry& p, const float ox,
                              const float sx)
{
    if (w == kGroup) {
        // Most groups keep every voxel (about 90 % on a sphere): test all 8 steps at once on
        // the assumption that no voxel changes, each candidate coming from the previous
        // voxel's current vector (the first from the carry). If none wins, the assumption
        // holds and the chain leaves the group as it is; otherwise run the steps one by one.
        // Same operations, so the same comparisons as the scalar steps. (__builtin_shufflevector:
        // GCC >= 12 and clang alike.)
        const v8f X = load8(c), D = load8(c + 24), YZ = load8(yzg);
        const v8f px = v8f{} + p.x, pyz = v8f{} + p.yz;
        const v8f cxs = xs > 0 ? __builtin_shufflevector(X, px, 8, 0, 1, 2, 3, 4, 5, 6)
                               : __builtin_shufflevector(X, px, 1, 2, 3, 4, 5, 6, 7, 8);
        const v8f yzs = xs > 0 ? __builtin_shufflevector(YZ, pyz, 8, 0, 1, 2, 3, 4, 5, 6)
                               : __builtin_shufflevector(YZ, pyz, 1, 2, 3, 4, 5, 6, 7, 8);
        const v8f cx = cxs + ox;
        const v8f Xs = Unit ? cx : cx * sx;
        const v8i win = (Xs * Xs + yzs) < D;
        if (!anyLane(win)) {
            const int last = xs > 0 ? kGroup - 1 : 0;
            p.x = c[last];
            p.y = c[kGroup + last];
            p.z = c[2 * kGroup + last];
            p.yz = yzg[last];
        } else if (xs > 0) {
            for (int l = 0; l < kGroup; ++l) chainStep<Unit>(c, yzg, l, kGroup, p, ox, sx);
        } else {
            for (int l = kGroup - 1; l >= 0; --l) chainStep<Unit>(c, yzg, l, kGroup, p, ox, sx);
        }
    } else {
        // The short last group of a row (stride w): one step at a time.
        for (int k = 0; k < w; ++k) chainStep<Unit>(c, yzg, xs > 0 ? k : w - 1 - k, w, p, ox, sx);
    }
}

/// The sequential part of a pass on groups [g0, g1) of one row, in x order xs (+1 / -1),
/// starting from carry p (the voxel before the span in pass order, or +inf) and leaving the
/// span's last voxel in it.
template<bool Unit>
LEVELFORGE_AI void rowChain(float* row, const float* yz, int g0, int g1, int nx, int xs, Carry& carry, const Spacing& s)
{
    const float ox = float(-xs), sx = s.sx;
    Carry p = carry; // a local copy stays in registers (the row may alias `carry`)
    const int gl = g1 - 1;
    const int wl = groupWidth(gl, nx);
    auto group = [&](int g) __attribute__((always_inline)) {
        chainGroup<Unit>(row + size_t(g) * kGroup * 4, yz + size_t(g) * kGroup, g == gl ? wl : kGroup, xs, p, ox, sx);
    };
    if (xs > 0)
        for (int g = g0; g < g1; ++g) group(g);
    else
        for (int g = g1 - 1; g >= g0; --g) group(g);
    carry = p;
}
#pragma GCC diagnostic pop

/// The element-wise candidates of a row task (the pass shape picks the kernel).
template<bool Unit>
LEVELFORGE_AI void rowTaskCandidates(const RowTask& t, float* yz, const Spacing& s)
{
    if (t.vertRow && t.prevRow)
        rowCandidates<true, true, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
    else if (t.vertRow)
        rowCandidates<true, false, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
    else if (t.prevRow)
        rowCandidates<false, true, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
    else
        rowCandidates<false, false, Unit>(t.row, t.prevRow, t.vertRow, yz, t.g0, t.g1, t.nx, t.oy, t.oz, s);
}

void rowCandidatesBase(const RowTask& t, float* yz, const Spacing& s, bool unit)
{
    if (unit) rowTaskCandidates<true>(t, yz, s);
    else rowTaskCandidates<false>(t, yz, s);
}

void rowChainBase(const RowTask& t, const float* yz, Carry& carry, const Spacing& s, bool unit)
{
    if (unit) rowChain<true>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
    else rowChain<false>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
}

#ifdef LEVELFORGE_VDT_AVX
// The same kernel compiled for AVX2: the element-wise candidates run 8 voxels per instruction,
// the chain gets the VEX three-operand encoding. The arithmetic is the same IEEE single
// precision and FMA is NOT enabled (nothing is contracted), so the results are bit-identical.
__attribute__((target("avx2"))) void rowCandidatesAvx2(const RowTask& t, float* yz, const Spacing& s, bool unit)
{
    if (unit) rowTaskCandidates<true>(t, yz, s);
    else rowTaskCandidates<false>(t, yz, s);
}

__attribute__((target("avx2"))) void rowChainAvx2(const RowTask& t, const float* yz, Carry& carry, const Spacing& s,
                                                  bool unit)
{
    if (unit) rowChain<true>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
    else rowChain<false>(t.row, yz, t.g0, t.g1, t.nx, t.xs, carry, s);
}

bool cpuHasAvx2()
{
    static const bool has = __builtin_cpu_supports("avx2");
    return has;
}
#endif

std::atomic<bool> gAvx2KernelEnabled{true}; // testing hook (vector_transform_internal)

} // namespace

Kernel::Kernel(const Spacing& sp)
    : candidates(rowCandidatesBase), chain(rowChainBase), s(sp),
      unit(sp.sx == 1.0f && sp.sy == 1.0f && sp.sz == 1.0f)
{
#ifdef LEVELFORGE_VDT_AVX
    if (cpuHasAvx2() && gAvx2KernelEnabled.load(std::memory_order_relaxed)) {
        avx2 = true;
        candidates = rowCandidatesAvx2;
        chain = rowChainAvx2;
    }
#endif
}

bool avx2KernelAvailable()
{
#ifdef LEVELFORGE_VDT_AVX
    return cpuHasAvx2();
#else
    return false;
#endif
}

void setAvx2KernelEnabled(bool enabled) { gAvx2KernelEnabled.store(enabled, std::memory_order_relaxed); }

} // namespace levelforge::vector_transform_internal
