// SPDX-License-Identifier: Apache-2.0
// The fast sweeping method of the expansion: Godunov updates swept leaf by leaf on sparse VDB
// topology (see src/expand/FastSweeping.h).
#include "detail/ProgressCheck.h"
#include "expand/FastSweepingInternal.h"

#include <levelforge/core/Progress.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#ifdef __SSE__
#include <xmmintrin.h>
#endif

namespace levelforge::fast_sweeping_internal {

namespace {

using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using MaskT = LeafT::NodeMaskType;
using openvdb::Coord;

/// One voxel update: Godunov upwind solution of |∇φ| = 1 from the neighbour magnitudes
/// (world units; h = voxel size, h2 = h²). Single precision with the discriminants written as
/// sums of squared differences (2h² − (a1 − a0)², 3h² − Σ (ai − aj)²), which do not cancel.
inline float sqrtNonNegative(float x)
{
#ifdef __SSE__
    return _mm_cvtss_f32(_mm_sqrt_ss(_mm_set_ss(x))); // no errno branch
#else
    return std::sqrt(x);
#endif
}

inline float godunov(float a0, float a1, float a2, float h, float h2)
{
    const float lo = std::min(a0, a1), hi = std::max(a0, a1);
    a0 = std::min(lo, a2);
    const float mid = std::max(lo, a2);
    a1 = std::min(mid, hi);
    a2 = std::max(mid, hi);
    // the three candidates side by side (two independent square roots, no unpredictable branch)
    const float u1 = a0 + h;
    const float d01 = a1 - a0, d02 = a2 - a0, d12 = a2 - a1;
    const float u2 = 0.5f * (a0 + a1 + sqrtNonNegative(std::max(2.0f * h2 - d01 * d01, 0.0f)));
    const float disc = 3.0f * h2 - (d01 * d01 + d02 * d02 + d12 * d12);
    const float u3 = (a0 + a1 + a2 + sqrtNonNegative(std::max(disc, 0.0f))) * (1.0f / 3.0f);
    return u1 <= a1 ? u1 : (u2 <= a2 ? u2 : u3);
}

/// bit b of a byte -> bit 8b of a word (a column of a leaf's z face into mask-word layout)
struct SpreadTable
{
    uint64_t t[256];
    SpreadTable()
    {
        for (int v = 0; v < 256; ++v) {
            uint64_t w = 0;
            for (int b = 0; b < 8; ++b) if (v >> b & 1) w |= uint64_t(1) << (8 * b);
            t[v] = w;
        }
    }
};
const SpreadTable kSpread;

/// the values of a missing neighbour leaf
struct Nowhere
{
    float v[512];
    Nowhere() { std::fill(v, v + 512, kBig); }
};
const Nowhere kNowhere;

/// The sweeper: leaves of the expanded tree, their face neighbours, updatable masks, per-voxel
/// dirty bits (a voxel is re-evaluated only when a neighbour changed in a way its update can
/// see; its Godunov value depends on nothing else, so skipping it changes no result) and the
/// leaf schedule of the file comment (pending keys, passes per leaf).
class Sweeper
{
public:
    /// capPos / capNeg: voxels whose value would not be below the cap (world units) on their side
    /// are left unreached (they are trimmed afterwards anyway, and no voxel below the cap
    /// depends on them: the upwind stencil only reads smaller values).
    Sweeper(FloatTree& tree, const FloatTree& frozen, float h, float tol, float capPos, float capNeg,
            openvdb::util::NullInterrupter* interrupter)
        : mH(h), mTol(tol), mCapPos(capPos), mCapNeg(capNeg), mInterrupter(interrupter)
    {
        tree.getNodes(mLeaves);
        const size_t n = mLeaves.size();
        // leaf origin -> index: a dense grid of leaf cells when small, else a sorted list
        Coord lo(std::numeric_limits<int32_t>::max()), hi(std::numeric_limits<int32_t>::min());
        for (size_t i = 0; i < n; ++i) {
            const Coord c = mLeaves[i]->origin() >> 3;
            lo.minComponent(c);
            hi.maxComponent(c);
        }
        const double cells = n ? double(hi.x() - lo.x() + 3) * double(hi.y() - lo.y() + 3) *
                                     double(hi.z() - lo.z() + 3)
                               : 0.0;
        const bool dense = cells <= double(1 << 23);
        std::vector<int32_t> grid;
        std::vector<std::pair<Coord, int32_t>> sorted;
        const int64_t dimY = hi.y() - lo.y() + 3, dimZ = hi.z() - lo.z() + 3;
        auto cell = [&](const Coord& c) { // c: leaf coordinates within [lo - 1, hi + 1]
            return ((int64_t(c.x()) - lo.x() + 1) * dimY + (int64_t(c.y()) - lo.y() + 1)) * dimZ +
                   (int64_t(c.z()) - lo.z() + 1);
        };
        if (dense) {
            grid.assign(size_t(cells), -1);
            for (size_t i = 0; i < n; ++i) grid[size_t(cell(mLeaves[i]->origin() >> 3))] = int32_t(i);
        } else {
            sorted.reserve(n);
            for (size_t i = 0; i < n; ++i) sorted.emplace_back(mLeaves[i]->origin(), int32_t(i));
            std::sort(sorted.begin(), sorted.end(),
                      [](const auto& a, const auto& b) { return a.first < b.first; });
        }
        auto find = [&](const Coord& origin) -> int32_t {
            if (dense) return grid[size_t(cell(origin >> 3))];
            auto it = std::lower_bound(sorted.begin(), sorted.end(), origin,
                                       [](const auto& a, const Coord& c) { return a.first < c; });
            return it != sorted.end() && it->first == origin ? it->second : -1;
        };
        mNb.assign(n * 6, -1);
        mUpd.assign(n * 8, 0);
        mDirty.assign(n * 8, 0);
        mOut.assign(n * 6, 0);
        mSide.assign(n, 0);
        mHasWork.assign(n, 0);
        std::vector<char> hasFixed(n, 0);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                LeafT& leaf = *mLeaves[i];
                const Coord o = leaf.origin();
                for (int k = 0; k < 3; ++k) {
                    for (int s = 0; s < 2; ++s) {
                        Coord c = o;
                        c[k] += s ? 8 : -8;
                        mNb[i * 6 + k * 2 + s] = find(c);
                    }
                }
                MaskT upd = leaf.getValueMask();
                if (const LeafT* f = frozen.probeConstLeaf(o)) {
                    upd -= f->getValueMask();
                } else if (frozen.isValueOn(o)) {
                    upd.setOff(); // an active tile of the input covers this leaf
                }
                mHasWork[i] = upd.isOff() ? 0 : 1;
                // Working values: inactive voxels are "not in the domain", new voxels not reached.
                float* v = leaf.buffer().data();
                bool pos = false, neg = false;
                const MaskT& on = leaf.getValueMask();
                for (int x = 0; x < 8; ++x) {
                    const uint64_t uw = upd.getWord<uint64_t>(x), reset = uw | ~on.getWord<uint64_t>(x);
                    float* vx = v + 64 * x;
                    for (int b = 0; b < 64; ++b) {
                        if (reset >> b & 1) vx[b] = std::copysign(kBig, vx[b]);
                        if (uw >> b & 1) (vx[b] < 0 ? neg : pos) = true;
                    }
                }
                mSide[i] = pos == neg ? 0 : (pos ? 1 : -1);
                for (int x = 0; x < 8; ++x) mUpd[i * 8 + x] = upd.getWord<uint64_t>(x);
                MaskT fixed = leaf.getValueMask();
                fixed -= upd;
                hasFixed[i] = fixed.isOff() ? 0 : 1;
            }
        });
        // First evaluations: the leaves that hold a fixed (input band) value, keyed by the
        // smallest fixed magnitude next to one of their updatable voxels (and, rarely, the leaves
        // touching a fixed value of a leaf without updatable voxels). A leaf holding fixed
        // values sends them to its face neighbours after its first pass (processLeaf), so
        // those wait for it; a voxel elsewhere has only unreached neighbours until one of them
        // changes (and marks it).
        mVisits.assign(n, 0);
        mKey.reset(new std::atomic<uint32_t>[n]);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                mKey[i].store(kNoKey, std::memory_order_relaxed);
                if (!mHasWork[i]) continue;
                float key = kBig;
                if (hasFixed[i]) {
                    const uint64_t* u = &mUpd[i * 8];
                    const MaskT& on = mLeaves[i]->getValueMask();
                    const float* v = mLeaves[i]->buffer().data();
                    float adjacent = kBig, any = kBig;
                    for (int x = 0; x < 8; ++x) {
                        const uint64_t dil = u[x] | (x > 0 ? u[x - 1] : 0) | (x < 7 ? u[x + 1] : 0) |
                                             (u[x] << 8) | (u[x] >> 8) |
                                             ((u[x] << 1) & ~0x0101010101010101ull) |
                                             ((u[x] >> 1) & ~0x8080808080808080ull);
                        const uint64_t fixed = on.getWord<uint64_t>(x) & ~u[x];
                        for (uint64_t b = fixed; b; b &= b - 1) {
                            const float a = std::abs(v[64 * x + __builtin_ctzll(b)]);
                            any = std::min(any, a);
                            if (dil >> __builtin_ctzll(b) & 1) adjacent = std::min(adjacent, a);
                        }
                    }
                    key = adjacent < kBig ? adjacent : any;
                } else {
                    for (int k = 0; k < 6; ++k) {
                        const int32_t nb = mNb[i * 6 + k];
                        if (nb >= 0 && hasFixed[nb] && !mHasWork[nb]) key = 0.0f;
                    }
                }
                if (!(key < kBig)) continue;
                for (int x = 0; x < 8; ++x) mDirty[i * 8 + x] = mUpd[i * 8 + x];
                mKey[i].store(floatToBits(key), std::memory_order_relaxed);
            }
        });
        mHasFixed.swap(hasFixed);
        mDelta = 8.0f * h;
    }

    uint64_t candidateVoxels() const
    {
        uint64_t c = 0;
        for (const LeafT* l : mLeaves) c += l->onVoxelCount();
        return c;
    }

    /// Leaf-level marching (see the file comment): processes leaves until none has pending
    /// input, or only leaves already processed maxIterations times have.
    void run(int maxIterations, ExpandLevelSetStats& stats)
    {
        const size_t n = mLeaves.size();
        std::vector<int32_t> work; // leaves with updatable voxels
        std::vector<char> colour(n, 0), inWindow(n, 0); // colour: leaf-coordinate parity
        for (size_t i = 0; i < n; ++i) {
            if (!mHasWork[i]) continue;
            const Coord o = mLeaves[i]->origin();
            colour[i] = char(((o.x() >> 3) + (o.y() >> 3) + (o.z() >> 3)) & 1);
            work.push_back(int32_t(i));
        }
        const int maxVisits = std::min(std::max(1, maxIterations), 65535); // (mVisits: 16 bits)
        auto key = [&](int32_t li) {
            return mVisits[li] < maxVisits ? mKey[li].load(std::memory_order_relaxed) : kNoKey;
        };
        std::atomic<uint64_t> leafUpdates{0}, voxelEvaluations{0};
        std::vector<int32_t> window, list;
        const float capMax = std::max(std::min(mCapPos, 1e20f), std::min(mCapNeg, 1e20f));
        for (;;) {
            uint32_t kmin = kNoKey;
            for (int32_t li : work) kmin = std::min(kmin, key(li));
            if (kmin == kNoKey) break;
            const float kminF = bitsToFloat(kmin);
            const int percent = std::min(99, int(100.0 * kminF / std::max(capMax, mH)));
            // the leaves with pending input below kmin + delta (the window), by colour, until
            // none is left; a leaf enters the window when it is found there at the start or a
            // neighbour processed in this step gave it such input
            const uint32_t limit = floatToBits(kminF + mDelta);
            window.clear();
            for (int32_t li : work) {
                if (key(li) < limit) { window.push_back(li); inWindow[li] = 1; }
            }
            while (!window.empty()) {
                progress_internal::check(mInterrupter, percent);
                for (int c = 0; c < 2; ++c) {
                    list.clear();
                    for (int32_t li : window) {
                        if (colour[li] != c) continue;
                        const uint32_t k = key(li);
                        if (k >= limit) continue;
                        // wait while a face neighbour has smaller pending input: processing it
                        // first may still lower this leaf's input
                        bool wait = false;
                        for (int f = 0; f < 6 && !wait; ++f) {
                            const int32_t nb = mNb[li * 6 + f];
                            wait = nb >= 0 && key(nb) < k;
                        }
                        if (!wait) list.push_back(li);
                    }
                    if (list.empty()) continue;
                    tbb::parallel_for(tbb::blocked_range<size_t>(0, list.size(), 2),
                                      [&](const tbb::blocked_range<size_t>& r) {
                        uint64_t done = 0, evals = 0;
                        for (size_t k = r.begin(); k != r.end(); ++k) processLeaf(list[k], done, evals);
                        leafUpdates += done;
                        voxelEvaluations += evals;
                    });
                    for (int32_t li : list) {
                        for (int f = 0; f < 6; ++f) {
                            const int32_t nb = mNb[li * 6 + f];
                            if (nb >= 0 && !inWindow[nb] && key(nb) < limit) {
                                window.push_back(nb);
                                inWindow[nb] = 1;
                            }
                        }
                    }
                }
                // keep the leaves still pending below the limit
                size_t kept = 0;
                for (int32_t li : window) {
                    if (key(li) < limit) window[kept++] = li;
                    else inWindow[li] = 0;
                }
                window.resize(kept);
            }
        }
        bool converged = true;
        int visits = 0;
        for (size_t i = 0; i < n; ++i) {
            visits = std::max(visits, int(mVisits[i]));
            if (mHasWork[i] && mKey[i].load(std::memory_order_relaxed) != kNoKey) converged = false;
        }
        stats.iterations = visits;
        // converged: every change above the tolerance was passed on and re-solved; what is left
        // is the largest change that was not (at most the tolerance)
        stats.maxChange = converged ? double(bitsToFloat(mDropped.load())) / double(mH)
                                    : std::numeric_limits<double>::infinity();
        stats.converged = converged;
        stats.leafUpdates = leafUpdates;
        stats.voxelUpdates = voxelEvaluations;
    }

private:
    static constexpr uint32_t kNoKey = 0xffffffffu;
    static uint32_t floatToBits(float f) { uint32_t b; std::memcpy(&b, &f, 4); return b; }
    static float bitsToFloat(uint32_t b) { float f; std::memcpy(&f, &b, 4); return f; }

    /// Imports the marks of the neighbours, then Gauss–Seidel sweeps of the leaf on a padded
    /// 10^3 copy until none of its voxels is dirty: the first ordering runs away from the halo
    /// face with the smaller minimum along each axis, each next one reverses the axes along
    /// which a change marked an already visited voxel. Finally the neighbours that got marks
    /// get their pending key lowered to the smallest new value sent to them.
    void processLeaf(int32_t li, uint64_t& done, uint64_t& evals)
    {
        mKey[li].store(kNoKey, std::memory_order_relaxed);
        ++mVisits[li];
        uint64_t* d = &mDirty[size_t(li) * 8];
        const uint64_t* upd = &mUpd[size_t(li) * 8];
        // dirty bits from the faces of the neighbours that changed since they were last read
        for (int k = 0; k < 3; ++k) {
            for (int s = 0; s < 2; ++s) {
                const int32_t n = mNb[li * 6 + k * 2 + s];
                if (n < 0) continue;
                uint64_t& in = mOut[size_t(n) * 6 + k * 2 + (1 - s)];
                const uint64_t m = in;
                if (!m) continue;
                in = 0;
                const int face = s ? 7 : 0;
                if (k == 0) {
                    d[face] |= m & upd[face];
                } else if (k == 1) {
                    for (int a = 0; a < 8; ++a) d[a] |= (((m >> (8 * a)) & 0xff) << (8 * face)) & upd[a];
                } else {
                    for (int a = 0; a < 8; ++a) d[a] |= (kSpread.t[(m >> (8 * a)) & 0xff] << face) & upd[a];
                }
            }
        }
        uint64_t anyDirty = 0;
        for (int x = 0; x < 8; ++x) anyDirty |= d[x] & upd[x];
        if (!anyDirty) return;
        ++done;
        LeafT& leaf = *mLeaves[li];
        float* v = leaf.buffer().data();
        float P[10 * 10 * 10];
        auto pid = [](int x, int y, int z) { return (x + 1) * 100 + (y + 1) * 10 + (z + 1); };
        const float side = float(mSide[li]);
        const bool uniform = side != 0.0f;
        auto mag = [](float w, float sgn) {
            float r = w * sgn;
            if (r < 0) r = (r > -kBig * 0.5f) ? 0.0f : kBig; // across the surface
            return r;
        };
        if (uniform) {
            for (int x = 0; x < 8; ++x)
                for (int y = 0; y < 8; ++y)
                    for (int z = 0; z < 8; ++z) P[pid(x, y, z)] = mag(v[(x << 6) | (y << 3) | z], side);
        } else {
            for (int x = 0; x < 8; ++x)
                for (int y = 0; y < 8; ++y)
                    for (int z = 0; z < 8; ++z) P[pid(x, y, z)] = v[(x << 6) | (y << 3) | z];
        }
        // halo: face neighbours (missing leaves: "not in the domain")
        static const int kLeafStride[3] = {64, 8, 1}, kPadStride[3] = {100, 10, 1};
        for (int k = 0; k < 3; ++k) {
            const int ka = (k + 1) % 3, kb = (k + 2) % 3;
            for (int s = 0; s < 2; ++s) {
                const int32_t n = mNb[li * 6 + k * 2 + s];
                const int outerOff = (s ? 0 : 7) * kLeafStride[k];
                const int padOff = (s ? 9 : 0) * kPadStride[k];
                if (n < 0) {
                    for (int i = 0; i < 8; ++i)
                        for (int j = 0; j < 8; ++j)
                            P[(i + 1) * kPadStride[ka] + (j + 1) * kPadStride[kb] + padOff] = kBig;
                    continue;
                }
                const float* nv = mLeaves[n]->buffer().data();
                for (int i = 0; i < 8; ++i) {
                    for (int j = 0; j < 8; ++j) {
                        const int base = i * kLeafStride[ka] + j * kLeafStride[kb];
                        const int pad = (i + 1) * kPadStride[ka] + (j + 1) * kPadStride[kb] + padOff;
                        const float w = nv[base + outerOff];
                        P[pad] = uniform ? mag(w, side) : w;
                    }
                }
            }
        }
        const float h = mH, h2 = mH * mH;
        uint64_t* out = &mOut[size_t(li) * 6];
        const float* nvf[6]; // face neighbours' values (none: "not in the domain")
        for (int f = 0; f < 6; ++f) {
            const int32_t n = mNb[li * 6 + f];
            nvf[f] = n >= 0 ? mLeaves[n]->buffer().data() : kNowhere.v;
        }
        float outMin[6] = {kBig, kBig, kBig, kBig, kBig, kBig};
        float dropped = 0.0f; // the largest change not passed on (at most the tolerance)
        uint64_t evaluations = 0;
        // the first ordering runs from the halo face with the smaller minimum to the opposite one
        int sx, sy, sz;
        {
            float hs[6];
            for (int k = 0; k < 3; ++k) {
                const int ka = (k + 1) % 3, kb = (k + 2) % 3;
                for (int s = 0; s < 2; ++s) {
                    const int padOff = (s ? 9 : 0) * kPadStride[k];
                    float mn = kBig;
                    for (int i = 0; i < 8; ++i)
                        for (int j = 0; j < 8; ++j) {
                            float w = P[(i + 1) * kPadStride[ka] + (j + 1) * kPadStride[kb] + padOff];
                            if (!uniform) w = std::abs(w);
                            mn = std::min(mn, w);
                        }
                    hs[k * 2 + s] = mn;
                }
            }
            sx = hs[0] <= hs[1] ? 1 : -1;
            sy = hs[2] <= hs[3] ? 1 : -1;
            sz = hs[4] <= hs[5] ? 1 : -1;
        }
        for (;;) {
            // back[k]: a change marked a voxel behind it along axis k (already visited)
            bool backX = false, backY = false, backZ = false;
            // A changed voxel makes its neighbours dirty (across a face: the neighbour leaf's), in
            // a leaf with both signs all six; their evaluations are skipped only when they cannot
            // change (see touchUniform).
            auto touchAll = [&](int x, int y, int z, float un) __attribute__((always_inline)) {
                const int j = (y << 3) | z;
                if (z > 0) { d[x] |= uint64_t(1) << (j - 1); backZ |= sz > 0; }
                else { out[4] |= uint64_t(1) << ((x << 3) | y); outMin[4] = std::min(outMin[4], un); }
                if (z < 7) { d[x] |= uint64_t(1) << (j + 1); backZ |= sz < 0; }
                else { out[5] |= uint64_t(1) << ((x << 3) | y); outMin[5] = std::min(outMin[5], un); }
                if (y > 0) { d[x] |= uint64_t(1) << (j - 8); backY |= sy > 0; }
                else { out[2] |= uint64_t(1) << ((x << 3) | z); outMin[2] = std::min(outMin[2], un); }
                if (y < 7) { d[x] |= uint64_t(1) << (j + 8); backY |= sy < 0; }
                else { out[3] |= uint64_t(1) << ((x << 3) | z); outMin[3] = std::min(outMin[3], un); }
                if (x > 0) { d[x - 1] |= uint64_t(1) << j; backX |= sx > 0; }
                else { out[0] |= uint64_t(1) << j; outMin[0] = std::min(outMin[0], un); }
                if (x < 7) { d[x + 1] |= uint64_t(1) << j; backX |= sx < 0; }
                else { out[1] |= uint64_t(1) << j; outMin[1] = std::min(outMin[1], un); }
            };
            // Uniform leaves (one sign): a neighbour q is marked only when it can use the new
            // value un, i.e. un is below q's magnitude and below q's other neighbour r along the
            // same axis (q's upwind value on that axis is min(p, r); if r <= un it stays r bit
            // for bit). Across a face, r is read from the neighbour leaf, and a q there that may
            // lie on the other side of the surface (seen from here: 0 if reached, kBig if not)
            // is marked when this voxel is reached for the first time (q then sees the surface
            // between them: 0 instead of kBig).
            auto faceMark = [&](int f, int p2, int rIdx, int bit, float un, bool first) __attribute__((always_inline)) {
                const float q = P[p2];
                if ((first && (q == 0.0f || q >= kBig * 0.5f)) ||
                    (q > un && mag(nvf[f][rIdx], side) > un)) {
                    out[f] |= uint64_t(1) << bit;
                    outMin[f] = std::min(outMin[f], un);
                }
            };
            auto touchUniform = [&](int x, int y, int z, int p, float un, bool first) __attribute__((always_inline)) {
                const int j = (y << 3) | z;
                if (z > 0) {
                    if (std::min(P[p - 1], P[p - 2]) > un) { d[x] |= uint64_t(1) << (j - 1); backZ |= sz > 0; }
                } else faceMark(4, p - 1, (x << 6) | (y << 3) | 6, (x << 3) | y, un, first);
                if (z < 7) {
                    if (std::min(P[p + 1], P[p + 2]) > un) { d[x] |= uint64_t(1) << (j + 1); backZ |= sz < 0; }
                } else faceMark(5, p + 1, (x << 6) | (y << 3) | 1, (x << 3) | y, un, first);
                if (y > 0) {
                    if (std::min(P[p - 10], P[p - 20]) > un) { d[x] |= uint64_t(1) << (j - 8); backY |= sy > 0; }
                } else faceMark(2, p - 10, (x << 6) | (6 << 3) | z, (x << 3) | z, un, first);
                if (y < 7) {
                    if (std::min(P[p + 10], P[p + 20]) > un) { d[x] |= uint64_t(1) << (j + 8); backY |= sy < 0; }
                } else faceMark(3, p + 10, (x << 6) | (1 << 3) | z, (x << 3) | z, un, first);
                if (x > 0) {
                    if (std::min(P[p - 100], P[p - 200]) > un) { d[x - 1] |= uint64_t(1) << j; backX |= sx > 0; }
                } else faceMark(0, p - 100, (6 << 6) | j, j, un, first);
                if (x < 7) {
                    if (std::min(P[p + 100], P[p + 200]) > un) { d[x + 1] |= uint64_t(1) << j; backX |= sx < 0; }
                } else faceMark(1, p + 100, (1 << 6) | j, j, un, first);
            };
            for (int xi = 0; xi < 8; ++xi) {
                const int x = sx > 0 ? xi : 7 - xi;
                if (!(d[x] & upd[x])) continue;
                for (int yi = 0; yi < 8; ++yi) {
                    const int y = sy > 0 ? yi : 7 - yi;
                    if (!(((d[x] & upd[x]) >> (8 * y)) & 0xff)) continue;
                    for (int zi = 0; zi < 8; ++zi) {
                        const int z = sz > 0 ? zi : 7 - zi;
                        const int j = (y << 3) | z;
                        const uint64_t bit = uint64_t(1) << j;
                        if (!(d[x] & upd[x] & bit)) continue;
                        d[x] &= ~bit;
                        const int p = pid(x, y, z);
                        if (uniform) {
                            const float m = P[p];
                            const float ax = std::min(P[p - 100], P[p + 100]);
                            const float ay = std::min(P[p - 10], P[p + 10]);
                            const float az = std::min(P[p - 1], P[p + 1]);
                            if (std::min(ax, std::min(ay, az)) >= kBig * 0.5f) continue;
                            ++evaluations;
                            const float un = godunov(ax, ay, az, h, h2);
                            if (un < m && un < (side > 0 ? mCapPos : mCapNeg)) {
                                P[p] = un;
                                v[(x << 6) | j] = un * side;
                                // a change of at most the tolerance is not passed on: rounding
                                // creep would otherwise ripple through the band
                                const bool first = m >= kBig * 0.5f;
                                if (first || m - un > mTol) touchUniform(x, y, z, p, un, first);
                                else dropped = std::max(dropped, m - un);
                            }
                            continue;
                        }
                        const float u = P[p];
                        const float sgn = u < 0 ? -1.0f : 1.0f;
                        const float m = u * sgn;
                        const float ax = std::min(mag(P[p - 100], sgn), mag(P[p + 100], sgn));
                        const float ay = std::min(mag(P[p - 10], sgn), mag(P[p + 10], sgn));
                        const float az = std::min(mag(P[p - 1], sgn), mag(P[p + 1], sgn));
                        if (std::min(ax, std::min(ay, az)) >= kBig * 0.5f) continue;
                        ++evaluations;
                        const float un = godunov(ax, ay, az, h, h2);
                        if (un < m && un < (sgn > 0 ? mCapPos : mCapNeg)) {
                            P[p] = un * sgn;
                            v[(x << 6) | j] = un * sgn;
                            touchAll(x, y, z, un);
                        }
                    }
                }
            }
            uint64_t left = 0;
            for (int x = 0; x < 8; ++x) left |= d[x] & upd[x];
            if (!left) break;
            if (!(backX || backY || backZ)) backX = backY = backZ = true; // (not expected)
            if (backX) sx = -sx;
            if (backY) sy = -sy;
            if (backZ) sz = -sz;
        }
        if (mVisits[li] == 1 && mHasFixed[li]) {
            // first pass of a leaf with fixed values: they are new input for the neighbours
            const MaskT& on = leaf.getValueMask();
            uint64_t fz[8];
            for (int x = 0; x < 8; ++x) fz[x] = on.getWord<uint64_t>(x) & ~upd[x];
            auto send = [&](int f, int voxel, int bit) {
                out[f] |= uint64_t(1) << bit;
                outMin[f] = std::min(outMin[f], std::abs(v[voxel]));
            };
            for (int x = 0; x < 8; ++x) {
                for (uint64_t b = fz[x]; b; b &= b - 1) {
                    const int j = __builtin_ctzll(b), y = j >> 3, z = j & 7;
                    if (x == 0) send(0, j, j);
                    if (x == 7) send(1, (7 << 6) | j, j);
                    if (y == 0) send(2, (x << 6) | j, (x << 3) | z);
                    if (y == 7) send(3, (x << 6) | j, (x << 3) | z);
                    if (z == 0) send(4, (x << 6) | j, (x << 3) | y);
                    if (z == 7) send(5, (x << 6) | j, (x << 3) | y);
                }
            }
        }
        // tell the neighbours (of the other colour: not running now) that input is waiting
        for (int f = 0; f < 6; ++f) {
            if (!(outMin[f] < kBig)) continue;
            const int32_t n = mNb[li * 6 + f];
            if (n < 0 || !mHasWork[n]) continue;
            const uint32_t key = floatToBits(outMin[f]);
            uint32_t cur = mKey[n].load(std::memory_order_relaxed);
            while (key < cur && !mKey[n].compare_exchange_weak(cur, key, std::memory_order_relaxed)) {}
        }
        evals += evaluations;
        if (dropped > 0.0f) { // non-negative floats order like their bits
            const uint32_t b = floatToBits(dropped);
            uint32_t cur = mDropped.load(std::memory_order_relaxed);
            while (b > cur && !mDropped.compare_exchange_weak(cur, b, std::memory_order_relaxed)) {}
        }
    }

    std::vector<LeafT*> mLeaves;
    std::vector<int32_t> mNb;
    std::vector<uint64_t> mUpd;   ///< updatable voxels, 8 mask words per leaf
    std::vector<uint64_t> mDirty; ///< voxels to re-evaluate, 8 mask words per leaf
    std::vector<uint64_t> mOut;   ///< per face: own face voxels changed since the neighbour read them
    std::vector<int8_t> mSide;    ///< sign of all updatable voxels of the leaf, 0 if mixed
    std::vector<char> mHasWork;
    std::unique_ptr<std::atomic<uint32_t>[]> mKey; ///< smallest pending input (float bits), kNoKey: none
    std::vector<char> mHasFixed; ///< the leaf holds fixed (input band) values
    std::vector<uint16_t> mVisits; ///< times the leaf was processed
    float mDelta;                 ///< width of the key window processed per step (world units)
    std::atomic<uint32_t> mDropped{0}; ///< largest change not passed on (float bits, world units)
    float mH;
    float mTol;
    float mCapPos, mCapNeg;
    openvdb::util::NullInterrupter* mInterrupter;
};

} // namespace

void sweepLeaves(openvdb::FloatTree& tree, const openvdb::FloatTree& frozen, float h, float tol, float capPos,
                 float capNeg, int maxIterations, openvdb::util::NullInterrupter* interrupter,
                 ExpandLevelSetStats& stats)
{
    Sweeper sweeper(tree, frozen, h, tol, capPos, capNeg, interrupter);
    stats.candidateVoxels = sweeper.candidateVoxels();
    sweeper.run(maxIterations, stats);
}

} // namespace levelforge::fast_sweeping_internal
