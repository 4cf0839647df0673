// SPDX-License-Identifier: Apache-2.0
// levelforge — mesh validation. See MeshValidation.h.
#include <levelforge/core/MeshValidation.h>

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>

namespace levelforge {

namespace meshvalidation_internal {

/// Counting sort: turns per-bucket counts into bucket starts (exclusive prefix sum, in place);
/// returns the total.
inline uint64_t exclusivePrefixSum(std::vector<uint64_t>& counts, size_t n)
{
    uint64_t total = 0;
    for (size_t i = 0; i < n; ++i) {
        const uint64_t c = counts[i];
        counts[i] = total;
        total += c;
    }
    return total;
}


std::string sourceName(const TriangleMesh& mesh)
{
    return mesh.source.empty() ? std::string("<mesh>") : mesh.source;
}

/// Counts over a range of edge buckets (one bucket per smaller vertex index).
struct EdgeCounts
{
    uint64_t edges = 0, boundary = 0, nonManifold = 0, inconsistent = 0;
    std::vector<Vec3I> boundaryExamples, nonManifoldExamples, inconsistentExamples;

    static void addExample(std::vector<Vec3I>& list, const Vec3I& e)
    {
        if (list.size() < MeshReport::kMaxListed) list.push_back(e);
    }
    static void appendExamples(std::vector<Vec3I>& list, const std::vector<Vec3I>& more)
    {
        for (const Vec3I& e : more) addExample(list, e);
    }
    /// Merges the counts of the buckets that follow this range.
    void join(const EdgeCounts& rhs)
    {
        edges += rhs.edges;
        boundary += rhs.boundary;
        nonManifold += rhs.nonManifold;
        inconsistent += rhs.inconsistent;
        appendExamples(boundaryExamples, rhs.boundaryExamples);
        appendExamples(nonManifoldExamples, rhs.nonManifoldExamples);
        appendExamples(inconsistentExamples, rhs.inconsistentExamples);
    }
};

/// Sorts a small range in place (buckets hold a handful of half-edges).
inline void sortSmall(uint64_t* b, uint64_t* e)
{
    if (e - b > 16) {
        std::sort(b, e);
        return;
    }
    for (uint64_t* i = b + 1; i < e; ++i) {
        const uint64_t v = *i;
        uint64_t* j = i;
        while (j > b && *(j - 1) > v) {
            *j = *(j - 1);
            --j;
        }
        *j = v;
    }
}

/// Scans buckets [begin, end). bucketEnd[v] is the end of bucket v; bucket v starts at
/// bucketEnd[v-1] (0 for v = 0). Entries are (other vertex << 1) | (1 if stored hi -> lo).
void scanBuckets(uint32_t begin, uint32_t end, const std::vector<uint64_t>& bucketEnd,
                 std::vector<uint64_t>& entries, EdgeCounts& out)
{
    for (uint32_t v = begin; v < end; ++v) {
        const uint64_t b = v == 0 ? 0 : bucketEnd[v - 1];
        const uint64_t e = bucketEnd[v];
        if (b == e) continue;
        uint64_t* first = entries.data() + b;
        uint64_t* last = entries.data() + e;
        sortSmall(first, last);
        for (uint64_t* run = first; run < last;) {
            const uint64_t other = *run >> 1;
            uint64_t* next = run;
            uint32_t forward = 0, backward = 0;
            while (next < last && (*next >> 1) == other) {
                if (*next & 1) ++backward;
                else ++forward;
                ++next;
            }
            const uint32_t uses = forward + backward;
            const Vec3I edge(v, uint32_t(other), 0);
            ++out.edges;
            if (uses == 1) {
                ++out.boundary;
                EdgeCounts::addExample(out.boundaryExamples, edge);
            } else if (uses >= 3) {
                ++out.nonManifold;
                EdgeCounts::addExample(out.nonManifoldExamples, Vec3I(v, uint32_t(other), uses));
            } else if (forward != 1) { // two uses, same direction
                ++out.inconsistent;
                EdgeCounts::addExample(out.inconsistentExamples, edge);
            }
            run = next;
        }
    }
}

/// Counts pinched vertices in [begin, end): vertices whose link (the graph of the opposite
/// edges of their triangles) has more than one connected component. cornerEnd[v] is the end of
/// v's list of incident triangles in @a incident; it starts at cornerEnd[v-1].
void scanVertexFans(uint32_t begin, uint32_t end, const TriangleMesh& mesh,
                    const std::vector<uint64_t>& cornerEnd, const std::vector<uint32_t>& incident,
                    uint64_t& count, std::vector<uint32_t>& examples)
{
    std::vector<uint32_t> nodes, parent;
    for (uint32_t v = begin; v < end; ++v) {
        const uint64_t b = v == 0 ? 0 : cornerEnd[v - 1];
        const uint64_t e = cornerEnd[v];
        if (e - b < 2) continue;
        nodes.clear();
        for (uint64_t i = b; i < e; ++i) {
            const Vec3I& t = mesh.triangles[incident[i]];
            for (int k = 0; k < 3; ++k) {
                if (t[k] != v) nodes.push_back(t[k]);
            }
        }
        std::sort(nodes.begin(), nodes.end());
        nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
        parent.resize(nodes.size());
        for (uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
        size_t components = nodes.size();
        for (uint64_t i = b; i < e; ++i) {
            const Vec3I& t = mesh.triangles[incident[i]];
            const int k = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
            const auto w1 = std::lower_bound(nodes.begin(), nodes.end(), t[(k + 1) % 3]);
            const auto w2 = std::lower_bound(nodes.begin(), nodes.end(), t[(k + 2) % 3]);
            uint32_t x = uint32_t(w1 - nodes.begin()), y = uint32_t(w2 - nodes.begin());
            while (parent[x] != x) x = parent[x] = parent[parent[x]];
            while (parent[y] != y) y = parent[y] = parent[parent[y]];
            if (x != y) {
                parent[std::max(x, y)] = std::min(x, y);
                --components;
            }
        }
        if (components > 1) {
            ++count;
            if (examples.size() < MeshReport::kMaxListed) examples.push_back(v);
        }
    }
}

inline uint32_t findRoot(std::vector<uint32_t>& parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]]; // path halving
        x = parent[x];
    }
    return x;
}

inline void unite(std::vector<uint32_t>& parent, uint32_t a, uint32_t b)
{
    a = findRoot(parent, a);
    b = findRoot(parent, b);
    if (a == b) return;
    if (a < b) parent[b] = a;
    else parent[a] = b;
}

inline bool collapsed(const Vec3I& t) { return t[0] == t[1] || t[1] == t[2] || t[0] == t[2]; }

} // namespace meshvalidation_internal

bool isDegenerateTriangle(const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    const Vec3d e0 = b - a, e1 = c - a, e2 = c - b;
    const double longest2 = std::max({e0.lengthSqr(), e1.lengthSqr(), e2.lengthSqr()});
    const double twiceArea = e0.cross(e1).length();
    return twiceArea <= MeshReport::kDegenerateRelativeArea * longest2;
}

MeshReport validateMesh(const TriangleMesh& mesh)
{
    using namespace meshvalidation_internal;
    const std::string name = sourceName(mesh);
    MeshReport r;
    r.source = mesh.source;
    r.vertices = mesh.points.size();
    r.triangles = mesh.triangles.size();

    if (mesh.triangles.empty()) throw InvalidMeshError(name + ": no triangles");
    if (mesh.points.size() > size_t(UINT32_MAX)) {
        throw InvalidMeshError(name + ": too many vertices (" + std::to_string(mesh.points.size()) +
            "; at most 2^32-1 can be indexed)");
    }
    const uint32_t nV = uint32_t(mesh.points.size());
    for (uint32_t i = 0; i < nV; ++i) {
        const Vec3d& p = mesh.points[i];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            std::ostringstream s;
            s.precision(17);
            s << name << ": vertex " << i << " has a non-finite coordinate (" << p[0] << ", "
              << p[1] << ", " << p[2] << ")";
            throw InvalidMeshError(s.str());
        }
    }
    const size_t nT = mesh.triangles.size();
    for (size_t t = 0; t < nT; ++t) {
        const Vec3I& tri = mesh.triangles[t];
        for (int k = 0; k < 3; ++k) {
            if (tri[k] >= nV) {
                throw InvalidMeshError(name + ": triangle " + std::to_string(t) + ": vertex index " +
                    std::to_string(tri[k]) + " is out of range (the mesh has " +
                    std::to_string(nV) + " vertices)");
            }
        }
    }

    // Degenerate triangles, used vertices, half-edge counts per smaller vertex.
    std::vector<uint8_t> used(nV, 0);
    std::vector<uint64_t> bucketEnd(size_t(nV) + 1, 0);
    for (size_t t = 0; t < nT; ++t) {
        const Vec3I& tri = mesh.triangles[t];
        used[tri[0]] = used[tri[1]] = used[tri[2]] = 1;
        const bool isCollapsed = collapsed(tri);
        if (isCollapsed || isDegenerateTriangle(mesh.points[tri[0]], mesh.points[tri[1]],
                                                mesh.points[tri[2]])) {
            ++r.degenerateTriangles;
            if (isCollapsed) ++r.collapsedTriangles;
            if (r.degenerateTriangleIds.size() < MeshReport::kMaxListed) {
                r.degenerateTriangleIds.push_back(uint32_t(t));
            }
        }
        if (isCollapsed) continue;
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = tri[k], b = tri[(k + 1) % 3];
            ++bucketEnd[std::min(a, b)];
        }
    }
    for (uint32_t i = 0; i < nV; ++i) r.unusedVertices += used[i] ? 0 : 1;

    // Prefix sums: bucketEnd[v] = start of bucket v; filling advances it to the end of bucket v.
    const uint64_t total = exclusivePrefixSum(bucketEnd, nV);
    std::vector<uint64_t> entries(total);
    for (size_t t = 0; t < nT; ++t) {
        const Vec3I& tri = mesh.triangles[t];
        if (collapsed(tri)) continue;
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = tri[k], b = tri[(k + 1) % 3];
            const uint32_t lo = std::min(a, b), hi = std::max(a, b);
            entries[bucketEnd[lo]++] = (uint64_t(hi) << 1) | (a > b ? 1u : 0u);
        }
    }

    EdgeCounts counts = tbb::parallel_reduce(
        tbb::blocked_range<uint32_t>(0, nV, 4096), EdgeCounts(),
        [&](const tbb::blocked_range<uint32_t>& range, EdgeCounts acc) {
            scanBuckets(range.begin(), range.end(), bucketEnd, entries, acc);
            return acc;
        },
        [](EdgeCounts lhs, const EdgeCounts& rhs) {
            lhs.join(rhs);
            return lhs;
        });
    r.edges = counts.edges;
    r.boundaryEdges = counts.boundary;
    r.nonManifoldEdges = counts.nonManifold;
    r.inconsistentlyOrientedEdges = counts.inconsistent;
    r.boundaryEdgeExamples = std::move(counts.boundaryExamples);
    r.nonManifoldEdgeExamples = std::move(counts.nonManifoldExamples);
    r.inconsistentEdgeExamples = std::move(counts.inconsistentExamples);
    entries.clear();
    entries.shrink_to_fit();

    // Pinched vertices: incident triangles per vertex (counting sort), then each vertex's link.
    std::fill(bucketEnd.begin(), bucketEnd.end(), 0);
    uint64_t corners = 0;
    for (const Vec3I& tri : mesh.triangles) {
        if (collapsed(tri)) continue;
        for (int k = 0; k < 3; ++k) ++bucketEnd[tri[k]];
        corners += 3;
    }
    (void)exclusivePrefixSum(bucketEnd, nV);
    std::vector<uint32_t> incident(corners);
    for (size_t t = 0; t < nT; ++t) {
        const Vec3I& tri = mesh.triangles[t];
        if (collapsed(tri)) continue;
        for (int k = 0; k < 3; ++k) incident[bucketEnd[tri[k]]++] = uint32_t(t);
    }
    using VertexCounts = std::pair<uint64_t, std::vector<uint32_t>>;
    VertexCounts pinched = tbb::parallel_reduce(
        tbb::blocked_range<uint32_t>(0, nV, 4096), VertexCounts(),
        [&](const tbb::blocked_range<uint32_t>& range, VertexCounts acc) {
            scanVertexFans(range.begin(), range.end(), mesh, bucketEnd, incident, acc.first, acc.second);
            return acc;
        },
        [](VertexCounts lhs, const VertexCounts& rhs) {
            lhs.first += rhs.first;
            for (uint32_t v : rhs.second) {
                if (lhs.second.size() < MeshReport::kMaxListed) lhs.second.push_back(v);
            }
            return lhs;
        });
    r.nonManifoldVertices = pinched.first;
    r.nonManifoldVertexIds = std::move(pinched.second);
    incident.clear();
    incident.shrink_to_fit();

    // Components: union-find over vertices through non-collapsed triangles.
    std::vector<uint32_t> parent(nV);
    std::iota(parent.begin(), parent.end(), 0u);
    std::vector<uint8_t> inTriangle(nV, 0);
    for (const Vec3I& tri : mesh.triangles) {
        if (collapsed(tri)) continue;
        inTriangle[tri[0]] = inTriangle[tri[1]] = inTriangle[tri[2]] = 1;
        unite(parent, tri[0], tri[1]);
        unite(parent, tri[1], tri[2]);
    }
    for (uint32_t i = 0; i < nV; ++i) {
        if (inTriangle[i] && findRoot(parent, i) == i) ++r.components;
    }
    return r;
}

std::vector<std::string> MeshReport::findings() const
{
    auto plural = [](uint64_t n, const char* one, const char* many) {
        return std::to_string(n) + " " + (n == 1 ? one : many);
    };
    auto edgeList = [](const std::vector<Vec3I>& list, bool withUses) {
        std::string out;
        for (size_t i = 0; i < list.size(); ++i) {
            out += (i ? ", " : "") + std::to_string(list[i][0]) + "-" + std::to_string(list[i][1]);
            if (withUses) out += " (" + std::to_string(list[i][2]) + " triangles)";
        }
        return out;
    };
    std::vector<std::string> lines;
    if (boundaryEdges) {
        lines.push_back(plural(boundaryEdges, "boundary edge", "boundary edges") +
            " (holes or open borders), e.g. vertices " + edgeList(boundaryEdgeExamples, false));
    }
    if (nonManifoldEdges) {
        lines.push_back(plural(nonManifoldEdges, "non-manifold edge", "non-manifold edges") +
            " (shared by more than two triangles), e.g. vertices " +
            edgeList(nonManifoldEdgeExamples, true));
    }
    if (inconsistentlyOrientedEdges) {
        lines.push_back(plural(inconsistentlyOrientedEdges, "inconsistently oriented edge",
                               "inconsistently oriented edges") +
            " (two triangles wound against each other), e.g. vertices " +
            edgeList(inconsistentEdgeExamples, false));
    }
    if (degenerateTriangles) {
        std::string line = plural(degenerateTriangles, "degenerate (zero-area) triangle",
                                  "degenerate (zero-area) triangles");
        if (collapsedTriangles) {
            line += " (" + std::to_string(collapsedTriangles) + " with a repeated vertex)";
        }
        line += ", e.g. triangle";
        for (size_t i = 0; i < degenerateTriangleIds.size(); ++i) {
            line += (i ? ", " : " ") + std::to_string(degenerateTriangleIds[i]);
        }
        lines.push_back(line);
    }
    if (nonManifoldVertices) {
        std::string line = plural(nonManifoldVertices, "non-manifold (pinched) vertex",
                                  "non-manifold (pinched) vertices") +
            " (surface sheets touching at a single vertex), e.g. vertex";
        for (size_t i = 0; i < nonManifoldVertexIds.size(); ++i) {
            line += (i ? ", " : " ") + std::to_string(nonManifoldVertexIds[i]);
        }
        lines.push_back(line);
    }
    if (unusedVertices) {
        lines.push_back(plural(unusedVertices, "unused vertex", "unused vertices") +
            " (referenced by no triangle)");
    }
    return lines;
}

std::vector<std::string> MeshReport::warnings() const
{
    std::vector<std::string> lines = findings();
    const std::string prefix = (source.empty() ? std::string("<mesh>") : source) + ": ";
    for (std::string& line : lines) line.insert(0, prefix);
    return lines;
}

std::string MeshReport::summary() const
{
    auto plural = [](uint64_t n, const char* one, const char* many) {
        return std::to_string(n) + " " + (n == 1 ? one : many);
    };
    std::string s = (source.empty() ? std::string("<mesh>") : source) + ": " +
        plural(vertices, "vertex", "vertices") + ", " + plural(triangles, "triangle", "triangles") +
        ", " + plural(edges, "edge", "edges") + ", " + plural(components, "component", "components") +
        ": " + (closed() ? "closed (watertight, consistently oriented)" : "NOT closed");
    for (const std::string& line : findings()) s += "\n  " + line;
    return s;
}

TriangleMesh withoutDegenerateTriangles(const TriangleMesh& mesh, uint64_t* removed)
{
    TriangleMesh out;
    out.points = mesh.points;
    out.source = mesh.source;
    out.triangles.reserve(mesh.triangles.size());
    const size_t nV = mesh.points.size();
    out.faceIndex.reserve(mesh.triangles.size());
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        const Vec3I& t = mesh.triangles[i];
        const bool inRange = t[0] < nV && t[1] < nV && t[2] < nV;
        if (inRange && (meshvalidation_internal::collapsed(t) ||
                        isDegenerateTriangle(mesh.points[t[0]], mesh.points[t[1]], mesh.points[t[2]]))) {
            continue;
        }
        out.triangles.push_back(t);
        out.faceIndex.push_back(mesh.sourceFace(i)); // the input face stays known
    }
    if (mesh.faceIndex.empty() && out.triangles.size() == mesh.triangles.size())
        std::vector<uint32_t>().swap(out.faceIndex); // still "triangle i is face i"
    if (removed) *removed = mesh.triangles.size() - out.triangles.size();
    return out;
}

void requireUsableMesh(const TriangleMesh& mesh)
{
    const std::string where = mesh.source.empty() ? std::string("mesh") : mesh.source;
    if (mesh.triangles.empty()) throw InvalidMeshError(where + ": mesh has no triangles");
    const size_t nv = mesh.points.size();
    for (size_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k)
            if (mesh.triangles[t][k] >= nv) {
                std::ostringstream os;
                os << where << ": face " << t << " refers to vertex " << mesh.triangles[t][k]
                   << " but the mesh has " << nv << " vertices";
                throw InvalidMeshError(os.str());
            }
    for (size_t v = 0; v < nv; ++v) {
        const Vec3d& p = mesh.points[v];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            std::ostringstream os;
            os << where << ": vertex " << v << " has a non-finite coordinate (" << p[0] << ", " << p[1]
               << ", " << p[2] << ")";
            throw InvalidMeshError(os.str());
        }
    }
}


} // namespace levelforge
