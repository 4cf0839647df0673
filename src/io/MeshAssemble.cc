// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief From what OpenMesh read to a TriangleMesh: quads split along 0-2 (1-3 where 0-2 leaves
///        a non-convex quad), ear clipping of larger polygons in their best-fit plane, and the
///        assembly (exact positions, range checks, dropped faces).
#include "io/MeshImporter.h"

#include <unordered_set>

namespace levelforge {

namespace meshio_internal {

// ----------------------------------------------------------------------------- ear clipping

/// Triangulates simple polygons in their best-fit plane: a quad along its 0-2 diagonal (as
/// OpenVDB's meshToVolume and most tools do), or along 1-3 where 0-2 would leave a non-convex
/// quad; larger polygons (and bow-tie quads) by ear clipping. Buffers are reused from polygon to
/// polygon.
class EarClipper
{
public:
    /// Appends triangles for @a corners (k >= 4 distinct consecutive corners) to @a out.
    /// Returns false if it had to fall back to a fan.
    bool triangulate(const std::vector<Vec3d>& P, const uint32_t* corners, size_t k,
                     std::vector<Vec3I>& out, std::unordered_set<uint64_t>* edges = nullptr)
    {
        // Newell normal, relative to the first corner for accuracy.
        const Vec3d o = P[corners[0]];
        Vec3d n(0.0);
        for (size_t i = 0; i < k; ++i) {
            const Vec3d a = P[corners[i]] - o;
            const Vec3d b = P[corners[(i + 1) % k]] - o;
            n += a.cross(b);
        }
        const double len = n.length();
        if (!(len > 0.0)) return fan(corners, k, out);
        n /= len;
        // Orthonormal basis (u, v) of the plane with u x v = n: the polygon is CCW in (u, v).
        Vec3d u = std::abs(n[0]) < 0.9 ? Vec3d(1, 0, 0).cross(n) : Vec3d(0, 1, 0).cross(n);
        u.normalize();
        const Vec3d v = n.cross(u);
        mQ.resize(k);
        for (size_t i = 0; i < k; ++i) {
            const Vec3d d = P[corners[i]] - o;
            mQ[i] = {d.dot(u), d.dot(v)};
        }
        if (k == 4) {
            // quads as OpenVDB and most tools split them: 0-1-2, 0-2-3, unless that diagonal
            // leaves the quad (a non-convex quad seen in its best-fit plane, where it would fold
            // the surface); then 1-2-3, 1-3-0; a bow tie (neither) goes to the ear clipper
            // (or where 0-2 is already an edge of another face, or the diagonal of an earlier
            // quad, and 1-3 is not: that split would make the edge non-manifold)
            const auto inside = [&](int a) {
                const int b = (a + 1) % 4, c = (a + 2) % 4, d = (a + 3) % 4;
                return orient(mQ[a], mQ[b], mQ[c]) > 0.0 && orient(mQ[a], mQ[c], mQ[d]) > 0.0;
            };
            const auto taken = [&](int a) { return edges && edges->count(edgeKey(corners[a], corners[a + 2])) > 0; };
            const auto split = [&](int a) {
                const int b = (a + 1) % 4, c = (a + 2) % 4, d = (a + 3) % 4;
                if (edges) edges->insert(edgeKey(corners[a], corners[c])); // taken for later quads
                out.emplace_back(corners[a], corners[b], corners[c]);
                out.emplace_back(corners[a], corners[c], corners[d]);
                return true;
            };
            const bool in0 = inside(0), in1 = inside(1);
            if (in0 && (!in1 || !taken(0) || taken(1))) return split(0);
            if (in1) return split(1);
        }
        mRing.resize(k);
        for (size_t i = 0; i < k; ++i) mRing[i] = uint32_t(i);

        size_t guard = 0;
        size_t i = 0;
        while (mRing.size() > 3) {
            const size_t m = mRing.size();
            if (guard++ > m) { // went once around without finding an ear
                fanRing(corners, out);
                return false;
            }
            const size_t ip = (i + m - 1) % m, in = (i + 1) % m;
            const uint32_t a = mRing[ip], b = mRing[i], c = mRing[in];
            if (isEar(a, b, c)) {
                out.emplace_back(corners[a], corners[b], corners[c]);
                mRing.erase(mRing.begin() + std::ptrdiff_t(i));
                if (i >= mRing.size()) i = 0;
                guard = 0;
            } else {
                i = (i + 1) % m;
            }
        }
        out.emplace_back(corners[mRing[0]], corners[mRing[1]], corners[mRing[2]]);
        return true;
    }

    /// The key of the undirected edge (a, b).
    static uint64_t edgeKey(uint32_t a, uint32_t b)
    {
        return a < b ? (uint64_t(a) << 32) | b : (uint64_t(b) << 32) | a;
    }

private:
    struct P2 { double x, y; };

    static double orient(const P2& a, const P2& b, const P2& c)
    {
        return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    }

    bool isEar(uint32_t a, uint32_t b, uint32_t c) const
    {
        const P2 &A = mQ[a], &B = mQ[b], &C = mQ[c];
        if (!(orient(A, B, C) > 0.0)) return false; // reflex or flat corner
        for (uint32_t r : mRing) {
            if (r == a || r == b || r == c) continue;
            const P2& R = mQ[r];
            if ((R.x == A.x && R.y == A.y) || (R.x == B.x && R.y == B.y) || (R.x == C.x && R.y == C.y)) {
                continue; // a repeated position (touching polygon)
            }
            if (orient(A, B, R) >= 0.0 && orient(B, C, R) >= 0.0 && orient(C, A, R) >= 0.0) return false;
        }
        return true;
    }

    static bool fan(const uint32_t* corners, size_t k, std::vector<Vec3I>& out)
    {
        for (size_t i = 1; i + 1 < k; ++i) out.emplace_back(corners[0], corners[i], corners[i + 1]);
        return false;
    }

    void fanRing(const uint32_t* corners, std::vector<Vec3I>& out) const
    {
        for (size_t i = 1; i + 1 < mRing.size(); ++i) {
            out.emplace_back(corners[mRing[0]], corners[mRing[i]], corners[mRing[i + 1]]);
        }
    }

    std::vector<P2> mQ;
    std::vector<uint32_t> mRing;
};

// ------------------------------------------------------------------------------- assembling

/// True when the float OpenMesh produced is (within one float step of) the exact value.
inline bool sameAsFloat(double exact, double received)
{
    const float f = float(exact);
    const float r = float(received);
    return f == r || std::nextafter(f, FLT_MAX) == r || std::nextafter(f, -FLT_MAX) == r;
}

void assemble(const std::string& path, Importer& imp, Prescan& pre, TriangleMesh& mesh,
              MeshReadInfo& info)
{
    // Positions: exact doubles from the pre-scan when they agree with what OpenMesh read.
    bool exact = !pre.importerPointsExact && pre.havePoints && pre.points.size() == imp.mPoints.size();
    for (size_t i = 0; exact && i < pre.points.size(); ++i) {
        for (int k = 0; k < 3; ++k) {
            if (!sameAsFloat(pre.points[i][k], imp.mPoints[i][k])) { exact = false; break; }
        }
    }
    if (pre.importerPointsExact) {
        mesh.points = std::move(imp.mPoints);
        exact = true;
    } else if (exact) {
        mesh.points = std::move(pre.points);
    } else {
        mesh.points = std::move(imp.mPoints);
    }
    info.doublePrecision = exact;
    info.fileVertices = mesh.points.size();
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        const Vec3d& p = mesh.points[i];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            throwInvalid(path, 0, "vertex " + std::to_string(i) + " has a non-finite coordinate " +
                formatPoint(p));
        }
    }

    // Faces: range check, drop faces with fewer than three distinct corners, triangulate.
    const int64_t nV = int64_t(mesh.points.size());
    std::vector<uint32_t> poly;
    EarClipper clipper;
    const std::vector<int32_t>& s = imp.mFaceStream;
    size_t pos = 0, expected = 0;
    for (uint64_t f = 0; f < imp.mFaceCount; ++f) { // at most k - 2 triangles per face
        const size_t k = size_t(s[pos]);
        expected += k >= 3 ? k - 2 : 0;
        pos += 1 + k;
    }
    mesh.triangles.clear();
    mesh.triangles.reserve(expected);
    mesh.faceIndex.clear();
    mesh.faceIndex.reserve(expected);
    // the faces' edges, where there are quads (their split avoids an existing edge)
    std::unordered_set<uint64_t> edges;
    bool quads = false;
    for (size_t q = 0, f = 0; f < imp.mFaceCount && !quads; ++f) { quads = s[q] == 4; q += 1 + size_t(s[q]); }
    if (quads) {
        edges.reserve(expected * 2);
        for (size_t q = 0, f = 0; f < imp.mFaceCount; ++f) {
            const size_t k = size_t(s[q]);
            for (size_t j = 0; j < k; ++j) {
                const int32_t a = s[q + 1 + j], b = s[q + 1 + (j + 1) % k];
                if (a >= 0 && b >= 0 && a != b) edges.insert(EarClipper::edgeKey(uint32_t(a), uint32_t(b)));
            }
            q += 1 + k;
        }
    }
    uint64_t dropped = 0;
    pos = 0;
    for (uint64_t f = 0; f < imp.mFaceCount; ++f) {
        const size_t k = size_t(s[pos]);
        const int32_t* c = s.data() + pos + 1;
        pos += 1 + k;
        for (size_t j = 0; j < k; ++j) {
            if (c[j] < 0 || c[j] >= nV) {
                throwInvalid(path, 0, "face " + std::to_string(f) + ": vertex index " +
                    (c[j] < 0 ? std::string("invalid (negative)") : std::to_string(c[j])) +
                    " is out of range (the file has " + std::to_string(nV) + " vertices)");
            }
        }
        if (k == 3) {
            if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
                ++dropped;
            } else {
                mesh.triangles.emplace_back(uint32_t(c[0]), uint32_t(c[1]), uint32_t(c[2]));
                mesh.faceIndex.push_back(uint32_t(f));
            }
            continue;
        }
        // Polygon: remove repeated consecutive corners (cyclically).
        poly.clear();
        for (size_t j = 0; j < k; ++j) {
            const uint32_t idx = uint32_t(c[j]);
            if (poly.empty() || poly.back() != idx) poly.push_back(idx);
        }
        while (poly.size() > 1 && poly.back() == poly.front()) poly.pop_back();
        size_t distinct = poly.size();
        if (distinct >= 3) { // count distinct values (small polygons: quadratic is fine)
            distinct = 0;
            for (size_t j = 0; j < poly.size(); ++j) {
                if (std::find(poly.begin(), poly.begin() + std::ptrdiff_t(j), poly[j]) ==
                    poly.begin() + std::ptrdiff_t(j)) {
                    ++distinct;
                }
            }
        }
        if (distinct < 3) {
            ++dropped;
            continue;
        }
        if (poly.size() == 3) {
            mesh.triangles.emplace_back(poly[0], poly[1], poly[2]);
            mesh.faceIndex.push_back(uint32_t(f));
            continue;
        }
        ++info.polygons;
        const size_t first = mesh.triangles.size();
        if (!clipper.triangulate(mesh.points, poly.data(), poly.size(), mesh.triangles, quads ? &edges : nullptr)) {
            ++info.fanFallbacks;
            // A fan over a polygon that repeats a corner may produce collapsed triangles.
            auto collapsed = [](const Vec3I& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; };
            mesh.triangles.erase(std::remove_if(mesh.triangles.begin() + std::ptrdiff_t(first),
                                     mesh.triangles.end(), collapsed), mesh.triangles.end());
        }
        mesh.faceIndex.resize(mesh.triangles.size(), uint32_t(f));
    }
    // Triangle i is face i (no polygon, no dropped face): leave faceIndex empty.
    bool identity = mesh.faceIndex.size() == mesh.triangles.size();
    for (size_t t = 0; identity && t < mesh.faceIndex.size(); ++t) identity = mesh.faceIndex[t] == t;
    if (identity) std::vector<uint32_t>().swap(mesh.faceIndex);
    const uint64_t received = imp.mFaceCount;
    info.fileFaces = pre.haveFaces ? std::max(pre.faces, received) : received;
    info.droppedFaces = dropped + (info.fileFaces - received);
    if (mesh.triangles.empty()) {
        std::string what = "no triangles (read " + std::to_string(mesh.points.size()) +
            " vertices and " + std::to_string(info.fileFaces) + " faces";
        if (info.droppedFaces > 0) {
            what += ", " + std::to_string(info.droppedFaces) + " of them without area";
        } else if (info.fileFaces == 0) {
            what += "; is it really a ." + info.format + " file?";
        }
        throwInvalid(path, 0, what + ")");
    }
}

void attachAttributes(const std::string& path, const AttributeScan& scan, TriangleMesh& mesh)
{
    const size_t nT = mesh.triangles.size(), nV = mesh.points.size();
    const size_t faces = scan.faceStart.empty() ? 0 : scan.faceStart.size() - 1;
    for (const AttributeSource& src : scan.sources) {
        const size_t C = size_t(src.components);
        MeshAttribute attr;
        attr.name = src.name;
        attr.components = src.components;
        attr.values.resize(nT * 3 * C);
        const size_t entries = src.values.size() / C;
        for (size_t t = 0; t < nT; ++t) {
            const Vec3I& tri = mesh.triangles[t];
            for (int k = 0; k < 3; ++k) {
                size_t entry = tri[k];
                if (src.perVertex) {
                    if (entry >= nV || entry >= entries) {
                        throwInvalid(path, 0, "attribute '" + src.name + "': no value for vertex " + std::to_string(entry));
                    }
                } else {
                    // the corner of the triangle's face that names this vertex (a face names each
                    // vertex once: repeated corners were removed when it was read)
                    const size_t f = mesh.sourceFace(t);
                    if (f >= faces) {
                        throwInvalid(path, 0, "attribute '" + src.name + "': face " + std::to_string(f) +
                            " was not found by the attribute scan");
                    }
                    size_t j = scan.faceStart[f];
                    while (j < scan.faceStart[f + 1] && uint32_t(scan.cornerVertex[j]) != tri[k]) ++j;
                    if (j == scan.faceStart[f + 1] || src.cornerIndex[j] < 0 || size_t(src.cornerIndex[j]) >= entries) {
                        throwInvalid(path, 0, "attribute '" + src.name + "': face " + std::to_string(f) +
                            " has no value for its vertex " + std::to_string(tri[k]));
                    }
                    entry = size_t(src.cornerIndex[j]);
                }
                std::copy_n(src.values.data() + entry * C, C, attr.values.data() + (3 * t + size_t(k)) * C);
            }
        }
        mesh.attributes.push_back(std::move(attr));
    }
}

} // namespace meshio_internal

} // namespace levelforge
