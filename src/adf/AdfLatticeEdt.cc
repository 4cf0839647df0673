// SPDX-License-Identifier: Apache-2.0
// The lattice distance transform of the type-3 samples (see AdfLatticeEdt.h).
#include "adf/AdfLatticeEdt.h"

#include "detail/LowerEnvelope.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdlib>
#include <limits>

namespace levelforge {
namespace adf_internal {

namespace {

using ListLeaf = openvdb::UInt32Tree::LeafNodeType;

/// An exact breakpoint num/den of two parabolas (den > 0); the envelope's sentinels -1/0 and
/// 1/0 compare as -inf and +inf with every breakpoint (its den is 2(Y[q] - Y[a]) > 0).
struct Rational { int64_t num, den; };
using Envelope = detail::LowerEnvelope<int64_t, Rational>;

Envelope makeEnvelope() { return Envelope(Rational{-1, 0}, Rational{1, 0}); }

/// Lower envelope of the parabolas (t - Y[i])² + F[i] (Y strictly increasing), evaluated at
/// t = t0 + j·dt, j < nq. Breakpoints are the rationals num/den (den > 0), compared exactly.
void lowerEnvelope(Envelope& env, const int64_t* Y, const int64_t* F, int n, int64_t t0, int64_t dt, int nq, int64_t* out)
{
    env.reset(size_t(n));
    for (int q = 0; q < n; ++q)
        env.add(
            q, F[q], [&](int a, int64_t fa) { return Rational{(F[q] + Y[q] * Y[q]) - (fa + Y[a] * Y[a]), 2 * (Y[q] - Y[a])}; },
            // pop while s <= z[k]
            [](const Rational& s, const Rational& z) { return __int128(s.num) * z.den <= __int128(z.num) * s.den; });
    env.evaluate(
        nq, [&](int j) { return t0 + int64_t(j) * dt; },
        // advance while the next breakpoint z[c+1] < t
        [](const Rational& z, int64_t t) { return __int128(z.num) < __int128(t) * z.den; },
        [&](int j, int64_t t, int a, int64_t fa) { out[j] = (t - Y[a]) * (t - Y[a]) + fa; });
}

} // namespace

bool LatticeEdt::build(const openvdb::UInt32Tree& tree, const CoordBBox& domain)
{
    mD.clear();
    mLo = domain.min();
    std::vector<const ListLeaf*> leaves;
    for (auto it = tree.cbeginLeaf(); it; ++it)
        if (!it->isEmpty()) leaves.push_back(&*it);
    if (leaves.empty()) return false;
    std::sort(leaves.begin(), leaves.end(), [](const ListLeaf* a, const ListLeaf* b) { return a->origin() < b->origin(); });
    CoordBBox sb;
    for (const ListLeaf* l : leaves) { sb.expand(l->origin()); sb.expand(l->origin().offsetBy(7)); }
    const int64_t lim = int64_t(1) << 20;
    for (int k = 0; k < 3; ++k) {
        if (std::abs(int64_t(sb.min()[k])) >= lim || std::abs(int64_t(sb.max()[k])) >= lim) return false;
        if (std::abs(int64_t(domain.min()[k])) >= lim || std::abs(int64_t(domain.max()[k])) >= lim) return false;
        if (domain.max()[k] < domain.min()[k]) return false;
        mN[k] = (domain.max()[k] - domain.min()[k]) / kStep + 1;
    }
    const int sx0 = sb.min().x(), nxs = sb.max().x() - sx0 + 1;
    const int nx = mN[0], ny = mN[1], nz = mN[2];
    if (double(nx) * ny * nz > double(1 << 24) || double(nxs) * ny * nz > double(1 << 24)) return false;

    // pass 1 (z) and 2 (y), per site column x: g2[(j*nz + k)*nxs + x - sx0]
    const int64_t kInf = std::numeric_limits<int64_t>::max();
    std::vector<int64_t> g2(size_t(nxs) * ny * nz, kInf);
    std::vector<uint8_t> hasX(size_t(nxs), 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, nxs, 4), [&](const tbb::blocked_range<int>& r) {
        std::vector<int64_t> Y, g1, Z, F, out(static_cast<size_t>(ny));
        Envelope env = makeEnvelope();
        for (int xi = r.begin(); xi != r.end(); ++xi) {
            const int x = sx0 + xi, ox = x & ~7, lx = x - ox;
            auto lo = std::lower_bound(leaves.begin(), leaves.end(), ox, [](const ListLeaf* l, int v) { return l->origin().x() < v; });
            auto hi = std::lower_bound(lo, leaves.end(), ox + 8, [](const ListLeaf* l, int v) { return l->origin().x() < v; });
            Y.clear();
            g1.clear();
            for (auto g = lo; g != hi;) {
                auto ge = g;
                while (ge != hi && (*ge)->origin().y() == (*g)->origin().y()) ++ge;
                const int oy = (*g)->origin().y();
                for (int ly = 0; ly < 8; ++ly) {
                    Z.clear();
                    for (auto it = g; it != ge; ++it) {
                        uint32_t bits = uint32_t(((*it)->getValueMask().template getWord<uint64_t>(openvdb::Index(lx)) >> (8 * ly)) & 0xffu);
                        while (bits) {
                            Z.push_back(2 * int64_t((*it)->origin().z() + __builtin_ctz(bits)) + 1);
                            bits &= bits - 1;
                        }
                    }
                    if (Z.empty()) continue;
                    Y.push_back(2 * int64_t(oy + ly) + 1);
                    size_t i = 0;
                    for (int k = 0; k < nz; ++k) {
                        const int64_t t = 2 * (int64_t(mLo.z()) + int64_t(k) * kStep);
                        while (i + 1 < Z.size() && Z[i + 1] <= t) ++i;
                        int64_t best = (t - Z[i]) * (t - Z[i]);
                        if (i + 1 < Z.size()) best = std::min(best, (Z[i + 1] - t) * (Z[i + 1] - t));
                        g1.push_back(best);
                    }
                }
                g = ge;
            }
            if (Y.empty()) continue;
            hasX[size_t(xi)] = 1;
            F.resize(Y.size());
            for (int k = 0; k < nz; ++k) {
                for (size_t i = 0; i < Y.size(); ++i) F[i] = g1[i * size_t(nz) + size_t(k)];
                lowerEnvelope(env, Y.data(), F.data(), int(Y.size()), 2 * int64_t(mLo.y()), 2 * kStep, ny, out.data());
                for (int j = 0; j < ny; ++j) g2[(size_t(j) * nz + size_t(k)) * nxs + size_t(xi)] = out[size_t(j)];
            }
        }
    });
    // pass 3 (x)
    std::vector<int64_t> X;
    std::vector<int> xs;
    for (int xi = 0; xi < nxs; ++xi)
        if (hasX[size_t(xi)]) { X.push_back(2 * int64_t(sx0 + xi) + 1); xs.push_back(xi); }
    mD.assign(size_t(nx) * ny * nz, 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, ny * nz, 16), [&](const tbb::blocked_range<int>& r) {
        std::vector<int64_t> F(X.size()), out(static_cast<size_t>(nx));
        Envelope env = makeEnvelope();
        for (int jk = r.begin(); jk != r.end(); ++jk) {
            const int64_t* row = &g2[size_t(jk) * nxs];
            for (size_t i = 0; i < xs.size(); ++i) F[i] = row[size_t(xs[i])];
            lowerEnvelope(env, X.data(), F.data(), int(X.size()), 2 * int64_t(mLo.x()), 2 * kStep, nx, out.data());
            for (int i = 0; i < nx; ++i) mD[size_t(i) * ny * nz + size_t(jk)] = out[size_t(i)];
        }
    });
    return true;
}

} // namespace adf_internal
} // namespace levelforge
