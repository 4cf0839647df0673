// SPDX-License-Identifier: Apache-2.0
// Mesh → level set, the sign stage of the winding and unsigned modes (see MeshToLevelSet.h,
// SignMode): the groups of a leaf's voxels with no surface between them, one winding number
// estimate per group (or per component of groups across leaves), and the choice of Auto.
#include "mesh/MeshToLevelSetInternal.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace levelforge {
namespace meshtols_internal {


namespace {

/// The groups of a leaf's voxels: connected components of 6-neighbours with no surface between
/// them (lower[a] + lower[b] > 1), numbered in the order of their smallest voxel, into label[].
/// A union-find over the +x, +y, +z neighbours (the smaller index stays the root) gives the
/// same numbering as a breadth-first search from each unlabelled voxel in increasing order, at
/// half the tests. Returns the number of groups.
uint16_t leafGroups(const double* lower, uint16_t* label)
{
    uint16_t parent[512];
    for (uint16_t i = 0; i < 512; ++i) parent[i] = i;
    const auto find = [&parent](uint16_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    const auto join = [&](uint16_t a, uint16_t b) {
        if (!(lower[a] + lower[b] > 1.0 + 1e-9)) return;
        a = find(a);
        b = find(b);
        if (a < b) parent[b] = a;
        else if (b < a) parent[a] = b;
    };
    for (uint16_t v = 0; v < 512; ++v) {
        if ((v & 7u) < 7u) join(v, uint16_t(v + 1));
        if (((v >> 3) & 7u) < 7u) join(v, uint16_t(v + 8));
        if ((v >> 6) < 7u) join(v, uint16_t(v + 64));
    }
    uint16_t rootLabel[512];
    std::fill(rootLabel, rootLabel + 512, uint16_t(0xffff));
    uint16_t groups = 0;
    for (uint16_t v = 0; v < 512; ++v) {
        const uint16_t r = find(v);
        if (rootLabel[r] == 0xffff) rootLabel[r] = groups++;
        label[v] = rootLabel[r];
    }
    return groups;
}

/// Triangles near a region up to which the local exact tier is used there (each costs one
/// solid angle per undecided voxel, ~40 ns; an estimate of w from the tree costs 10-25 µs near
/// a rim).
constexpr size_t kNearTrianglesMax = 96;
/// How far (voxels) beyond a region's voxel centres its near triangles are gathered: the whole
/// leaf with 6 (the leaf, then its 4×4×4 blocks, modelled), else each 4×4×4 block with 4.
constexpr double kLeafReach = 6.0, kBlockReach = 4.0;

/// The triangles N near the index box [lo, hi] grown by `reach` voxels, and their boundary ∂N
/// (half-edges cancelled by exact position) into the scratch; the grown box (world units) into
/// skipLo / skipHi. False (nothing kept) when N has more than kNearTrianglesMax triangles.
bool gatherNear(const Context& ctx, Scratch& s, const Vec3d& lo, const Vec3d& hi, double reach, Vec3d& skipLo,
                Vec3d& skipHi)
{
    const double h = ctx.voxelSize;
    const FastWindingNumber& fwn = *ctx.fwn;
    // the gather box a hair larger than the grown box, so that an edge the slab test finds
    // meeting the grown box has all its triangles gathered whatever the rounding
    skipLo = (lo - Vec3d(reach)) * h;
    skipHi = (hi + Vec3d(reach)) * h;
    const Vec3d pad(1e-6 * h);
    FastWindingNumberAccess::gather(fwn, skipLo - pad, skipHi + pad, s.nearTris);
    if (s.nearTris.size() > kNearTrianglesMax) return false;
    s.halfEdges.clear();
    for (uint32_t t : s.nearTris) {
        const double* c = FastWindingNumberAccess::triangle(fwn, t);
        for (int k = 0; k < 3; ++k) {
            const double* p = c + 3 * k;
            const double* q = c + 3 * ((k + 1) % 3);
            const bool forward = std::lexicographical_compare(p, p + 3, q, q + 3);
            const double* a = forward ? p : q;
            const double* b = forward ? q : p;
            s.halfEdges.push_back({{a[0], a[1], a[2], b[0], b[1], b[2]}, forward ? 1 : -1});
        }
    }
    std::sort(s.halfEdges.begin(), s.halfEdges.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    s.nearEdges.clear();
    for (size_t i = 0; i < s.halfEdges.size();) {
        size_t j = i;
        int net = 0;
        for (; j < s.halfEdges.size() && s.halfEdges[j].first == s.halfEdges[i].first; ++j) net += s.halfEdges[j].second;
        if (net != 0) {
            const auto& e = s.halfEdges[i].first;
            s.nearEdges.push_back({Vec3d(e[0], e[1], e[2]), Vec3d(e[3], e[4], e[5]), double(net)});
        }
        i = j;
    }
    return true;
}

/// Decides the voxels s.undecided[first, last) of the cube of `side` voxels at offset `base`
/// of the leaf at `origin` with the near set in the scratch (gatherNear()): a first-order model
/// of w_F at the cube's centre plus the exact w_N of each voxel (see localExactTier()). The
/// undecided ones are appended to s.group2. wNearOf[i] caches voxel i's w_N for the near set in
/// the scratch (NaN: not computed yet), across the cube sizes that use the same near set.
void decideByNearSet(const Context& ctx, const Coord& origin, Scratch& s, const double* lower, uint32_t base, int side,
                     size_t first, size_t last, const Vec3d& skipLo, const Vec3d& skipHi, double* wNearOf)
{
    using namespace winding_internal;
    const double h = ctx.voxelSize;
    const FastWindingNumber& fwn = *ctx.fwn;
    const auto indexOf = [&](uint32_t i) {
        return Vec3d(double(origin.x() + int(i >> 6)), double(origin.y() + int((i >> 3) & 7)), double(origin.z() + int(i & 7)));
    };
    const auto wNear = [&](const Vec3d& p) {
        SolidAngleSum sum;
        for (uint32_t t : s.nearTris) {
            const double* c = FastWindingNumberAccess::triangle(fwn, t);
            sum.add(c, c + 3, c + 6, p.asPointer());
        }
        return sum.value() / (4.0 * 3.14159265358979323846);
    };
    const Vec3d c = indexOf(base) + Vec3d(0.5 * (side - 1.0));
    const Vec3d cw = c * h;
    const Vec3d lo = (indexOf(base) - Vec3d(0.5)) * h, hi = (indexOf(base) + Vec3d(side - 0.5)) * h;
    double H = FastWindingNumberAccess::hessianBoundBeyond(fwn, lo, hi, skipLo, skipHi);
    double be = 0.0;
    Vec3d B = fwn.gradient(cw, be);
    for (const Scratch::NearEdge& e : s.nearEdges) {
        B -= FastWindingNumberAccess::edgeGradient(e.a, e.b, e.current, cw);
        if (!FastWindingNumberAccess::segmentMeetsBox(e.a, e.b, skipLo, skipHi))
            H += FastWindingNumberAccess::edgeHessianBound(e.a, e.b, e.current, lo, hi);
    }
    H *= h * h;
    B *= h;
    be *= h;
    ++s.windingEvaluations;
    const double wF = fwn(cw) - wNear(cw);
    const bool model = std::isfinite(H) && std::isfinite(wF);
    for (size_t k = first; k < last; ++k) {
        const uint32_t i = s.undecided[k];
        int v = -1;
        if (!(lower[i] > kOnSurface)) v = 0; // on the surface: 0 either way
        else if (model) {
            const Vec3d d = indexOf(i) - c;
            const double r = d.length();
            if (std::isnan(wNearOf[i])) wNearOf[i] = wNear(indexOf(i) * h);
            v = decide(wNearOf[i] + wF + B.dot(d), 0.5 * H * r * r + be * r);
        }
        if (v >= 0) s.inside[i] = uint8_t(v);
        else s.group2.push_back(i);
    }
}

/// The local exact tier, for the undecided voxels of a leaf near a boundary current (a hole's
/// rim, a stray open triangle): w = w_N + w_F, w_N the winding number of the triangles N whose
/// box meets the region's box grown by a reach of a few voxels (summed exactly, one solid
/// angle per triangle and voxel), w_F that of the rest F. No triangle of F comes within the
/// reach of the region, so w_F is smooth there: a first-order model of it at the centre c of
/// a cube: w_F(c) = w(c) − w_N(c) (one estimate), ∇w_F(c) = ∇w(c) − ∇w_N(c) (the edge tree's
/// gradient with its error bound Be, less the exact Biot–Savart field of ∂N), and a bound H of
/// ‖∇∇w_F‖ over the cube from the current of ∂F = ∂M − ∂N: every element of it is an edge of a
/// triangle of F, so an edge that meets the grown box (all of whose triangles are in N) carries
/// none, and any other carries at most |I_M(e)| + |I_N(e)|. A voxel v then gets
/// w_N(v) + w_F(c) + ∇w_F·(v − c) ± (½ H |v − c|² + Be |v − c|). Regions: the whole leaf
/// (reach kLeafReach; models on the leaf, then on its 4×4×4 and 2×2×2 blocks) when few
/// triangles are near it, else each 4×4×4 block with its own near set (reach kBlockReach;
/// models on it, then on its 2×2×2 blocks; fine meshes).
/// What this leaves undecided stays in s.undecided for the tiers below. Exact in the sense of
/// decide(): the only estimates are the w(c).
void localExactTier(const Context& ctx, const Coord& origin, Scratch& s, const double* lower)
{
    const Vec3d o(origin.x(), origin.y(), origin.z());
    const auto blockSort = [&](uint32_t m) {
        const auto block = [m](uint32_t i) { return (((i >> 6) & m) << 6) | (((i >> 3) & m) << 3) | (i & m); };
        std::sort(s.undecided.begin(), s.undecided.end(), [&](uint32_t a, uint32_t b) {
            const uint32_t ba = block(a), bb = block(b);
            return ba < bb || (ba == bb && a < b);
        });
        return block;
    };
    Vec3d skipLo, skipHi;
    // each voxel's w_N for the near set in use (NaN: not yet), kept across the cube sizes
    const double kNotYet = std::numeric_limits<double>::quiet_NaN();
    double wNearOf[512];
    if (gatherNear(ctx, s, o, o + Vec3d(7.0), kLeafReach, skipLo, skipHi)) {
        // the whole leaf, then its 4×4×4 blocks, with the leaf's near set
        s.group2.clear();
        std::fill(wNearOf, wNearOf + 512, kNotYet);
        decideByNearSet(ctx, origin, s, lower, 0, 8, 0, s.undecided.size(), skipLo, skipHi, wNearOf);
        s.undecided.swap(s.group2);
        if (s.undecided.empty()) return;
        for (int side = 4; side >= 2 && !s.undecided.empty(); side /= 2) {
            const auto block = blockSort(uint32_t(8 - side));
            s.group2.clear();
            for (size_t first = 0; first < s.undecided.size();) {
                const uint32_t base = block(s.undecided[first]);
                size_t last = first;
                while (last < s.undecided.size() && block(s.undecided[last]) == base) ++last;
                decideByNearSet(ctx, origin, s, lower, base, side, first, last, skipLo, skipHi, wNearOf);
                first = last;
            }
            s.undecided.swap(s.group2);
        }
        return;
    }
    // each 4×4×4 block with its own near set
    const auto block = blockSort(4u);
    s.group2.clear();
    for (size_t first = 0; first < s.undecided.size();) {
        const uint32_t base = block(s.undecided[first]);
        size_t last = first;
        while (last < s.undecided.size() && block(s.undecided[last]) == base) ++last;
        const Vec3d bo = o + Vec3d(double(base >> 6), double((base >> 3) & 7), double(base & 7));
        if (gatherNear(ctx, s, bo, bo + Vec3d(3.0), kBlockReach, skipLo, skipHi)) {
            // the block, then its 2×2×2 blocks with the same near set
            const size_t mark = s.group2.size();
            for (size_t k = first; k < last; ++k) wNearOf[s.undecided[k]] = kNotYet; // this block's near set
            decideByNearSet(ctx, origin, s, lower, base, 4, first, last, skipLo, skipHi, wNearOf);
            if (s.group2.size() > mark) {
                s.rest.assign(s.group2.begin() + long(mark), s.group2.end());
                s.group2.resize(mark);
                const auto sub = [](uint32_t i) { return (((i >> 6) & 6u) << 6) | (((i >> 3) & 6u) << 3) | (i & 6u); };
                std::sort(s.rest.begin(), s.rest.end(), [&](uint32_t a, uint32_t b) {
                    return sub(a) < sub(b) || (sub(a) == sub(b) && a < b);
                });
                s.undecided.swap(s.rest); // decideByNearSet reads s.undecided
                for (size_t f = 0; f < s.undecided.size();) {
                    size_t l = f;
                    while (l < s.undecided.size() && sub(s.undecided[l]) == sub(s.undecided[f])) ++l;
                    decideByNearSet(ctx, origin, s, lower, sub(s.undecided[f]), 2, f, l, skipLo, skipHi, wNearOf);
                    f = l;
                }
                s.undecided.swap(s.rest);
            }
        } else
            s.group2.insert(s.group2.end(), s.undecided.begin() + long(first), s.undecided.begin() + long(last));
        first = last;
    }
    s.undecided.swap(s.group2);
}

} // namespace

/// The winding signs of a leaf's 512 voxels (see MeshToLevelSet.h, SignMode::Winding).
///
/// Groups: face-adjacent voxels u, v with d(u) + d(v) > 1 see no surface between them (the open
/// balls of radius d cover the segment; a voxel with nothing within reach counts the limit as a
/// lower bound of its distance), so w changes along the hop by at most the gradient bound g of
/// the leaf's box (0 for a mesh without boundary current). One estimate is made per leaf, at
/// the voxel farthest from the surface (P); every other group's representative Q (its farthest
/// voxel) gets w(Q) = w(P) + the signed crossings of a segment P'→Q' with the leaf's triangles,
/// P' and Q' moved inside their surface-free balls off the lattice (so that the segment misses
/// edges and vertices; another direction is tried when a crossing is too close to call, and
/// after three the representative is evaluated instead), ± g × the path length. Each voxel
/// then takes its group's value ± g × its hops from the representative (tier 1); one whose
/// interval still contains ±1/2 gets a first-order model about P over the leaf (tier 1b), then
/// the blocks' models (tier 2), the local exact tier (tier 3) and, last, its own estimate.
void windingSigns(const Context& ctx, const Coord& origin, Scratch& s)
{
    using namespace winding_internal;
    const double h = ctx.voxelSize;
    double lower[512];
    for (int i = 0; i < 512; ++i) lower[i] = s.vd[i] >= 0.0 ? s.vd[i] : ctx.limit;
    const auto adjacent = [&lower](uint32_t a, uint32_t b) { return lower[a] + lower[b] > 1.0 + 1e-9; };
    const auto indexOf = [&](uint32_t i) {
        return Vec3d(double(origin.x() + int(i >> 6)), double(origin.y() + int((i >> 3) & 7)), double(origin.z() + int(i & 7)));
    };
    // gradient bound per voxel of path over the leaf's cells grown by the largest move of a
    // segment end (0.25 voxel)
    const double g = ctx.fwn->gradientBound((indexOf(0) - Vec3d(0.5)) * h, (indexOf(511) + Vec3d(0.5)) * h) * h;
    // a boundary current through the leaf (a hole's rim, an open triangle): the groups cannot
    // carry a value, every voxel goes to the blocks' models
    const bool local = !std::isfinite(g);
    if (local) {
        s.undecided.resize(512);
        for (uint32_t i = 0; i < 512; ++i) s.undecided[i] = i;
    }
    // fixed directions off the lattice for the segment ends
    static const Vec3d kDir[3] = {Vec3d(0.5257311121, 0.3090169944, 0.7925052400).unit(),
                                  Vec3d(-0.2763932023, 0.8506508084, 0.4472135955).unit(),
                                  Vec3d(0.7236067977, -0.5257311121, 0.4472135955).unit()};
    const auto evalVoxel = [&](uint32_t i) {
        ++s.windingEvaluations;
        ++s.windingIndividual;
        return (*ctx.fwn)(indexOf(i) * h);
    };
    // The change of w along P → P' → Q' → Q (P', Q' inside the surface-free balls, off the
    // lattice): its signed crossings, and the path's length; false when no attempt was clear.
    bool gathered = false;
    const auto crossing = [&](uint32_t A, uint32_t Bv, int& change, double& length) {
        if (!gathered) {
            FastWindingNumberAccess::gather(*ctx.fwn, (indexOf(0) - Vec3d(0.3)) * h, (indexOf(511) + Vec3d(0.3)) * h, s.tris);
            gathered = true;
        }
        if (!(lower[A] > kOnSurface) || !(lower[Bv] > kOnSurface)) return false;
        const double ma = 0.5 * std::min(lower[A], 0.5), mb = 0.5 * std::min(lower[Bv], 0.5);
        for (int attempt = 0; attempt < 3; ++attempt) {
            const Vec3d a = indexOf(A) + kDir[attempt] * ma, b = indexOf(Bv) + kDir[(attempt + 1) % 3] * mb;
            if (crossingChange(*ctx.fwn, s.tris, a * h, b * h, change)) {
                length = ma + (b - a).length() + mb;
                return true;
            }
        }
        return false;
    };
    // per voxel left undecided by tier 1: its group's carried value and the length of its path
    // from P (for tier 1b)
    double carried[512], pathLength[512];
    uint32_t P = 0;     // the voxel of the leaf's one estimate (not local)
    double w0 = 0.0;    // its estimate
    if (!local) {
        // groups, each with its representative (farthest voxel, ties to the lowest offset)
        // (leafGroups(); each group's voxels in increasing order, by a counting sort)
        uint16_t label[512];
        const size_t groups = leafGroups(lower, label);
        s.groupStart.assign(groups + 1, 0);
        s.groupRep.assign(groups, 0xffffffffu);
        for (uint32_t i = 0; i < 512; ++i) {
            ++s.groupStart[label[i] + 1u];
            uint32_t& rep = s.groupRep[label[i]];
            if (rep == 0xffffffffu || lower[i] > lower[rep]) rep = i;
        }
        for (size_t k = 0; k < groups; ++k) s.groupStart[k + 1] += s.groupStart[k];
        s.groupVoxels.resize(512);
        {
            uint32_t fill[512];
            std::copy(s.groupStart.begin(), s.groupStart.end() - 1, fill);
            for (uint32_t i = 0; i < 512; ++i) s.groupVoxels[fill[label[i]]++] = i;
        }
        s.windingGroups += groups;
        size_t main = 0;
        for (size_t k = 1; k < groups; ++k)
            if (lower[s.groupRep[k]] > lower[s.groupRep[main]]) main = k;
        P = s.groupRep[main];
        w0 = (*ctx.fwn)(indexOf(P) * h);
        ++s.windingEvaluations;
        s.undecided.clear();
        for (size_t k = 0; k < groups; ++k) {
            const uint32_t Q = s.groupRep[k];
            double wq = w0, err0 = 0.0, toQ = 0.0; // toQ: the path's length from P to Q
            bool own = k == main; // the value is Q's own estimate
            if (!(lower[Q] > kOnSurface)) {
                // voxels on the surface (to rounding; a group of them alone): their value is 0
                // whatever the side; +0, and no estimate
                for (uint32_t i = s.groupStart[k]; i < s.groupStart[k + 1]; ++i) s.inside[s.groupVoxels[i]] = 0;
                continue;
            }
            if (k != main) {
                int change = 0;
                double length = 0.0;
                if (crossing(P, Q, change, length)) {
                    wq = w0 + change;
                    err0 = g > 0.0 ? g * length : 0.0;
                    toQ = length;
                } else {
                    wq = evalVoxel(Q);
                    own = true;
                }
            }
            // tier 1: the leaf's gradient bound times the path (P to Q, then Q's hops)
            const uint32_t* first = s.groupVoxels.data() + s.groupStart[k];
            const uint32_t* last = s.groupVoxels.data() + s.groupStart[k + 1];
            // (no hop counts needed when the group's size, which bounds every path, already decides)
            const int whole = g > 0.0 ? decide(wq, err0 + g * double(last - first)) : decide(wq, err0);
            const bool hops = g > 0.0 && last - first > 1 && whole < 0;
            if (hops) {
                for (const uint32_t* it = first; it != last; ++it) { s.inGroup[*it] = 1; s.hopsRep[*it] = -1; }
                bfs(3, Q, s.inGroup, adjacent, s.hopsRep, s.group2);
                for (const uint32_t* it = first; it != last; ++it) s.inGroup[*it] = 0;
            }
            for (const uint32_t* it = first; it != last; ++it) {
                const uint32_t i = *it;
                int v;
                if (i == Q && own) v = insideByEstimate(wq) ? 1 : 0;
                else if (!hops) v = whole >= 0 ? whole : decide(wq, err0);
                else v = decide(wq, err0 + g * double(i == Q ? 0 : s.hopsRep[i]));
                if (v < 0) {
                    s.undecided.push_back(i);
                    // (undecided: g > 0, so the hops were counted; a group whose value is its
                    // own estimate carries nothing from P)
                    carried[i] = wq;
                    pathLength[i] = own && k != main ? -1.0 : toQ + double(i == Q ? 0 : s.hopsRep[i]);
                }
                else s.inside[i] = uint8_t(v);
            }
        }
    }
    if (s.undecided.empty()) return;
    // tier 1b: a first-order model of w about P over the whole leaf, from P's estimate (no new
    // one): the gradient B at P from the edge tree (error bound Be) and a bound H of the Hessian
    // over the leaf's cells grown by the segment ends' moves. Along a path of length L from P
    // that crosses the surface c times (net), w(v) = w(P) + c + B·(v − P) ± (½ H L² + Be |v − P|),
    // because ∇w is continuous across the surface and varies by at most H per unit of path.
    if (!local) {
        const Vec3d lo = indexOf(0) - Vec3d(0.75), hi = indexOf(511) + Vec3d(0.75);
        const double H = ctx.fwn->hessianBound(lo * h, hi * h) * h * h;
        if (std::isfinite(H)) {
            double be = 0.0;
            const Vec3d B = ctx.fwn->gradient(indexOf(P) * h, be) * h;
            be *= h;
            s.group2.clear();
            for (uint32_t i : s.undecided) {
                int v = -1;
                if (pathLength[i] >= 0.0) {
                    const Vec3d d = indexOf(i) - indexOf(P);
                    const double L = pathLength[i];
                    v = decide(carried[i] + B.dot(d), 0.5 * H * L * L + be * d.length());
                }
                if (v >= 0) s.inside[i] = uint8_t(v);
                else s.group2.push_back(i);
            }
            s.undecided.swap(s.group2);
            if (s.undecided.empty()) return;
        }
    }
    const auto blockOf = [](uint32_t i, int shift) {
        // the block of side 1 << shift holding voxel i, as the offset of its first voxel
        const uint32_t m = (0xffu << shift) & 7u;
        return (((i >> 6) & m) << 6) | (((i >> 3) & m) << 3) | (i & m);
    };
    // tier 2 (near a boundary edge, or where |w| is near 1/2): per 4×4×4 block, a first-order
    // model at the block's voxel farthest from the surface S (value, gradient B from the edge
    // tree with its error bound Be, Hessian bound H of the block grown by the segment ends'
    // moves); a voxel v gets w(S) + crossings(S' → v') + B·(v − S) ± (kWindingTolerance +
    // ½ H L² + Be |v − S|), L the path length. (The same models on 2×2×2 blocks, tried next
    // until 2026-12-07, decided about 8 voxels an estimate where the local exact tier below
    // decides 17, and their gradients and Hessian bounds near many rims cost more than the
    // estimates: without them the elephant with holes at 512 takes 4.4–5.2 s instead of
    // 7.4–8.6 s, the teapot and the open bunny slightly less.)
    if (!s.undecided.empty()) {
        const int shift = 2;
        const uint32_t side = 1u << shift;
        std::sort(s.undecided.begin(), s.undecided.end(),
                  [&](uint32_t a, uint32_t b) { return blockOf(a, shift) < blockOf(b, shift) || (blockOf(a, shift) == blockOf(b, shift) && a < b); });
        s.group2.clear(); // still undecided after this size
        for (size_t first = 0; first < s.undecided.size();) {
            const uint32_t base = blockOf(s.undecided[first], shift);
            size_t last = first;
            while (last < s.undecided.size() && blockOf(s.undecided[last], shift) == base) ++last;
            uint32_t S = base;
            for (uint32_t x = 0; x < side; ++x)
                for (uint32_t y = 0; y < side; ++y)
                    for (uint32_t z = 0; z < side; ++z) {
                        const uint32_t i = base + (x << 6) + (y << 3) + z;
                        if (lower[i] > lower[S]) S = i;
                    }
            const Vec3d lo = indexOf(base) - Vec3d(0.75), hi = indexOf(base) + Vec3d(side - 0.25);
            const double H = ctx.fwn->hessianBound(lo * h, hi * h) * h * h;
            // a model is worth its estimate only where it can decide something
            const bool model = std::isfinite(H) && lower[S] > kOnSurface && 0.5 * H * 3.0 * side * side < 0.5;
            double ws = 0.0, be = 0.0;
            Vec3d Bs(0.0);
            if (model) {
                ws = evalVoxel(S);
                Bs = ctx.fwn->gradient(indexOf(S) * h, be) * h;
                be *= h;
            }
            for (size_t k = first; k < last; ++k) {
                const uint32_t i = s.undecided[k];
                int v = -1;
                if (!(lower[i] > kOnSurface)) v = 0; // on the surface: 0 either way
                else if (model && i == S) v = insideByEstimate(ws) ? 1 : 0;
                else if (model) {
                    int change = 0;
                    double length = 0.0;
                    if (crossing(S, i, change, length))
                        v = decide(ws + change + Bs.dot(indexOf(i) - indexOf(S)),
                                   0.5 * H * length * length + be * (indexOf(i) - indexOf(S)).length());
                }
                if (v >= 0) s.inside[i] = uint8_t(v);
                else s.group2.push_back(i);
            }
            first = last;
        }
        s.undecided.swap(s.group2);
    }
    // what the models leave (next to a hole's rim, mostly): the local exact tier where few
    // triangles are near
    if (!s.undecided.empty()) localExactTier(ctx, origin, s, lower);
    // the rest: their own estimates, a 4×4×4 block's voxels in
    // one traversal of the tree (sorted by block above)
    for (size_t first = 0; first < s.undecided.size();) {
        const uint32_t base = blockOf(s.undecided[first], 2);
        size_t last = first;
        while (last < s.undecided.size() && blockOf(s.undecided[last], 2) == base) ++last;
        s.points.clear();
        for (size_t k = first; k < last; ++k) s.points.push_back(indexOf(s.undecided[k]) * h);
        s.values.resize(s.points.size());
        ctx.fwn->evaluate(s.points.data(), s.points.size(), s.values.data());
        s.windingEvaluations += s.points.size();
        s.windingIndividual += s.points.size();
        for (size_t k = first; k < last; ++k) s.inside[s.undecided[k]] = insideByEstimate(s.values[k - first]) ? 1 : 0;
        first = last;
    }
}

/// Winding without boundary current: the leaf's groups and distances for the global join
/// (resolveDeferred()); the values are the unsigned distances until then.
LeafResult deferLeaf(const Context& ctx, Scratch& s, LeafResult& res, bool wantClosest)
{
    using namespace winding_internal;
    auto dw = std::make_unique<DeferredWinding>();
    double lower[512];
    for (int i = 0; i < 512; ++i) {
        lower[i] = s.vd[i] >= 0.0 ? s.vd[i] : ctx.limit;
        // a float not above the double (the join needs lower bounds)
        float f = float(s.vd[i]);
        if (s.vd[i] >= 0.0 && double(f) > s.vd[i]) f = std::nextafter(f, 0.0f);
        dw->lower[i] = s.vd[i] >= 0.0 ? f : -1.0f;
    }
    // the groups (leafGroups())
    dw->groups = leafGroups(lower, dw->group);
    s.windingGroups += dw->groups;
    for (openvdb::Index i = 0; i < 512; ++i) {
        dw->band[i] = 0;
        if (s.vd[i] < 0.0) continue;
        const double d = s.vd[i] <= kOnSurface ? 0.0 : s.vd[i];
        dw->band[i] = uint8_t((d < ctx.extW ? 1 : 0) | (d < ctx.intW ? 2 : 0));
        res.sdf->setValueOnly(i, float(d * ctx.voxelSize));
        if (wantClosest) {
            res.cp->setValueOnly(i, s.vcp[i]);
            res.tri->setValueOnly(i, s.vtri[i]);
        }
    }
    res.deferred = std::move(dw);
    return std::move(res);
}

/// The deferred winding signs of every leaf (a mesh without boundary current: w is constant off
/// the surface between jumps): groups joined across leaf faces (d(u) + d(v) > 1, with float
/// lower bounds) into components of the union-find; one estimate per component, at its voxel
/// farthest from the surface; then each leaf's values and active states. Deterministic: the
/// union-find keeps the smallest index as the root, leaves are in sorted order.
void resolveDeferred(const Context& ctx, const std::vector<Coord>& origins, std::vector<LeafResult>& leaves,
                     bool wantClosest, uint64_t& evaluations, uint64_t& activeVoxels)
{
    using namespace winding_internal;
    const size_t n = leaves.size();
    std::vector<uint64_t> first(n + 1, 0);
    for (size_t l = 0; l < n; ++l) first[l + 1] = first[l] + (leaves[l].deferred ? leaves[l].deferred->groups : 0);
    const uint64_t total = first[n];
    std::vector<uint64_t> parent(total);
    for (uint64_t i = 0; i < total; ++i) parent[i] = i;
    const auto find = [&parent](uint64_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    const auto unite = [&](uint64_t a, uint64_t b) {
        a = find(a);
        b = find(b);
        if (a < b) parent[b] = a;
        else if (b < a) parent[a] = b;
    };
    const auto lowerOf = [&ctx](const DeferredWinding& d, int i) { return d.lower[i] >= 0.0f ? double(d.lower[i]) : ctx.limit; };
    for (size_t l = 0; l < n; ++l) {
        const DeferredWinding* a = leaves[l].deferred.get();
        if (!a) continue;
        for (int axis = 0; axis < 3; ++axis) {
            Coord o = origins[l];
            o[axis] += 8;
            const auto it = std::lower_bound(origins.begin(), origins.end(), o);
            if (it == origins.end() || *it != o) continue;
            const size_t m = size_t(it - origins.begin());
            const DeferredWinding* b = leaves[m].deferred.get();
            if (!b) continue;
            // a face's 64 voxel pairs mostly join the same two groups: a pair just joined is
            // skipped (the components, and their smallest-index roots, are the same)
            uint64_t lastA = ~uint64_t(0), lastB = ~uint64_t(0);
            for (int u = 0; u < 8; ++u)
                for (int v = 0; v < 8; ++v) {
                    int ia, ib; // the voxel at the face of a, its neighbour in b
                    if (axis == 0) { ia = (7 << 6) | (u << 3) | v; ib = (u << 3) | v; }
                    else if (axis == 1) { ia = (u << 6) | (7 << 3) | v; ib = (u << 6) | v; }
                    else { ia = (u << 6) | (v << 3) | 7; ib = (u << 6) | (v << 3); }
                    if (!(lowerOf(*a, ia) + lowerOf(*b, ib) > 1.0 + 1e-9)) continue;
                    const uint64_t ga = first[l] + a->group[ia], gb = first[m] + b->group[ib];
                    if (ga == lastA && gb == lastB) continue;
                    lastA = ga;
                    lastB = gb;
                    unite(ga, gb);
                }
        }
    }
    std::vector<uint64_t> roots;
    for (uint64_t i = 0; i < total; ++i) {
        parent[i] = find(i); // every entry straight to its root, for the parallel reads below
        if (parent[i] == i) roots.push_back(i);
    }
    // the components that hold a leaf's voxel farthest from the surface get an estimate (at that
    // voxel of the first such leaf); every other group its leaf's value plus its crossings
    const auto farthest = [&](const DeferredWinding& a, int group) {
        int best = -1;
        for (int i = 0; i < 512; ++i)
            if ((group < 0 || a.group[i] == group) && (best < 0 || lowerOf(a, i) > lowerOf(a, best))) best = i;
        return best;
    };
    const auto indexOf = [&origins](size_t l, int i) {
        return Vec3d(origins[l].x() + (i >> 6), origins[l].y() + ((i >> 3) & 7), origins[l].z() + (i & 7));
    };
    std::vector<int64_t> primaryAt(total, -1); // root -> leaf * 512 + voxel of its estimate
    std::vector<int> leafP(n, -1);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t l = r.begin(); l != r.end(); ++l)
            if (const DeferredWinding* a = leaves[l].deferred.get()) leafP[l] = farthest(*a, -1);
    });
    for (size_t l = 0; l < n; ++l) { // in leaf order: the first leaf of a component holds its estimate
        const DeferredWinding* a = leaves[l].deferred.get();
        if (!a) continue;
        const uint64_t c = parent[first[l] + a->group[leafP[l]]];
        if (primaryAt[c] < 0) primaryAt[c] = int64_t(l) * 512 + leafP[l];
    }
    std::vector<uint64_t> primary;
    for (uint64_t r : roots)
        if (primaryAt[r] >= 0) primary.push_back(r);
    std::vector<double> value(total, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, primary.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            const int64_t at = primaryAt[primary[k]];
            value[primary[k]] = (*ctx.fwn)(indexOf(size_t(at / 512), int(at % 512)) * ctx.voxelSize);
        }
    });
    std::atomic<uint64_t> estimates{primary.size()}, active{0};
    const float bg = ctx.background;
    static const Vec3d kDir[3] = {Vec3d(0.5257311121, 0.3090169944, 0.7925052400).unit(),
                                  Vec3d(-0.2763932023, 0.8506508084, 0.4472135955).unit(),
                                  Vec3d(0.7236067977, -0.5257311121, 0.4472135955).unit()};
    tbb::enumerable_thread_specific<std::vector<uint32_t>> trisTls;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 16), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<uint32_t>& tris = trisTls.local();
        for (size_t l = r.begin(); l != r.end(); ++l) {
            LeafResult& res = leaves[l];
            if (!res.deferred) continue;
            const DeferredWinding& a = *res.deferred;
            const int P = leafP[l];
            const double w0 = value[parent[first[l] + a.group[P]]];
            uint8_t groupInside[512];
            bool gathered = false;
            for (int g = 0; g < a.groups; ++g) {
                const uint64_t c = parent[first[l] + uint64_t(g)];
                if (primaryAt[c] >= 0) { groupInside[g] = insideByEstimate(value[c]) ? 1 : 0; continue; }
                const int Q = farthest(a, g);
                if (!(lowerOf(a, Q) > kOnSurface)) { groupInside[g] = 0; continue; } // on the surface
                if (!gathered) {
                    FastWindingNumberAccess::gather(*ctx.fwn, (indexOf(l, 0) - Vec3d(0.3)) * ctx.voxelSize,
                                                    (indexOf(l, 511) + Vec3d(0.3)) * ctx.voxelSize, tris);
                    gathered = true;
                }
                bool done = false;
                int change = 0;
                const double mp = 0.5 * std::min(lowerOf(a, P), 0.5), mq = 0.5 * std::min(lowerOf(a, Q), 0.5);
                for (int attempt = 0; attempt < 3 && !done && mp > kOnSurface; ++attempt) {
                    const Vec3d pa = indexOf(l, P) + kDir[attempt] * mp, pb = indexOf(l, Q) + kDir[(attempt + 1) % 3] * mq;
                    done = crossingChange(*ctx.fwn, tris, pa * ctx.voxelSize, pb * ctx.voxelSize, change);
                }
                double w = w0 + change;
                if (!done) {
                    w = (*ctx.fwn)(indexOf(l, Q) * ctx.voxelSize);
                    estimates.fetch_add(1, std::memory_order_relaxed);
                }
                groupInside[g] = insideByEstimate(w) ? 1 : 0;
            }
            uint64_t count = 0;
            for (openvdb::Index i = 0; i < 512; ++i) {
                const bool in = groupInside[a.group[i]] != 0;
                if (a.lower[i] < 0.0f) { res.sdf->setValueOff(i, in ? -bg : bg); continue; }
                const float v = res.sdf->getValue(i);
                if (a.band[i] & (in ? 2 : 1)) {
                    res.sdf->setValueOn(i, in ? -v : v);
                    if (wantClosest) {
                        res.cp->setValueOn(i);
                        res.tri->setValueOn(i);
                    }
                    ++count;
                } else {
                    res.sdf->setValueOff(i, in ? -bg : bg);
                }
            }
            res.deferred.reset();
            active.fetch_add(count, std::memory_order_relaxed);
        }
    });
    evaluations += estimates.load();
    activeVoxels += active.load();
}

/// Winding and unsigned modes: the leaf's values from the distances recorded in `s`. A winding
/// leaf is kept when any of its voxels had a triangle within reach, active or not (so that the
/// tiles around it hold no surface); an unsigned one when a voxel is active.
LeafResult finishLeaf(const Context& ctx, Scratch& s, LeafResult& res, bool wantClosest)
{
    const bool winding = ctx.sign == SignMode::Winding;
    const Coord origin = res.sdf->origin();
    bool any = false;
    for (int i = 0; i < 512 && !any; ++i) any = s.vd[i] >= 0.0;
    if (!any) return LeafResult{};
    if (winding && ctx.deferWinding) return deferLeaf(ctx, s, res, wantClosest);
    if (winding) windingSigns(ctx, origin, s);
    const float bg = ctx.background;
    uint64_t active = 0;
    for (openvdb::Index i = 0; i < 512; ++i) {
        const bool inside = winding && s.inside[i];
        const double d = winding && s.vd[i] >= 0.0 && s.vd[i] <= kOnSurface ? 0.0 : s.vd[i];
        if (d >= 0.0 && (inside ? d < ctx.intW : d < ctx.extW)) {
            res.sdf->setValueOn(i, float((inside ? -d : d) * ctx.voxelSize));
            if (wantClosest) {
                res.cp->setValueOn(i, s.vcp[i]);
                res.tri->setValueOn(i, s.vtri[i]);
            }
            ++active;
        } else {
            res.sdf->setValueOff(i, inside ? -bg : bg);
        }
    }
    s.activeVoxels += active;
    if (active == 0 && !winding) return LeafResult{};
    return std::move(res);
}

} // namespace meshtols_internal

SignMode signModeFromString(const std::string& name)
{
    if (name == "auto") return SignMode::Auto;
    if (name == "pseudonormal") return SignMode::Pseudonormal;
    if (name == "winding") return SignMode::Winding;
    if (name == "unsigned") return SignMode::Unsigned;
    throw InvalidArgumentError("unknown sign mode '" + name + "' (auto, pseudonormal, winding, unsigned)");
}

const char* toString(SignMode mode)
{
    switch (mode) {
    case SignMode::Auto: return "auto";
    case SignMode::Pseudonormal: return "pseudonormal";
    case SignMode::Winding: return "winding";
    case SignMode::Unsigned: return "unsigned";
    }
    return "auto";
}

namespace meshtols_internal {
/// The connected parts (through shared vertices) of a closed mesh whose enclosed volume is
/// negative (wound clockwise seen from outside: pseudonormals would sign them inside out).
uint64_t invertedParts(const TriangleMesh& mesh, uint64_t& parts)
{
    std::vector<uint32_t> parent(mesh.points.size());
    for (uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
    const auto find = [&parent](uint32_t x) {
        while (parent[x] != x) x = parent[x] = parent[parent[x]];
        return x;
    };
    for (const Vec3I& t : mesh.triangles) {
        const uint32_t a = find(t[0]), b = find(t[1]), c = find(t[2]);
        parent[b] = a;
        parent[find(c)] = find(a);
    }
    std::vector<double> volume(mesh.points.size(), 0.0);
    std::vector<uint8_t> used(mesh.points.size(), 0);
    for (const Vec3I& t : mesh.triangles) {
        const uint32_t r = find(t[0]);
        used[r] = 1;
        volume[r] += mesh.points[t[0]].dot(mesh.points[t[1]].cross(mesh.points[t[2]]));
    }
    uint64_t inverted = 0;
    parts = 0;
    for (uint32_t i = 0; i < parent.size(); ++i) {
        if (!used[i] || parent[i] != i) continue;
        ++parts;
        if (volume[i] < 0.0) ++inverted;
    }
    return inverted;
}

/// The sign mode a conversion uses, and why (Auto: validateMesh()'s verdict).
SignMode resolveSignMode(const TriangleMesh& mesh, const MeshToLevelSetOptions& options, std::string& reason)
{
    if (options.sign != SignMode::Auto) {
        reason = std::string(toString(options.sign)) + ": requested";
        return options.sign;
    }
    MeshReport local;
    const MeshReport* report = options.validation;
    if (!report) {
        local = validateMesh(mesh);
        report = &local;
    }
    if (report->closed()) {
        uint64_t parts = 0;
        const uint64_t inverted = invertedParts(mesh, parts);
        if (inverted == 0) {
            reason = "auto: the mesh is closed and consistently oriented, so pseudonormals sign it exactly";
            return SignMode::Pseudonormal;
        }
        std::ostringstream os;
        os << "auto: the mesh is closed, but " << inverted << " of its " << parts
           << " parts are inside out (negative volume), so the winding number signs it";
        reason = os.str();
        return SignMode::Winding;
    }
    std::ostringstream os;
    os << "auto: the mesh is not closed (" << report->boundaryEdges << " boundary, " << report->nonManifoldEdges
       << " non-manifold, " << report->inconsistentlyOrientedEdges
       << " inconsistently oriented edges), so the winding number signs it";
    reason = os.str();
    return SignMode::Winding;
}
} // namespace meshtols_internal
} // namespace levelforge
