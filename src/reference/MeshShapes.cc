// SPDX-License-Identifier: Apache-2.0
// levelforge — procedural meshes. See MeshShapes.h.
#include <levelforge/reference/MeshShapes.h>

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <string>
#include <unordered_map>

namespace levelforge {

namespace meshshapes_internal {

constexpr double kPi = 3.14159265358979323846;

std::string num(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%g", v);
    return buf;
}

std::string vec(const Vec3d& v)
{
    return "(" + num(v[0]) + "," + num(v[1]) + "," + num(v[2]) + ")";
}

bool finite(const Vec3d& v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

void require(bool ok, const std::string& what)
{
    if (!ok) throw InvalidArgumentError(what);
}

inline uint64_t edgeKey(uint32_t a, uint32_t b)
{
    return a < b ? (uint64_t(a) << 32) | b : (uint64_t(b) << 32) | a;
}

/// Uniform double in [0, 1) from 53 random bits (the same on every platform).
inline double uniform01(std::mt19937_64& rng) { return double(rng() >> 11) * (1.0 / 9007199254740992.0); }

/// Two triangles per cell of an M x N vertex grid wrapped in both directions (vertex (i, j) at
/// index i * N + j): (i,j) -> (i+1,j) -> (i+1,j+1) and (i,j) -> (i+1,j+1) -> (i,j+1), or the
/// opposite winding when `reverse`.
inline void addWrappedGrid(TriangleMesh& mesh, uint32_t M, uint32_t N, bool reverse)
{
    for (uint32_t i = 0; i < M; ++i) {
        const uint32_t i1 = (i + 1) % M;
        for (uint32_t j = 0; j < N; ++j) {
            const uint32_t j1 = (j + 1) % N;
            const uint32_t a = i * N + j, b = i1 * N + j, c = i1 * N + j1, d = i * N + j1;
            if (reverse) {
                mesh.triangles.emplace_back(a, d, c);
                mesh.triangles.emplace_back(a, c, b);
            } else {
                mesh.triangles.emplace_back(a, b, c);
                mesh.triangles.emplace_back(a, c, d);
            }
        }
    }
}

} // namespace meshshapes_internal

// ------------------------------------------------------------------------------- icosphere

TriangleMesh makeIcosphere(const Vec3d& center, double radius, int subdivisions)
{
    using namespace meshshapes_internal;
    require(finite(center), "makeIcosphere: the centre must be finite");
    require(std::isfinite(radius) && radius > 0.0, "makeIcosphere: radius must be > 0, got " + num(radius));
    require(subdivisions >= 0 && subdivisions <= 10,
            "makeIcosphere: subdivisions must be in [0, 10], got " + std::to_string(subdivisions));

    const double t = (1.0 + std::sqrt(5.0)) / 2.0;
    std::vector<Vec3d> unit = {
        {-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
        {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    for (Vec3d& p : unit) p.normalize();
    std::vector<Vec3I> tris = {
        {0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
        {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
        {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    // Outward winding: the normal of each face points away from the centre.
    for (Vec3I& f : tris) {
        const Vec3d n = (unit[f[1]] - unit[f[0]]).cross(unit[f[2]] - unit[f[0]]);
        if (n.dot(unit[f[0]] + unit[f[1]] + unit[f[2]]) < 0.0) std::swap(f[1], f[2]);
    }

    const size_t finalV = size_t(10) * (size_t(1) << (2 * subdivisions)) + 2;
    const size_t finalT = size_t(20) * (size_t(1) << (2 * subdivisions));
    unit.reserve(finalV);
    std::unordered_map<uint64_t, uint32_t> midpoints;
    std::vector<Vec3I> next;
    for (int s = 0; s < subdivisions; ++s) {
        midpoints.clear();
        midpoints.reserve(tris.size() * 2);
        next.clear();
        next.reserve(tris.size() * 4);
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto [it, inserted] = midpoints.emplace(edgeKey(a, b), uint32_t(unit.size()));
            if (inserted) {
                Vec3d m = unit[a] + unit[b];
                m.normalize();
                unit.push_back(m);
            }
            return it->second;
        };
        for (const Vec3I& f : tris) {
            const uint32_t ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
            next.emplace_back(f[0], ab, ca);
            next.emplace_back(f[1], bc, ab);
            next.emplace_back(f[2], ca, bc);
            next.emplace_back(ab, bc, ca);
        }
        tris.swap(next);
    }
    (void)finalT;

    TriangleMesh mesh;
    mesh.points.resize(unit.size());
    for (size_t i = 0; i < unit.size(); ++i) mesh.points[i] = center + unit[i] * radius;
    mesh.triangles = std::move(tris);
    mesh.source = "<icosphere c=" + vec(center) + " r=" + num(radius) + " s=" +
                  std::to_string(subdivisions) + ">";
    return mesh;
}

// ------------------------------------------------------------------------------------- box

TriangleMesh makeBox(const Vec3d& min, const Vec3d& max, int segments)
{
    using namespace meshshapes_internal;
    require(finite(min) && finite(max), "makeBox: the corners must be finite");
    require(min[0] < max[0] && min[1] < max[1] && min[2] < max[2],
            "makeBox: min must be below max on every axis, got " + vec(min) + " and " + vec(max));
    require(segments >= 1 && segments <= 4096,
            "makeBox: segments must be in [1, 4096], got " + std::to_string(segments));

    const uint32_t n = uint32_t(segments);
    TriangleMesh mesh;
    const size_t surfaceVertices = size_t(6) * n * n + 2;
    mesh.points.reserve(surfaceVertices);
    mesh.triangles.reserve(size_t(12) * n * n);

    // Lattice points on the surface, shared between faces.
    std::unordered_map<uint64_t, uint32_t> index;
    index.reserve(surfaceVertices);
    auto coord = [&](int axis, uint32_t i) {
        return i == n ? max[axis] : min[axis] + (max[axis] - min[axis]) * (double(i) / double(n));
    };
    auto vertex = [&](uint32_t i, uint32_t j, uint32_t k) {
        const uint64_t key = (uint64_t(i) << 42) | (uint64_t(j) << 21) | uint64_t(k);
        const auto [it, inserted] = index.emplace(key, uint32_t(mesh.points.size()));
        if (inserted) mesh.points.emplace_back(coord(0, i), coord(1, j), coord(2, k));
        return it->second;
    };
    for (int a = 0; a < 3; ++a) {
        const int u = (a + 1) % 3, v = (a + 2) % 3; // u x v = +a
        for (int side = 0; side < 2; ++side) {
            for (uint32_t iu = 0; iu < n; ++iu) {
                for (uint32_t iv = 0; iv < n; ++iv) {
                    uint32_t corner[4];
                    const uint32_t du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
                    for (int c = 0; c < 4; ++c) {
                        uint32_t ijk[3];
                        ijk[a] = side ? n : 0;
                        ijk[u] = iu + du[c];
                        ijk[v] = iv + dv[c];
                        corner[c] = vertex(ijk[0], ijk[1], ijk[2]);
                    }
                    if (side) { // normal +a: counter-clockwise in (u, v)
                        mesh.triangles.emplace_back(corner[0], corner[1], corner[2]);
                        mesh.triangles.emplace_back(corner[0], corner[2], corner[3]);
                    } else {    // normal -a: clockwise in (u, v)
                        mesh.triangles.emplace_back(corner[0], corner[2], corner[1]);
                        mesh.triangles.emplace_back(corner[0], corner[3], corner[2]);
                    }
                }
            }
        }
    }
    mesh.source = "<box min=" + vec(min) + " max=" + vec(max) +
                  (segments > 1 ? " segments=" + std::to_string(segments) : std::string()) + ">";
    return mesh;
}

// ----------------------------------------------------------------------------------- torus

TriangleMesh makeTorus(const Vec3d& center, double majorRadius, double minorRadius,
                       int majorSegments, int minorSegments)
{
    using namespace meshshapes_internal;
    require(finite(center), "makeTorus: the centre must be finite");
    require(std::isfinite(majorRadius) && std::isfinite(minorRadius) && minorRadius > 0.0 &&
                majorRadius > minorRadius,
            "makeTorus: need 0 < minorRadius < majorRadius, got R=" + num(majorRadius) +
                " r=" + num(minorRadius));
    require(majorSegments >= 3 && minorSegments >= 3,
            "makeTorus: segments must be >= 3, got " + std::to_string(majorSegments) + " and " +
                std::to_string(minorSegments));

    const uint32_t M = uint32_t(majorSegments), N = uint32_t(minorSegments);
    TriangleMesh mesh;
    mesh.points.reserve(size_t(M) * N);
    mesh.triangles.reserve(size_t(2) * M * N);
    for (uint32_t i = 0; i < M; ++i) {
        const double u = 2.0 * kPi * double(i) / double(M);
        for (uint32_t j = 0; j < N; ++j) {
            const double v = 2.0 * kPi * double(j) / double(N);
            const double rho = majorRadius + minorRadius * std::cos(v);
            mesh.points.push_back(center + Vec3d(rho * std::cos(u), rho * std::sin(u),
                                                 minorRadius * std::sin(v)));
        }
    }
    // d/du x d/dv points outward, so (i,j) -> (i+1,j) -> (i+1,j+1) is counter-clockwise outside.
    meshshapes_internal::addWrappedGrid(mesh, M, N, false);
    mesh.source = "<torus c=" + vec(center) + " R=" + num(majorRadius) + " r=" + num(minorRadius) +
                  " segments=" + std::to_string(majorSegments) + "x" + std::to_string(minorSegments) + ">";
    return mesh;
}

// ------------------------------------------------------------------------------ torus knot

Vec3d torusKnotPoint(int p, int q, double radius, double t)
{
    const double a = 0.5 * radius;
    const double rho = radius + a * std::cos(q * t);
    return Vec3d(rho * std::cos(p * t), rho * std::sin(p * t), a * std::sin(q * t));
}

TriangleMesh makeTorusKnot(int p, int q, double radius, double tubeRadius, int segments,
                           int tubeSegments)
{
    using namespace meshshapes_internal;
    require(p >= 1 && q >= 1 && std::gcd(p, q) == 1,
            "makeTorusKnot: p and q must be >= 1 and coprime, got p=" + std::to_string(p) +
                " q=" + std::to_string(q));
    require(std::isfinite(radius) && radius > 0.0, "makeTorusKnot: radius must be > 0, got " + num(radius));
    require(std::isfinite(tubeRadius) && tubeRadius > 0.0,
            "makeTorusKnot: tubeRadius must be > 0, got " + num(tubeRadius));
    require(segments >= 3 && tubeSegments >= 3,
            "makeTorusKnot: segments must be >= 3, got " + std::to_string(segments) + " and " +
                std::to_string(tubeSegments));

    const uint32_t M = uint32_t(segments), N = uint32_t(tubeSegments);
    const double a = 0.5 * radius;
    TriangleMesh mesh;
    mesh.points.reserve(size_t(M) * N);
    mesh.triangles.reserve(size_t(2) * M * N);
    for (uint32_t i = 0; i < M; ++i) {
        const double t = 2.0 * kPi * double(i) / double(M);
        const Vec3d C = torusKnotPoint(p, q, radius, t);
        const double rho = radius + a * std::cos(q * t);
        // Analytic tangent.
        Vec3d T(-a * q * std::sin(q * t) * std::cos(p * t) - rho * p * std::sin(p * t),
                -a * q * std::sin(q * t) * std::sin(p * t) + rho * p * std::cos(p * t),
                a * q * std::cos(q * t));
        T.normalize();
        // Normal: the position vector made orthogonal to T. C has no azimuthal component and T
        // has one of at least p (R - a) > 0, so they are never parallel: the frame is smooth and
        // periodic (no twist to correct at the seam).
        Vec3d Nrm = C - T * C.dot(T);
        Nrm.normalize();
        const Vec3d B = T.cross(Nrm); // (T, N, B) right-handed
        for (uint32_t j = 0; j < N; ++j) {
            const double phi = 2.0 * kPi * double(j) / double(N);
            mesh.points.push_back(C + (Nrm * std::cos(phi) + B * std::sin(phi)) * tubeRadius);
        }
    }
    // d/dt x d/dphi points inward for this frame, so go (i,j) -> (i,j+1) -> (i+1,j+1).
    meshshapes_internal::addWrappedGrid(mesh, M, N, true);
    mesh.source = "<torus knot p=" + std::to_string(p) + " q=" + std::to_string(q) + " r=" + num(radius) +
                  " tube=" + num(tubeRadius) + " segments=" + std::to_string(segments) + "x" +
                  std::to_string(tubeSegments) + ">";
    return mesh;
}

// -------------------------------------------------------------------------- random triangles

TriangleMesh makeRandomTriangles(uint32_t count, uint64_t seed, const BBoxd& box, double maxEdge)
{
    using namespace meshshapes_internal;
    require(finite(box.min()) && finite(box.max()) && box.min()[0] < box.max()[0] &&
                box.min()[1] < box.max()[1] && box.min()[2] < box.max()[2],
            "makeRandomTriangles: the box must be finite with positive extent on every axis");
    require(std::isfinite(maxEdge) && maxEdge > 0.0,
            "makeRandomTriangles: maxEdge must be > 0, got " + num(maxEdge));

    std::mt19937_64 rng(seed);
    const Vec3d lo = box.min(), hi = box.max(), ext = hi - lo;
    const double ballRadius = 0.5 * maxEdge;
    auto inBall = [&]() {
        for (;;) {
            const Vec3d v(2.0 * uniform01(rng) - 1.0, 2.0 * uniform01(rng) - 1.0, 2.0 * uniform01(rng) - 1.0);
            if (v.lengthSqr() <= 1.0) return v * ballRadius;
        }
    };
    auto clampToBox = [&](Vec3d v) {
        for (int k = 0; k < 3; ++k) v[k] = std::min(std::max(v[k], lo[k]), hi[k]);
        return v;
    };

    TriangleMesh mesh;
    mesh.points.reserve(size_t(count) * 3);
    mesh.triangles.reserve(count);
    for (uint32_t i = 0; i < count; ++i) {
        Vec3d a, b, c;
        for (;;) { // resample the (practically impossible) degenerate triangles
            const Vec3d centre(lo[0] + ext[0] * uniform01(rng), lo[1] + ext[1] * uniform01(rng),
                               lo[2] + ext[2] * uniform01(rng));
            a = clampToBox(centre + inBall());
            b = clampToBox(centre + inBall());
            c = clampToBox(centre + inBall());
            if (!isDegenerateTriangle(a, b, c)) break;
        }
        const uint32_t base = uint32_t(mesh.points.size());
        mesh.points.push_back(a);
        mesh.points.push_back(b);
        mesh.points.push_back(c);
        mesh.triangles.emplace_back(base, base + 1, base + 2);
    }
    mesh.source = "<random triangles n=" + std::to_string(count) + " seed=" + std::to_string(seed) +
                  " box=" + vec(lo) + "-" + vec(hi) + " maxEdge=" + num(maxEdge) + ">";
    return mesh;
}

// -------------------------------------------------------------------------------- measures

double signedVolume(const TriangleMesh& mesh)
{
    if (mesh.triangles.empty()) return 0.0;
    const BBoxd b = mesh.bounds();
    const Vec3d o = (b.min() + b.max()) * 0.5; // reference point near the mesh for accuracy
    double sum = 0.0;
    for (const Vec3I& t : mesh.triangles) {
        const Vec3d a = mesh.points[t[0]] - o, bb = mesh.points[t[1]] - o, c = mesh.points[t[2]] - o;
        sum += a.dot(bb.cross(c));
    }
    return sum / 6.0;
}

double surfaceArea(const TriangleMesh& mesh)
{
    double sum = 0.0;
    for (const Vec3I& t : mesh.triangles) {
        const Vec3d& a = mesh.points[t[0]];
        sum += (mesh.points[t[1]] - a).cross(mesh.points[t[2]] - a).length();
    }
    return 0.5 * sum;
}

// ------------------------------------------------------------------------- built-in names

bool isBuiltinMeshName(const std::string& name) { return name.rfind("builtin:", 0) == 0; }

TriangleMesh makeBuiltinMesh(const std::string& name)
{
    if (name == "builtin:torus-knot") return makeTorusKnot();
    if (name == "builtin:sphere") return makeIcosphere(Vec3d(0.0), 1.0, 4);
    if (name == "builtin:box") return makeBox(Vec3d(-1.0), Vec3d(1.0));
    throw InvalidArgumentError("unknown built-in mesh '" + name +
                               "' (builtin:torus-knot, builtin:sphere, builtin:box)");
}

} // namespace levelforge
