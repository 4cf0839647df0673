// SPDX-License-Identifier: Apache-2.0
// Fast winding numbers (Barill et al. 2018). See mesh/FastWindingNumber.h; the signing of a
// level set's inactive region is in WindingSignTree.cc.
#include <levelforge/mesh/FastWindingNumber.h>

#include "mesh/EdgeBounds.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>


#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <unordered_map>
#include <cstring>

namespace levelforge {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kInf = std::numeric_limits<double>::infinity();
} // namespace

double triangleSolidAngle(const Vec3d& a0, const Vec3d& b0, const Vec3d& c0, const Vec3d& p)
{
    double num, den;
    // num = 0: in the triangle's plane (the principal value on the triangle)
    if (!winding_internal::SolidAngleSum::terms(a0.asPointer(), b0.asPointer(), c0.asPointer(), p.asPointer(), num, den))
        return 0.0;
    return 2.0 * std::atan2(num, den);
}

namespace fwn_internal {

/// A node of the cluster tree: the expansion about its centre, and either two children or a
/// range of triangles (leaf order).
struct Node
{
    double c[3];      // centre p̃: area-weighted centroid of its triangles
    double far2;      // (β ρ)²: queries farther than this from c use the expansion
    double radius;    // ρ: bound of |x − p̃| over its triangles
    double area;      // total area
    double N[3];      // vector area Σ a n
    double M[9];      // M_ij = Σ a n_i (c_t − p̃)_j (row major)
    // evaluation-ready forms of the expansion: the order-2 term is (tr M − 3 rᵀ S r / D²) / D³
    // with S the symmetric part of M (xx yy zz xy xz yz); the order-3 term is
    // ½ (v·r / D⁵ + 15 P(r) / D⁷), v_k = −6 Σ_i C_iik − 3 Σ_j C_kjj, P the cubic form C(r, r, r)
    // (coefficients of x³ y³ z³ x²y x²z y²x y²z z²x z²y xyz)
    double trM, S[6], v[3], P[10];
    double lo[3], hi[3]; // box of its triangles
    uint32_t first, count; // leaf: triangles [first, first + count); inner: count = 0
    uint32_t left, right;  // inner: children
};

/// Per-node second-order moments C_ijk (symmetric in j, k): index i*6 + (xx, yy, zz, xy, xz, yz).
using Second = std::array<double, 18>;

/// An edge with a net boundary current.
struct CurrentEdge
{
    Vec3d a, b;
    double signedCurrent; // net uses a→b minus uses b→a
    double current;       // |I|
    double length;
};

struct EdgeNode
{
    double lo[3], hi[3];
    double sumIL, sumI; // Σ |I| L, Σ |I| over the subtree
    double diag2;       // squared diagonal of the box
    double dl[3];       // Σ I (b − a), the net current element of the subtree (0 for closed loops)
    uint32_t first, count, left, right;
};

inline double boxBoxDist2(const double* alo, const double* ahi, const Vec3d& blo, const Vec3d& bhi)
{
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double e = bhi[k] < alo[k] ? alo[k] - bhi[k] : (blo[k] > ahi[k] ? blo[k] - ahi[k] : 0.0);
        d2 += e * e;
    }
    return d2;
}

/// Hash of a position's bit pattern (the welding of coincident vertices).
struct PositionHashImpl
{
    size_t operator()(const std::array<uint64_t, 3>& k) const
    {
        uint64_t h = 1469598103934665603ull;
        for (uint64_t x : k) h = (h ^ x) * 1099511628211ull ^ (x >> 29);
        return size_t(h);
    }
};

} // namespace fwn_internal

struct FastWindingNumber::Impl
{
    using PositionHash = fwn_internal::PositionHashImpl;
    using Node = fwn_internal::Node;
    FastWindingNumberOptions opt;
    std::vector<double> tri;            // 9 doubles per triangle, leaf order
    std::vector<Node> nodes;            // pre-order, root 0
    std::vector<fwn_internal::Second> second; // order 3 only
    std::vector<fwn_internal::CurrentEdge> edges;
    std::vector<fwn_internal::EdgeNode> edgeNodes;
    uint64_t triangleCount = 0;
    uint32_t leafSize = 8; // triangles per leaf cluster of this tree (options, see build())

    // ---------------------------------------------------------------- construction
    struct Item
    {
        Vec3d centroid;
        uint32_t id;
    };

    std::map<size_t, size_t> subtreeSize; // node count of a subtree over n triangles

    size_t countNodes(size_t n)
    {
        auto it = subtreeSize.find(n);
        if (it != subtreeSize.end()) return it->second;
        const size_t c = n <= leafSize ? 1 : 1 + countNodes(n / 2) + countNodes(n - n / 2);
        subtreeSize[n] = c;
        return c;
    }

    void build(const TriangleMesh& mesh)
    {
        const size_t nt = mesh.triangles.size();
        std::vector<uint8_t> ok(nt, 0);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 8192), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t t = r.begin(); t != r.end(); ++t) {
                const Vec3I& v = mesh.triangles[t];
                const Vec3d n = (mesh.points[v[1]] - mesh.points[v[0]]).cross(mesh.points[v[2]] - mesh.points[v[0]]);
                const double len = n.length();
                ok[t] = (len > 0.0 && std::isfinite(len)) ? 1 : 0;
            }
        });
        std::vector<Item> items;
        items.reserve(nt);
        for (uint32_t t = 0; t < nt; ++t) {
            if (!ok[t]) continue;
            const Vec3I& v = mesh.triangles[t];
            items.push_back({(mesh.points[v[0]] + mesh.points[v[1]] + mesh.points[v[2]]) / 3.0, t});
        }
        triangleCount = items.size();
        if (items.empty()) return;
        // the boundary currents first: without any, w is piecewise constant, only a few
        // estimates are made, and the coarser tree is cheaper to build
        buildEdges(mesh, ok);
        leafSize = edges.empty() && opt.leafSizeWithoutCurrent > 0 ? opt.leafSizeWithoutCurrent : opt.leafSize;
        countNodes(items.size());
        nodes.resize(countNodes(items.size()));
        tri.resize(9 * items.size());
        second.resize(nodes.size()); // the full C_ijk, for the parents' translation; freed after
        buildRange(mesh, items, 0, items.size(), 0);
        std::vector<fwn_internal::Second>().swap(second);
    }

    void buildRange(const TriangleMesh& mesh, std::vector<Item>& items, size_t b, size_t e, uint32_t me)
    {
        Node& n = nodes[me];
        const size_t count = e - b;
        if (count <= leafSize) {
            n.first = uint32_t(b);
            n.count = uint32_t(count);
            n.left = n.right = 0;
            for (size_t i = b; i < e; ++i) {
                const Vec3I& v = mesh.triangles[items[i].id];
                for (int k = 0; k < 3; ++k)
                    for (int j = 0; j < 3; ++j) tri[9 * i + 3 * k + j] = mesh.points[v[k]][j];
            }
            leafMoments(me);
            return;
        }
        // median split on the longest axis of the centroid box, ties by triangle id
        Vec3d lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
        for (size_t i = b; i < e; ++i) {
            lo = openvdb::math::minComponent(lo, items[i].centroid);
            hi = openvdb::math::maxComponent(hi, items[i].centroid);
        }
        const Vec3d ext = hi - lo;
        const int axis = ext[0] >= ext[1] && ext[0] >= ext[2] ? 0 : (ext[1] >= ext[2] ? 1 : 2);
        const size_t mid = b + count / 2;
        std::nth_element(items.begin() + long(b), items.begin() + long(mid), items.begin() + long(e),
                         [axis](const Item& x, const Item& y) {
                             return x.centroid[axis] < y.centroid[axis] ||
                                    (x.centroid[axis] == y.centroid[axis] && x.id < y.id);
                         });
        const uint32_t left = me + 1, right = uint32_t(me + 1 + subtreeSize.at(mid - b));
        n.first = 0;
        n.count = 0;
        n.left = left;
        n.right = right;
        if (count > 8192) {
            tbb::parallel_invoke([&] { buildRange(mesh, items, b, mid, left); },
                                 [&] { buildRange(mesh, items, mid, e, right); });
        } else {
            buildRange(mesh, items, b, mid, left);
            buildRange(mesh, items, mid, e, right);
        }
        innerMoments(me);
    }

    const double* corner(size_t t, int k) const { return &tri[9 * t + 3 * k]; }

    void leafMoments(uint32_t me)
    {
        Node& n = nodes[me];
        double A = 0.0, cx = 0, cy = 0, cz = 0;
        double N[3] = {0, 0, 0};
        for (uint32_t i = n.first; i < n.first + n.count; ++i) {
            const Vec3d a(corner(i, 0)), b(corner(i, 1)), c(corner(i, 2));
            const Vec3d an = (b - a).cross(c - a) * 0.5; // area · unit normal
            const double ar = an.length();
            const Vec3d ct = (a + b + c) / 3.0;
            A += ar;
            cx += ar * ct[0];
            cy += ar * ct[1];
            cz += ar * ct[2];
            for (int k = 0; k < 3; ++k) N[k] += an[k];
        }
        const Vec3d p(cx / A, cy / A, cz / A);
        double M[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
        fwn_internal::Second C{};
        double rho2 = 0.0;
        for (uint32_t i = n.first; i < n.first + n.count; ++i) {
            const Vec3d a(corner(i, 0)), b(corner(i, 1)), c(corner(i, 2));
            const Vec3d an = (b - a).cross(c - a) * 0.5;
            const double ar = an.length();
            const Vec3d y0 = a - p, y1 = b - p, y2 = c - p, yc = (y0 + y1 + y2) / 3.0;
            rho2 = std::max({rho2, y0.lengthSqr(), y1.lengthSqr(), y2.lengthSqr()});
            for (int r = 0; r < 3; ++r)
                for (int s = 0; s < 3; ++s) M[3 * r + s] += an[r] * yc[s];
            {
                // ∫_t y yᵀ dA = a/12 (Σ y_k y_kᵀ + (Σ y_k)(Σ y_k)ᵀ)
                const Vec3d s = y0 + y1 + y2;
                const int J[6] = {0, 1, 2, 0, 0, 1}, K[6] = {0, 1, 2, 1, 2, 2};
                for (int q = 0; q < 6; ++q) {
                    const int j = J[q], k = K[q];
                    const double m = ar / 12.0 * (y0[j] * y0[k] + y1[j] * y1[k] + y2[j] * y2[k] + s[j] * s[k]);
                    for (int r = 0; r < 3; ++r) C[6 * r + q] += (ar > 0 ? an[r] / ar : 0.0) * m;
                }
            }
        }
        finish(n, p, A, N, M, std::sqrt(rho2));
        compact(n, C);
        for (int k = 0; k < 3; ++k) { n.lo[k] = std::numeric_limits<double>::max(); n.hi[k] = -n.lo[k]; }
        for (uint32_t i = n.first; i < n.first + n.count; ++i)
            for (int c = 0; c < 3; ++c)
                for (int k = 0; k < 3; ++k) {
                    n.lo[k] = std::min(n.lo[k], corner(i, c)[k]);
                    n.hi[k] = std::max(n.hi[k], corner(i, c)[k]);
                }
        second[me] = C;
    }

    void innerMoments(uint32_t me)
    {
        Node& n = nodes[me];
        const Node& l = nodes[n.left];
        const Node& r = nodes[n.right];
        const double A = l.area + r.area;
        const Vec3d p((l.area * l.c[0] + r.area * r.c[0]) / A, (l.area * l.c[1] + r.area * r.c[1]) / A,
                      (l.area * l.c[2] + r.area * r.c[2]) / A);
        double N[3], M[9];
        fwn_internal::Second C{};
        double rho = 0.0;
        for (int k = 0; k < 3; ++k) N[k] = l.N[k] + r.N[k];
        for (int k = 0; k < 9; ++k) M[k] = 0.0;
        const Node* ch[2] = {&l, &r};
        const uint32_t idx[2] = {n.left, n.right};
        for (int h = 0; h < 2; ++h) {
            const Node& c = *ch[h];
            const Vec3d d(c.c[0] - p[0], c.c[1] - p[1], c.c[2] - p[2]);
            rho = std::max(rho, d.length() + c.radius);
            // translation: M = M_c + N_c dᵀ
            for (int a = 0; a < 3; ++a)
                for (int b = 0; b < 3; ++b) M[3 * a + b] += c.M[3 * a + b] + c.N[a] * d[b];
            {
                // C_ijk = C_c,ijk + M_c,ij d_k + M_c,ik d_j + N_c,i d_j d_k
                const fwn_internal::Second& Cc = second[idx[h]];
                const int J[6] = {0, 1, 2, 0, 0, 1}, K[6] = {0, 1, 2, 1, 2, 2};
                for (int i = 0; i < 3; ++i)
                    for (int q = 0; q < 6; ++q) {
                        const int j = J[q], k = K[q];
                        C[6 * i + q] += Cc[6 * i + q] + c.M[3 * i + j] * d[k] + c.M[3 * i + k] * d[j] + c.N[i] * d[j] * d[k];
                    }
            }
        }
        finish(n, p, A, N, M, rho);
        compact(n, C);
        for (int k = 0; k < 3; ++k) { n.lo[k] = std::min(l.lo[k], r.lo[k]); n.hi[k] = std::max(l.hi[k], r.hi[k]); }
        second[me] = C;
    }

    /// The evaluation-ready forms of M and C (see Node).
    static void compact(Node& n, const fwn_internal::Second& C)
    {
        const double* M = n.M;
        n.trM = M[0] + M[4] + M[8];
        n.S[0] = M[0];
        n.S[1] = M[4];
        n.S[2] = M[8];
        n.S[3] = 0.5 * (M[1] + M[3]);
        n.S[4] = 0.5 * (M[2] + M[6]);
        n.S[5] = 0.5 * (M[5] + M[7]);
        // C_i as a symmetric 3×3 in (j, k): index q of (xx yy zz xy xz yz)
        auto c = [&C](int i, int j, int k) {
            static const int Q[3][3] = {{0, 3, 4}, {3, 1, 5}, {4, 5, 2}};
            return C[6 * i + Q[j][k]];
        };
        for (int k = 0; k < 3; ++k) {
            double a = 0.0, t = 0.0;
            for (int i = 0; i < 3; ++i) a += c(i, i, k);
            for (int j = 0; j < 3; ++j) t += c(k, j, j);
            n.v[k] = -6.0 * a - 3.0 * t;
        }
        // P(r) = Σ_ijk c(i,j,k) r_i r_j r_k, gathered by monomial
        for (double& x : n.P) x = 0.0;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k) {
                    int e[3] = {0, 0, 0};
                    ++e[i];
                    ++e[j];
                    ++e[k];
                    int m;
                    if (e[0] == 3) m = 0;
                    else if (e[1] == 3) m = 1;
                    else if (e[2] == 3) m = 2;
                    else if (e[0] == 2) m = e[1] == 1 ? 3 : 4;
                    else if (e[1] == 2) m = e[0] == 1 ? 5 : 6;
                    else if (e[2] == 2) m = e[0] == 1 ? 7 : 8;
                    else m = 9;
                    n.P[m] += c(i, j, k);
                }
    }

    void finish(Node& n, const Vec3d& p, double A, const double* N, const double* M, double rho)
    {
        for (int k = 0; k < 3; ++k) { n.c[k] = p[k]; n.N[k] = N[k]; }
        for (int k = 0; k < 9; ++k) n.M[k] = M[k];
        n.area = A;
        n.radius = rho;
        const double fr = opt.accuracy * rho;
        n.far2 = fr * fr;
    }

    // ---------------------------------------------------------------- boundary currents
    void buildEdges(const TriangleMesh& mesh, const std::vector<uint8_t>& ok)
    {
        // Vertices at exactly the same position are one vertex here: the seams of unwelded
        // patches (a teapot's, a kit-bashed model's) carry opposite currents on coincident
        // segments, whose fields cancel exactly; keyed apart they would count as boundary
        // edges and make the gradient bounds useless along every seam.
        const size_t nv = mesh.points.size(), nt = mesh.triangles.size();
        std::vector<uint32_t> canon(nv);
        {
            std::unordered_map<std::array<uint64_t, 3>, uint32_t, PositionHash> seen;
            seen.reserve(nv);
            for (uint32_t i = 0; i < nv; ++i) {
                std::array<uint64_t, 3> key;
                for (int k = 0; k < 3; ++k) {
                    const double c = mesh.points[i][k] == 0.0 ? 0.0 : mesh.points[i][k]; // -0 is 0
                    std::memcpy(&key[k], &c, sizeof(double));
                }
                canon[i] = seen.emplace(key, i).first->second;
            }
        }
        // half-edges bucketed by their smaller vertex (counting sort): (other vertex, direction)
        std::vector<uint32_t> first(nv + 1, 0);
        for (size_t t = 0; t < nt; ++t) {
            if (!ok[t]) continue;
            const Vec3I& m = mesh.triangles[t];
            const uint32_t v[3] = {canon[m[0]], canon[m[1]], canon[m[2]]};
            for (int k = 0; k < 3; ++k) ++first[std::min(v[k], v[(k + 1) % 3]) + 1];
        }
        for (size_t i = 0; i < nv; ++i) first[i + 1] += first[i];
        std::vector<std::pair<uint32_t, int32_t>> half(first[nv]);
        std::vector<uint32_t> fill(first.begin(), first.end() - 1);
        for (size_t t = 0; t < nt; ++t) {
            if (!ok[t]) continue;
            const Vec3I& m = mesh.triangles[t];
            const uint32_t v[3] = {canon[m[0]], canon[m[1]], canon[m[2]]};
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = v[k], b = v[(k + 1) % 3];
                half[fill[std::min(a, b)]++] = {std::max(a, b), a < b ? 1 : -1};
            }
        }
        for (uint32_t a = 0; a < nv; ++a) {
            auto* beg = half.data() + first[a];
            auto* end = half.data() + first[a + 1];
            if (beg == end) continue;
            std::sort(beg, end);
            for (auto* it = beg; it != end;) {
                const uint32_t b = it->first;
                int64_t current = 0;
                for (; it != end && it->first == b; ++it) current += it->second;
                if (current != 0 && a != b) {
                    fwn_internal::CurrentEdge e;
                    e.a = mesh.points[a];
                    e.b = mesh.points[b];
                    e.signedCurrent = double(current);
                    e.current = double(current < 0 ? -current : current);
                    e.length = (e.b - e.a).length();
                    edges.push_back(e);
                }
            }
        }
        if (!edges.empty()) {
            std::vector<uint32_t> ids(edges.size());
            for (uint32_t i = 0; i < ids.size(); ++i) ids[i] = i;
            edgeNodes.reserve(2 * edges.size() / 4 + 2);
            buildEdgeRange(ids, 0, ids.size());
            std::vector<fwn_internal::CurrentEdge> sorted(edges.size());
            for (size_t i = 0; i < ids.size(); ++i) sorted[i] = edges[ids[i]];
            edges.swap(sorted);
        }
    }

    uint32_t buildEdgeRange(std::vector<uint32_t>& ids, size_t b, size_t e)
    {
        const uint32_t me = uint32_t(edgeNodes.size());
        edgeNodes.emplace_back();
        fwn_internal::EdgeNode n;
        for (int k = 0; k < 3; ++k) { n.lo[k] = std::numeric_limits<double>::max(); n.hi[k] = -n.lo[k]; }
        n.sumIL = n.sumI = 0.0;
        n.dl[0] = n.dl[1] = n.dl[2] = 0.0;
        for (size_t i = b; i < e; ++i) {
            const fwn_internal::CurrentEdge& ed = edges[ids[i]];
            for (int k = 0; k < 3; ++k) n.dl[k] += ed.signedCurrent * (ed.b[k] - ed.a[k]);
            for (int k = 0; k < 3; ++k) {
                n.lo[k] = std::min({n.lo[k], ed.a[k], ed.b[k]});
                n.hi[k] = std::max({n.hi[k], ed.a[k], ed.b[k]});
            }
            n.sumIL += ed.current * ed.length;
            n.sumI += ed.current;
        }
        n.diag2 = 0.0;
        for (int k = 0; k < 3; ++k) n.diag2 += (n.hi[k] - n.lo[k]) * (n.hi[k] - n.lo[k]);
        if (e - b <= 4) {
            n.first = uint32_t(b);
            n.count = uint32_t(e - b);
            n.left = n.right = 0;
        } else {
            int axis = 0;
            for (int k = 1; k < 3; ++k)
                if (n.hi[k] - n.lo[k] > n.hi[axis] - n.lo[axis]) axis = k;
            const size_t mid = (b + e) / 2;
            std::nth_element(ids.begin() + long(b), ids.begin() + long(mid), ids.begin() + long(e),
                             [&](uint32_t x, uint32_t y) {
                                 const double mx = edges[x].a[axis] + edges[x].b[axis];
                                 const double my = edges[y].a[axis] + edges[y].b[axis];
                                 return mx < my || (mx == my && x < y);
                             });
            n.first = 0;
            n.count = 0;
            n.left = buildEdgeRange(ids, b, mid);
            n.right = buildEdgeRange(ids, mid, e);
        }
        edgeNodes[me] = n;
        return me;
    }

    // ---------------------------------------------------------------- queries
    /// Solid angle of the far expansion of node n seen from q, and its truncation bound.
    template<bool kBound>
    inline double expansion(uint32_t, const Node& n, double rx, double ry, double rz, double d2, double& bound) const
    {
        const double D = std::sqrt(d2), inv2 = 1.0 / d2, inv3 = inv2 / D;
        double s = (n.N[0] * rx + n.N[1] * ry + n.N[2] * rz) * inv3;
        if (opt.order >= 2) {
            const double* S = n.S;
            const double rSr = S[0] * rx * rx + S[1] * ry * ry + S[2] * rz * rz +
                               2.0 * (S[3] * rx * ry + S[4] * rx * rz + S[5] * ry * rz);
            s += (n.trM - 3.0 * rSr * inv2) * inv3;
        }
        if (opt.order >= 3) {
            const double* P = n.P;
            const double xx = rx * rx, yy = ry * ry, zz = rz * rz;
            const double c3 = P[0] * xx * rx + P[1] * yy * ry + P[2] * zz * rz + P[3] * xx * ry + P[4] * xx * rz +
                              P[5] * yy * rx + P[6] * yy * rz + P[7] * zz * rx + P[8] * zz * ry + P[9] * rx * ry * rz;
            const double inv5 = inv3 * inv2;
            s += 0.5 * ((n.v[0] * rx + n.v[1] * ry + n.v[2] * rz) * inv5 + 15.0 * c3 * inv5 * inv2);
        }
        if constexpr (kBound) {
            const double t = n.radius / D;
            const int m = opt.order + 1;
            const double tp = std::pow(t, m - 1);
            bound += n.area * inv2 * (tp * (m - (m - 1) * t) / ((1 - t) * (1 - t)) + 0.5 * tp / (1 - t));
        }
        return s;
    }

    template<bool kBound>
    Estimate evaluate(const Vec3d& q) const
    {
        Estimate est;
        if (nodes.empty()) return est;
        double sum = 0.0, bound = 0.0;
        winding_internal::SolidAngleSum near; // the near field's exact solid angles, one atan2
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const uint32_t ni = stack[--sp];
            const Node& n = nodes[ni];
            const double rx = n.c[0] - q[0], ry = n.c[1] - q[1], rz = n.c[2] - q[2];
            const double d2 = rx * rx + ry * ry + rz * rz;
            if (d2 > n.far2 && d2 > 0.0) {
                sum += expansion<kBound>(ni, n, rx, ry, rz, d2, bound);
                ++est.expansions;
                continue;
            }
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i) near.add(corner(i, 0), corner(i, 1), corner(i, 2), q.asPointer());
                est.exactTriangles += n.count;
                continue;
            }
            stack[sp++] = n.right;
            stack[sp++] = n.left;
        }
        est.value = (sum + near.value()) / (4.0 * kPi);
        est.errorBound = bound / (4.0 * kPi);
        return est;
    }

    /// Estimates at n points at once (one traversal): a node is expanded when its centre is
    /// farther than β ρ + r from the points' centre c (r: their largest distance from c), so that
    /// it is far for every point; its data are read once for all of them.
    void evaluateMany(const Vec3d* q, size_t n, double* out) const
    {
        for (size_t i = 0; i < n; ++i) out[i] = 0.0;
        if (nodes.empty() || n == 0) return;
        Vec3d c(0.0);
        for (size_t i = 0; i < n; ++i) c += q[i];
        c /= double(n);
        double r = 0.0;
        for (size_t i = 0; i < n; ++i) r = std::max(r, (q[i] - c).length());
        double dummy = 0.0;
        // the near field's exact solid angles, one product per point (one atan2 each)
        winding_internal::SolidAngleSum nearStack[64];
        std::vector<winding_internal::SolidAngleSum> nearHeap;
        if (n > 64) nearHeap.resize(n);
        winding_internal::SolidAngleSum* near = n > 64 ? nearHeap.data() : nearStack;
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const uint32_t ni = stack[--sp];
            const Node& nd = nodes[ni];
            const double cx = nd.c[0] - c[0], cy = nd.c[1] - c[1], cz = nd.c[2] - c[2];
            const double dc = std::sqrt(cx * cx + cy * cy + cz * cz);
            const double reach = opt.accuracy * nd.radius + r;
            if (dc > reach) {
                for (size_t i = 0; i < n; ++i) {
                    const double rx = nd.c[0] - q[i][0], ry = nd.c[1] - q[i][1], rz = nd.c[2] - q[i][2];
                    out[i] += expansion<false>(ni, nd, rx, ry, rz, rx * rx + ry * ry + rz * rz, dummy);
                }
                continue;
            }
            if (nd.count > 0) {
                for (uint32_t t = nd.first; t < nd.first + nd.count; ++t)
                    for (size_t i = 0; i < n; ++i) near[i].add(corner(t, 0), corner(t, 1), corner(t, 2), q[i].asPointer());
                continue;
            }
            stack[sp++] = nd.right;
            stack[sp++] = nd.left;
        }
        for (size_t i = 0; i < n; ++i) out[i] = (out[i] + near[i].value()) / (4.0 * kPi);
    }

    /// Triangles (leaf-order indices) whose box meets [lo, hi].
    void gather(const Vec3d& lo, const Vec3d& hi, std::vector<uint32_t>& out) const
    {
        out.clear();
        if (nodes.empty()) return;
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const Node& n = nodes[stack[--sp]];
            if (fwn_internal::boxBoxDist2(n.lo, n.hi, lo, hi) > 0.0) continue;
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i) {
                    bool meet = true;
                    for (int k = 0; k < 3 && meet; ++k) {
                        const double a = corner(i, 0)[k], b = corner(i, 1)[k], c = corner(i, 2)[k];
                        meet = std::max({a, b, c}) >= lo[k] && std::min({a, b, c}) <= hi[k];
                    }
                    if (meet) out.push_back(i);
                }
                continue;
            }
            stack[sp++] = n.right;
            stack[sp++] = n.left;
        }
    }

    double exact(const Vec3d& q) const
    {
        double sum = 0.0;
        const size_t n = tri.size() / 9;
        for (size_t i = 0; i < n; ++i)
            sum += triangleSolidAngle(Vec3d(corner(i, 0)), Vec3d(corner(i, 1)), Vec3d(corner(i, 2)), q);
        return sum / (4.0 * kPi);
    }

    /// Σ over the current edges of a per-edge term of the distance δ from [lo, hi] to the edge
    /// (edgeTerm(edge, δ²)), a subtree farther than twice its box diagonal taken at once
    /// (nodeTerm(node, δ²) with δ to its box); +infinity when an edge touches the box.
    template<typename EdgeTerm, typename NodeTerm>
    double sumOverEdges(const Vec3d& lo, const Vec3d& hi, EdgeTerm&& edgeTerm, NodeTerm&& nodeTerm,
                        const Vec3d* skipLo = nullptr, const Vec3d* skipHi = nullptr) const
    {
        if (edgeNodes.empty()) return 0.0;
        double sum = 0.0;
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const fwn_internal::EdgeNode& n = edgeNodes[stack[--sp]];
            const double d2 = fwn_internal::boxBoxDist2(n.lo, n.hi, lo, hi);
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i) {
                    const fwn_internal::CurrentEdge& e = edges[i];
                    if (skipLo && fwn_internal::segmentMeetsBox(e.a, e.b, *skipLo, *skipHi)) continue;
                    const double de2 = fwn_internal::segmentBoxDist2(e.a, e.b, lo, hi);
                    if (!(de2 > 0.0)) return kInf;
                    sum += edgeTerm(e, de2);
                }
                continue;
            }
            if (d2 > 0.0 && d2 > 4.0 * n.diag2) {
                sum += nodeTerm(n, d2);
                continue;
            }
            stack[sp++] = n.right;
            stack[sp++] = n.left;
        }
        return sum / (4.0 * kPi) * (1.0 + 1e-9);
    }

    /// Bound of |∇w| over [lo, hi]: (1/4π) Σ |I| min(L/δ², π/δ).
    double gradientBound(const Vec3d& lo, const Vec3d& hi) const
    {
        return sumOverEdges(
            lo, hi,
            [](const fwn_internal::CurrentEdge& e, double de2) { return e.current * std::min(e.length / de2, kPi / std::sqrt(de2)); },
            [](const fwn_internal::EdgeNode& n, double d2) { return std::min(n.sumIL / d2, kPi * n.sumI / std::sqrt(d2)); });
    }

    /// ∇w(q) = −Σ_e I_e/(4π) ∫_e dl × (x − q)/|x − q|³ (I_e along the half-edge direction of
    /// the triangles, counter-clockwise seen from outside); per segment (a, b its ends relative
    /// to q): (I/4π) (a × b)(|a| + |b|) / (|a||b| (|a||b| + a·b)).
    Vec3d gradient(const Vec3d& q) const
    {
        Vec3d g(0.0);
        for (const fwn_internal::CurrentEdge& e : edges) g += edgeField(e, q);
        return g / (4.0 * kPi);
    }

    /// One edge's term of gradient() times 4π (zero for q on the edge's line beyond it).
    static Vec3d edgeField(const fwn_internal::CurrentEdge& e, const Vec3d& q)
    {
        const Vec3d a = e.a - q, b = e.b - q;
        const double la = a.length(), lb = b.length();
        const double den = la * lb * (la * lb + a.dot(b));
        if (!(den > 0.0)) return Vec3d(0.0);
        return a.cross(b) * (e.signedCurrent * (la + lb) / den);
    }

    /// ∇w(q) with the edge tree: a subtree whose box is farther than twice its diagonal from q
    /// is replaced by (1/4π) K(c) × Σ I (b − a), K(x) = (x − q)/|x − q|³ and c the box centre
    /// (each edge's term is (I/4π) ∫ K(x(t)) dt × (b − a)); since |∇K| <= 2/|x − q|³ and the box
    /// is convex, that moves it by at most (1/4π) Σ |I| L · 2ρ/δ³ (ρ the half diagonal, δ the
    /// distance from q to the box), added to `err`. Nearer edges are summed exactly.
    Vec3d gradientFast(const Vec3d& q, double& err) const
    {
        Vec3d g(0.0);
        double e2 = 0.0;
        if (edgeNodes.empty()) { err = 0.0; return g; }
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const fwn_internal::EdgeNode& n = edgeNodes[stack[--sp]];
            const double d2 = fwn_internal::boxBoxDist2(n.lo, n.hi, q, q);
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i) g += edgeField(edges[i], q);
                continue;
            }
            if (d2 > 4.0 * n.diag2 && d2 > 0.0) {
                const Vec3d c(0.5 * (n.lo[0] + n.hi[0]), 0.5 * (n.lo[1] + n.hi[1]), 0.5 * (n.lo[2] + n.hi[2]));
                const Vec3d r = c - q;
                const double lr = r.length();
                g += r.cross(Vec3d(n.dl[0], n.dl[1], n.dl[2])) / (lr * lr * lr);
                const double d = std::sqrt(d2);
                e2 += n.sumIL * std::sqrt(n.diag2) / (d2 * d); // 2ρ = the diagonal
                continue;
            }
            stack[sp++] = n.right;
            stack[sp++] = n.left;
        }
        err = e2 / (4.0 * kPi) * (1.0 + 1e-9) + 1e-12 * g.length();
        return g / (4.0 * kPi);
    }

    /// Bound of the operator norm of ∇∇w over [lo, hi]: (1/4π) Σ |I| min(2 L/δ³, 4/δ²); with a
    /// skip box, the edges that meet it are left out.
    double hessianBound(const Vec3d& lo, const Vec3d& hi, const Vec3d* skipLo = nullptr,
                        const Vec3d* skipHi = nullptr) const
    {
        return sumOverEdges(
            lo, hi,
            [](const fwn_internal::CurrentEdge& e, double de2) { return fwn_internal::edgeHessianTerm(e.current, e.length, de2); },
            [](const fwn_internal::EdgeNode& n, double d2) {
                return std::min(2.0 * n.sumIL / (d2 * std::sqrt(d2)), 4.0 * n.sumI / d2);
            },
            skipLo, skipHi);
    }
};

FastWindingNumber::FastWindingNumber(const TriangleMesh& mesh, const FastWindingNumberOptions& options)
    : mImpl(new Impl)
{
    if (!(options.accuracy > 1.0) || !std::isfinite(options.accuracy)) {
        std::ostringstream os;
        os << "fast winding number: the accuracy (beta) must be a finite number above 1, got " << options.accuracy;
        throw InvalidArgumentError(os.str());
    }
    if (options.order < 1 || options.order > 3) {
        throw InvalidArgumentError("fast winding number: the expansion order must be 1, 2 or 3, got " +
                                   std::to_string(options.order));
    }
    if (options.leafSize < 1 || options.leafSize > 64) {
        throw InvalidArgumentError("fast winding number: the leaf size must be in [1, 64], got " +
                                   std::to_string(options.leafSize));
    }
    if (options.leafSizeWithoutCurrent > 64) {
        throw InvalidArgumentError("fast winding number: the leaf size without boundary current must be in [0, 64], got " +
                                   std::to_string(options.leafSizeWithoutCurrent));
    }
    mImpl->opt = options;
    mImpl->build(mesh);
}

FastWindingNumber::~FastWindingNumber() = default;
FastWindingNumber::FastWindingNumber(FastWindingNumber&&) noexcept = default;
FastWindingNumber& FastWindingNumber::operator=(FastWindingNumber&&) noexcept = default;

FastWindingNumber::Estimate FastWindingNumber::evaluate(const Vec3d& p) const { return mImpl->evaluate<true>(p); }
double FastWindingNumber::operator()(const Vec3d& p) const { return mImpl->evaluate<false>(p).value; }
double FastWindingNumber::exact(const Vec3d& p) const { return mImpl->exact(p); }
void FastWindingNumber::evaluate(const Vec3d* points, size_t count, double* values) const
{
    mImpl->evaluateMany(points, count, values);
}
double FastWindingNumber::gradientBound(const Vec3d& lo, const Vec3d& hi) const { return mImpl->gradientBound(lo, hi); }
Vec3d FastWindingNumber::gradient(const Vec3d& p) const { return mImpl->gradient(p); }
Vec3d FastWindingNumber::gradient(const Vec3d& p, double& errorBound) const { return mImpl->gradientFast(p, errorBound); }
double FastWindingNumber::hessianBound(const Vec3d& lo, const Vec3d& hi) const { return mImpl->hessianBound(lo, hi); }
uint64_t FastWindingNumber::currentEdges() const { return mImpl->edges.size(); }
uint64_t FastWindingNumber::triangles() const { return mImpl->triangleCount; }
uint64_t FastWindingNumber::nodes() const { return mImpl->nodes.size(); }
const FastWindingNumberOptions& FastWindingNumber::options() const { return mImpl->opt; }
size_t FastWindingNumber::memoryBytes() const
{
    return mImpl->tri.capacity() * sizeof(double) + mImpl->nodes.capacity() * sizeof(Impl::Node) +
           mImpl->edges.capacity() * sizeof(fwn_internal::CurrentEdge) +
           mImpl->edgeNodes.capacity() * sizeof(fwn_internal::EdgeNode);
}

std::vector<double> fastWindingNumbers(const TriangleMesh& mesh, const std::vector<Vec3d>& points,
                                       const FastWindingNumberOptions& options)
{
    const FastWindingNumber fwn(mesh, options);
    std::vector<double> out(points.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, points.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) out[i] = fwn(points[i]);
    });
    return out;
}

void FastWindingNumberAccess::gather(const FastWindingNumber& f, const Vec3d& lo, const Vec3d& hi,
                                     std::vector<uint32_t>& out)
{
    f.mImpl->gather(lo, hi, out);
}

const double* FastWindingNumberAccess::triangle(const FastWindingNumber& f, uint32_t i) { return f.mImpl->corner(i, 0); }
} // namespace levelforge

namespace levelforge {
double FastWindingNumberAccess::hessianBoundBeyond(const FastWindingNumber& f, const Vec3d& lo, const Vec3d& hi,
                                                   const Vec3d& skipLo, const Vec3d& skipHi)
{
    return f.mImpl->hessianBound(lo, hi, &skipLo, &skipHi);
}

Vec3d FastWindingNumberAccess::edgeGradient(const Vec3d& a, const Vec3d& b, double signedCurrent, const Vec3d& q)
{
    fwn_internal::CurrentEdge e;
    e.a = a;
    e.b = b;
    e.signedCurrent = signedCurrent;
    return FastWindingNumber::Impl::edgeField(e, q) / (4.0 * kPi);
}

double FastWindingNumberAccess::edgeHessianBound(const Vec3d& a, const Vec3d& b, double current, const Vec3d& lo,
                                                 const Vec3d& hi)
{
    const double de2 = fwn_internal::segmentBoxDist2(a, b, lo, hi);
    if (!(de2 > 0.0)) return std::numeric_limits<double>::infinity();
    return fwn_internal::edgeHessianTerm(std::abs(current), (b - a).length(), de2) / (4.0 * kPi) * (1.0 + 1e-9);
}

double FastWindingNumberAccess::segmentBoxDistance(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi)
{
    return std::sqrt(fwn_internal::segmentBoxDist2(a, b, lo, hi));
}

void FastWindingNumberAccess::currentEdge(const FastWindingNumber& f, size_t i, Vec3d& a, Vec3d& b, double& signedCurrent)
{
    const fwn_internal::CurrentEdge& e = f.mImpl->edges.at(i);
    a = e.a;
    b = e.b;
    signedCurrent = e.signedCurrent;
}

bool FastWindingNumberAccess::segmentMeetsBox(const Vec3d& a, const Vec3d& b, const Vec3d& lo, const Vec3d& hi)
{
    return fwn_internal::segmentMeetsBox(a, b, lo, hi);
}
} // namespace levelforge
