// SPDX-License-Identifier: Apache-2.0
// Tetrahedral shells (Erleben & Dohlmann §3.3–3.5). See TetrahedralShell.h.
#include <levelforge/core/Exceptions.h>
#include <levelforge/scan/TetrahedralShell.h>
#include "scan/TetrahedralShellInternal.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace levelforge {

const char* toString(ShellMethod method)
{
    switch (method) {
    case ShellMethod::PseudoNormal: return "pseudonormal";
    case ShellMethod::Thin: return "thin";
    case ShellMethod::Offset: return "offset";
    case ShellMethod::Obb: return "obb";
    }
    return "?";
}

ShellMethod shellMethodFromString(const std::string& name)
{
    for (ShellMethod m : {ShellMethod::PseudoNormal, ShellMethod::Thin, ShellMethod::Offset, ShellMethod::Obb})
        if (name == toString(m)) return m;
    throw InvalidArgumentError("unknown shell method '" + name + "' (pseudonormal, thin, offset, obb)");
}

const char* toString(ShellCoverage coverage)
{
    return coverage == ShellCoverage::Paper ? "paper" : "complete";
}

ShellCoverage shellCoverageFromString(const std::string& name)
{
    for (ShellCoverage c : {ShellCoverage::Complete, ShellCoverage::Paper})
        if (name == toString(c)) return c;
    throw InvalidArgumentError("unknown shell coverage '" + name + "' (complete, paper)");
}

namespace shell_internal {

double volume(const Tetrahedron& t)
{
    return std::abs((t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).dot(t.p[3] - t.p[0])) / 6.0;
}

std::vector<std::array<int, 3>> convexHull(const std::vector<Vec3d>& pts)
{
    std::vector<std::array<int, 3>> out;
    const int n = int(pts.size());
    if (n < 4 || n > 64) return out;
    BBoxd box;
    for (const Vec3d& p : pts) box.expand(p);
    const double scale = std::max(box.extents()[box.maxExtent()], 1e-300);
    const double tol = 1e-10 * scale;
    // Unique points (first index of each cluster of coincident points).
    int uniq[64];
    int m = 0;
    for (int i = 0; i < n; ++i) {
        bool dup = false;
        for (int j = 0; j < m; ++j)
            if ((pts[i] - pts[uniq[j]]).length() <= tol) { dup = true; break; }
        if (!dup) uniq[m++] = i;
    }
    if (m < 4) return out;
    struct Plane { Vec3d n; double d; };
    Plane done[256];
    int nDone = 0;
    for (int a = 0; a < m; ++a)
        for (int b = a + 1; b < m; ++b)
            for (int c = b + 1; c < m; ++c) {
                const Vec3d& pa = pts[uniq[a]];
                Vec3d nrm = (pts[uniq[b]] - pa).cross(pts[uniq[c]] - pa);
                const double len = nrm.length();
                if (!(len > 1e-9 * scale * scale)) continue;
                nrm /= len;
                double d = nrm.dot(pa);
                bool pos = false, neg = false;
                for (int q = 0; q < m; ++q) {
                    const double s = nrm.dot(pts[uniq[q]]) - d;
                    if (s > tol) pos = true;
                    else if (s < -tol) neg = true;
                    if (pos && neg) break; // not a facet (the common case): stop early
                }
                if (pos && neg) continue;
                if (!pos && !neg) return {}; // all coplanar: flat, no hull
                if (pos) { nrm = -nrm; d = -d; }
                bool seen = false;
                for (int i = 0; i < nDone; ++i)
                    if (done[i].n.dot(nrm) > 1.0 - 1e-12 && std::abs(done[i].d - d) <= 4 * tol) { seen = true; break; }
                if (seen) continue;
                if (nDone < 256) done[nDone++] = {nrm, d};
                int face[64];
                int nFace = 0;
                for (int q = 0; q < m; ++q)
                    if (std::abs(nrm.dot(pts[uniq[q]]) - d) <= tol) face[nFace++] = uniq[q];
                if (nFace == 3) {
                    out.push_back({uniq[a], uniq[b], uniq[c]});
                    continue;
                }
                // Coplanar facet: 2-D convex hull (monotone chain) in a plane basis, then a fan.
                Vec3d u = std::abs(nrm[0]) < 0.9 ? Vec3d(1, 0, 0).cross(nrm) : Vec3d(0, 1, 0).cross(nrm);
                u.normalize();
                const Vec3d v = nrm.cross(u);
                struct P2 { double x, y; int id; };
                std::vector<P2> q2;
                for (int i = 0; i < nFace; ++i) q2.push_back({u.dot(pts[face[i]]), v.dot(pts[face[i]]), face[i]});
                std::sort(q2.begin(), q2.end(), [](const P2& l, const P2& r) {
                    return l.x < r.x || (l.x == r.x && (l.y < r.y || (l.y == r.y && l.id < r.id)));
                });
                auto cross2 = [](const P2& o, const P2& p, const P2& r) {
                    return (p.x - o.x) * (r.y - o.y) - (p.y - o.y) * (r.x - o.x);
                };
                std::vector<P2> h(2 * q2.size());
                size_t k = 0;
                for (size_t i = 0; i < q2.size(); ++i) {
                    while (k >= 2 && cross2(h[k - 2], h[k - 1], q2[i]) <= tol * scale) --k;
                    h[k++] = q2[i];
                }
                for (size_t i = q2.size() - 1, t = k + 1; i-- > 0;) {
                    while (k >= t && cross2(h[k - 2], h[k - 1], q2[i]) <= tol * scale) --k;
                    h[k++] = q2[i];
                }
                h.resize(k > 0 ? k - 1 : 0);
                for (size_t i = 1; i + 1 < h.size(); ++i) out.push_back({h[0].id, h[i].id, h[i + 1].id});
            }
    return out;
}

void hullTetrahedra(const std::vector<Vec3d>& pts, uint32_t triangle, std::vector<Tetrahedron>& out)
{
    const auto faces = convexHull(pts);
    if (faces.empty()) return;
    std::vector<int> used;
    for (const auto& f : faces)
        for (int i : f) used.push_back(i);
    std::sort(used.begin(), used.end());
    used.erase(std::unique(used.begin(), used.end()), used.end());
    Vec3d centre(0.0);
    for (int i : used) centre += pts[i];
    centre /= double(used.size());
    for (const auto& f : faces) {
        Tetrahedron t{{centre, pts[f[0]], pts[f[1]], pts[f[2]]}, triangle};
        if (volume(t) > 0.0) out.push_back(t);
    }
}

double thinShellExtrusionLimit(const std::array<Vec3d, 3>& p, const std::array<Vec3d, 3>& n, double sigma)
{
    // q_i(e) = p_i + e * d_i with d_i = sigma * n_i; n_q(e) = (q2 - q1) x (q3 - q1) = A e^2 + B e + C
    // (Eq. 6-10); constraint rows n_i . n_q(e) > 0 (Eq. 11).
    const Vec3d d1 = n[0] * sigma, d2 = n[1] * sigma, d3 = n[2] * sigma;
    const Vec3d A = (d2 - d1).cross(d3 - d1);
    const Vec3d B = (p[1] - p[0]).cross(d3 - d1) + (d2 - d1).cross(p[2] - p[0]);
    const Vec3d C = (p[1] - p[0]).cross(p[2] - p[0]);
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
        const double a = n[i].dot(A), b = n[i].dot(B), c = n[i].dot(C);
        if (c <= 0.0) return 0.0; // already violated at e = 0
        const double scale = std::max({std::abs(a), std::abs(b), std::abs(c)});
        if (std::abs(a) <= 1e-14 * scale) {
            if (b < 0.0) best = std::min(best, -c / b);
            continue;
        }
        const double disc = b * b - 4.0 * a * c;
        if (disc < 0.0) continue;
        const double sq = std::sqrt(disc);
        const double qq = -0.5 * (b + (b >= 0.0 ? sq : -sq));
        const double r1 = qq / a, r2 = qq != 0.0 ? c / qq : std::numeric_limits<double>::infinity();
        if (r1 > 0.0) best = std::min(best, r1);
        if (r2 > 0.0) best = std::min(best, r2);
    }
    return best;
}

std::array<Vec3d, 8> obbCorners(const Vec3d& a, const Vec3d& b, const Vec3d& c, double eps)
{
    const Vec3d v[3] = {a, b, c};
    int k = 0;
    double best = -1.0;
    for (int i = 0; i < 3; ++i) {
        const double l = (v[(i + 1) % 3] - v[i]).lengthSqr();
        if (l > best) { best = l; k = i; }
    }
    const Vec3d& A = v[k];
    const Vec3d& B = v[(k + 1) % 3];
    const Vec3d& C = v[(k + 2) % 3];
    const double elen = std::sqrt(best);
    const Vec3d u = (B - A) / elen;
    Vec3d nrm = (B - A).cross(C - A);
    nrm.normalize();
    Vec3d w = nrm.cross(u);
    if (w.dot(C - A) < 0.0) w = -w;
    const double cu = u.dot(C - A), hgt = w.dot(C - A);
    const double u0 = std::min(0.0, cu) - eps, u1 = std::max(elen, cu) + eps;
    const double w0 = std::min(0.0, hgt) - eps, w1 = std::max(0.0, hgt) + eps;
    std::array<Vec3d, 8> out;
    for (int i = 0; i < 8; ++i)
        out[i] = A + u * ((i & 1) ? u1 : u0) + w * ((i & 2) ? w1 : w0) + nrm * ((i & 4) ? eps : -eps);
    return out;
}

std::array<Vec3d, 12> epsilonPrism(const Vec3d& a, const Vec3d& b, const Vec3d& c, double eps)
{
    const Vec3d v[3] = {a, b, c};
    Vec3d n = (b - a).cross(c - a);
    n.normalize();
    Vec3d out[3]; // outward unit normal of edge i = (v[i], v[i+1]) in the face plane
    for (int i = 0; i < 3; ++i) {
        out[i] = (v[(i + 1) % 3] - v[i]).cross(n);
        out[i].normalize();
    }
    std::array<Vec3d, 12> c12;
    for (int i = 0; i < 3; ++i) {
        const int prev = (i + 2) % 3; // edge (v[i-1], v[i])
        Vec3d w = out[prev] + out[i]; // bisector of the vertex's outward normal cone
        w.normalize();
        // On edge prev's offset line, past v[i] along the edge; then on edge i's offset line.
        Vec3d d0 = v[i] - v[prev], d1 = v[i] - v[(i + 1) % 3];
        d0.normalize();
        d1.normalize();
        const double l0 = eps * (1.0 - out[prev].dot(w)) / std::max(d0.dot(w), 1e-12);
        const double l1 = eps * (1.0 - out[i].dot(w)) / std::max(d1.dot(w), 1e-12);
        c12[2 * i] = v[i] + out[prev] * eps + d0 * l0;
        c12[2 * i + 1] = v[i] + out[i] * eps + d1 * l1;
    }
    for (int k = 0; k < 6; ++k) {
        c12[k + 6] = c12[k] + n * eps;
        c12[k] -= n * eps;
    }
    return c12;
}

void prismTetrahedra(const std::array<Vec3d, 12>& c, uint32_t triangle, std::vector<Tetrahedron>& out)
{
    // Fan of the hexagon from corner 0; each triangular prism (a, b, d | a', b', d') as the three
    // tetrahedra (a, b, d, d'), (a, b, b', d'), (a, a', b', d'), whose union is the prism.
    for (int k = 1; k <= 4; ++k) {
        const int a = 0, b = k, d = k + 1;
        const Tetrahedron tets[3] = {{{c[a], c[b], c[d], c[d + 6]}, triangle},
                                     {{c[a], c[b], c[b + 6], c[d + 6]}, triangle},
                                     {{c[a], c[a + 6], c[b + 6], c[d + 6]}, triangle}};
        for (const Tetrahedron& t : tets)
            if (volume(t) > 0.0) out.push_back(t);
    }
}

void obbTetrahedra(const std::array<Vec3d, 8>& c, uint32_t triangle, std::vector<Tetrahedron>& out)
{
    // Five-tetrahedron decomposition of a box: the central tetrahedron (1, 2, 4, 7) and the four
    // corner tetrahedra at 0, 3, 5, 6.
    static const int tets[5][4] = {{1, 2, 4, 7}, {0, 1, 2, 4}, {3, 1, 2, 7}, {5, 1, 4, 7}, {6, 2, 4, 7}};
    for (const auto& t : tets) out.push_back(Tetrahedron{{c[t[0]], c[t[1]], c[t[2]], c[t[3]]}, triangle});
}

} // namespace shell_internal

std::vector<Tetrahedron> buildTetrahedralShell(const TriangleMesh& mesh, const PseudoNormals& normals,
                                               const TetrahedralShellOptions& options,
                                               TetrahedralShellStats* statsOut)
{
    using namespace shell_internal;
    const double eps = options.epsilon;
    if (!(eps > 0.0) || !std::isfinite(eps)) {
        std::ostringstream os;
        os << "shell width epsilon must be positive and finite, got " << eps;
        throw InvalidArgumentError(os.str());
    }
    const size_t nt = mesh.triangles.size();
    std::vector<std::vector<Tetrahedron>> perFace(nt);
    tbb::enumerable_thread_specific<uint64_t> limited(0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nt, 256), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<Vec3d> pts;
        for (size_t t = r.begin(); t != r.end(); ++t) {
            if (normals.isDegenerate(uint32_t(t))) continue;
            const Vec3I& tri = mesh.triangles[t];
            const std::array<Vec3d, 3> p = {mesh.points[tri[0]], mesh.points[tri[1]], mesh.points[tri[2]]};
            const Vec3d fn = normals.faceNormal(uint32_t(t));
            std::vector<Tetrahedron>& out = perFace[t];
            if (options.method == ShellMethod::Obb) {
                obbTetrahedra(obbCorners(p[0], p[1], p[2], eps), uint32_t(t), out);
                continue;
            }
            if (options.coverage == ShellCoverage::Complete) {
                // hull(paper points + prism) = prism: every paper point lies within eps of the face.
                prismTetrahedra(epsilonPrism(p[0], p[1], p[2], eps), uint32_t(t), out);
                continue;
            }
            std::array<Vec3d, 3> n;
            for (int k = 0; k < 3; ++k) {
                Vec3d v = normals.vertexNormal(tri[k]);
                const double l = v.length();
                n[k] = (l > 0.0 && std::isfinite(l)) ? v / l : fn;
            }
            double lenOut = eps, lenIn = eps;
            if (options.method == ShellMethod::Thin) {
                lenOut = std::min(eps, thinShellExtrusionLimit(p, n, +1.0));
                lenIn = std::min(eps, thinShellExtrusionLimit(p, n, -1.0));
                if (lenOut < eps || lenIn < eps) ++limited.local();
                // Eq. 11 asks for a strictly positive length; keep the prism a solid.
                lenOut = std::max(lenOut, 1e-3 * eps);
                lenIn = std::max(lenIn, 1e-3 * eps);
            }
            pts.clear();
            for (int k = 0; k < 3; ++k) {
                pts.push_back(p[k] + n[k] * lenOut);
                pts.push_back(p[k] - n[k] * lenIn);
            }
            if (options.method == ShellMethod::Offset)
                for (int k = 0; k < 3; ++k) {
                    pts.push_back(p[k] + fn * eps);
                    pts.push_back(p[k] - fn * eps);
                }
            hullTetrahedra(pts, uint32_t(t), out);
        }
    });
    std::vector<Tetrahedron> all;
    TetrahedralShellStats stats;
    size_t total = 0;
    for (const auto& v : perFace) total += v.size();
    all.reserve(total);
    for (size_t t = 0; t < nt; ++t) {
        if (normals.isDegenerate(uint32_t(t))) { ++stats.skippedDegenerate; continue; }
        ++stats.faces;
        all.insert(all.end(), perFace[t].begin(), perFace[t].end());
    }
    stats.tetrahedra = all.size();
    for (uint64_t v : limited) stats.limitedExtrusions += v;
    if (options.method != ShellMethod::Obb && options.coverage == ShellCoverage::Complete)
        stats.completedFaces = stats.faces;
    if (statsOut) *statsOut = stats;
    return all;
}

} // namespace levelforge
