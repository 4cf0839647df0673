// Microtriangle voxelization (Chang, Cha, Ihm 2008, §3.1, §3.3). See MicrotriangleVoxelizer.h.
#include <levelforge/MicrotriangleVoxelizer.h>

#include <algorithm>
#include <cmath>

namespace levelforge {

namespace voxelizer_internal {

constexpr double kTolerance = 1e-9; // cell units; separation at most this counts as overlap

/// True if [lo, hi] and [-r, r] are separated by more than tol (tol already scaled).
inline bool separated(double lo, double hi, double r, double tol)
{
    return lo > r + tol || hi < -r - tol;
}

inline double cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

/// 2-D overlap of triangle (q0,q1,q2) with the axis-aligned square centred at the origin with
/// half-size 0.5, testing only the three edge normals (the square lies inside the triangle's
/// 2-D bounding box by construction in case 3).
bool overlap2D(const double q[3][2], double tol)
{
    for (int k = 0; k < 3; ++k) {
        const double* s = q[k];
        const double* t = q[(k + 1) % 3];
        const double nx = t[1] - s[1], ny = s[0] - t[0]; // edge normal
        const double len = std::sqrt(nx * nx + ny * ny);
        if (len == 0.0) continue;
        const double p0 = nx * q[0][0] + ny * q[0][1];
        const double p1 = nx * q[1][0] + ny * q[1][1];
        const double p2 = nx * q[2][0] + ny * q[2][1];
        const double lo = std::min({p0, p1, p2}), hi = std::max({p0, p1, p2});
        const double r = 0.5 * (std::abs(nx) + std::abs(ny));
        if (separated(lo, hi, r, tol * len)) return false;
    }
    return true;
}

/// Akenine-Möller test with the vertices already relative to the box centre.
bool overlap3D(const Vec3d& v0, const Vec3d& v1, const Vec3d& v2, const Vec3d& h, double tol,
               bool testBoxAxes)
{
    if (testBoxAxes) {
        for (int i = 0; i < 3; ++i) {
            const double lo = std::min({v0[i], v1[i], v2[i]}), hi = std::max({v0[i], v1[i], v2[i]});
            if (separated(lo, hi, h[i], tol)) return false;
        }
    }
    const Vec3d e[3] = {v1 - v0, v2 - v1, v0 - v2};
    // 9 cross-product axes: unit axis i × edge j.
    for (int j = 0; j < 3; ++j) {
        for (int i = 0; i < 3; ++i) {
            Vec3d axis(0.0);
            // (unit_i × e_j)
            const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
            axis[i1] = -e[j][i2];
            axis[i2] = e[j][i1];
            const double len2 = axis.lengthSqr();
            if (len2 == 0.0) continue;
            const double p0 = axis.dot(v0), p1 = axis.dot(v1), p2 = axis.dot(v2);
            const double lo = std::min({p0, p1, p2}), hi = std::max({p0, p1, p2});
            const double r = h[0] * std::abs(axis[0]) + h[1] * std::abs(axis[1]) + h[2] * std::abs(axis[2]);
            if (separated(lo, hi, r, tol * std::sqrt(len2))) return false;
        }
    }
    // Triangle plane.
    const Vec3d n = e[0].cross(e[1]);
    const double len2 = n.lengthSqr();
    if (len2 > 0.0) {
        const double d = n.dot(v0);
        const double r = h[0] * std::abs(n[0]) + h[1] * std::abs(n[1]) + h[2] * std::abs(n[2]);
        if (separated(d, d, r, tol * std::sqrt(len2))) return false;
    }
    return true;
}

inline openvdb::math::Coord cellOf(const Vec3d& p)
{
    return openvdb::math::Coord(int(std::floor(p[0])), int(std::floor(p[1])), int(std::floor(p[2])));
}

struct Scratch
{
    std::vector<Vec3d> rowA, rowB;
    std::vector<openvdb::math::Coord> cellA, cellB;
};

} // namespace voxelizer_internal

bool triangleBoxOverlap(const Vec3d& center, const Vec3d& half, const Vec3d& a, const Vec3d& b,
                        const Vec3d& c, double tolerance)
{
    return voxelizer_internal::overlap3D(a - center, b - center, c - center, half, tolerance, true);
}

void voxelizeTriangle(const Vec3d& a, const Vec3d& b, const Vec3d& c,
                      std::vector<openvdb::math::Coord>& cells, VoxelizerCounters* counters)
{
    using namespace voxelizer_internal;
    using openvdb::math::Coord;
    thread_local Scratch s;
    VoxelizerCounters local;
    const size_t first = cells.size();

    const Vec3d ab = b - a, ac = c - a, bc = c - b;
    auto infNorm = [](const Vec3d& v) { return std::max({std::abs(v[0]), std::abs(v[1]), std::abs(v[2])}); };
    const double dT = std::max({infNorm(ab), infNorm(bc), infNorm(ac)});
    const int n = dT > 1.0 ? int(std::ceil(dT)) : 1;
    const double inv = 1.0 / double(n);

    auto latticeRow = [&](int j, std::vector<Vec3d>& pts, std::vector<Coord>& cs) {
        const int m = n - j;
        pts.resize(size_t(m) + 1);
        cs.resize(size_t(m) + 1);
        for (int i = 0; i <= m; ++i) {
            // Same formula for every lattice point, so shared vertices are bit-identical.
            const Vec3d p = (i == 0 && j == 0) ? a
                          : (i == n)           ? b
                          : (j == n)           ? c
                          : a + ab * (double(i) * inv) + ac * (double(j) * inv);
            pts[i] = p;
            cs[i] = cellOf(p);
            cells.push_back(cs[i]); // vertex scan
        }
    };

    auto process = [&](const Vec3d& p0, const Coord& c0, const Vec3d& p1, const Coord& c1,
                       const Vec3d& p2, const Coord& c2, bool white) {
        ++local.microtriangles;
        int same[3];
        for (int k = 0; k < 3; ++k) same[k] = (c0[k] == c1[k] && c1[k] == c2[k]) ? 1 : 0;
        const int I = same[0] + same[1] + same[2];
        ++local.cases[3 - I];
        if (I >= 2) return;
        const Coord lo(std::min({c0[0], c1[0], c2[0]}), std::min({c0[1], c1[1], c2[1]}),
                       std::min({c0[2], c1[2], c2[2]}));
        auto isVertexCell = [&](const Coord& q) { return q == c0 || q == c1 || q == c2; };
        if (I == 1) {
            if (!white) return; // its edges were covered by white microtriangles (§3.3)
            const int w = same[0] ? 0 : (same[1] ? 1 : 2);
            const int u = (w + 1) % 3, v = (w + 2) % 3;
            for (int du = 0; du < 2; ++du) {
                for (int dv = 0; dv < 2; ++dv) {
                    Coord q = lo;
                    q[u] += du;
                    q[v] += dv;
                    if (isVertexCell(q)) continue;
                    const double cu = q[u] + 0.5, cv = q[v] + 0.5;
                    const double qq[3][2] = {{p0[u] - cu, p0[v] - cv}, {p1[u] - cu, p1[v] - cv},
                                             {p2[u] - cu, p2[v] - cv}};
                    ++local.boxTests;
                    if (overlap2D(qq, kTolerance)) cells.push_back(q);
                }
            }
            return;
        }
        // I == 0: the 2×2×2 cube.
        const Vec3d half(0.5);
        for (int dz = 0; dz < 2; ++dz)
            for (int dy = 0; dy < 2; ++dy)
                for (int dx = 0; dx < 2; ++dx) {
                    const Coord q = lo.offsetBy(dx, dy, dz);
                    if (isVertexCell(q)) continue;
                    const Vec3d ctr(q[0] + 0.5, q[1] + 0.5, q[2] + 0.5);
                    ++local.boxTests;
                    if (overlap3D(p0 - ctr, p1 - ctr, p2 - ctr, half, kTolerance, false))
                        cells.push_back(q);
                }
    };

    if (n == 1) {
        const Coord ca = cellOf(a), cb = cellOf(b), cc = cellOf(c);
        cells.push_back(ca);
        cells.push_back(cb);
        cells.push_back(cc);
        process(a, ca, b, cb, c, cc, true);
    } else {
        // Row j holds lattice points P(i, j) = a + (i/n) ab + (j/n) ac, i = 0..n-j.
        latticeRow(0, s.rowA, s.cellA);
        // White pass and black pass interleaved per row pair; the order does not change the
        // result (the black ones skip case 3 either way).
        for (int j = 0; j < n; ++j) {
            latticeRow(j + 1, s.rowB, s.cellB);
            const int m = n - j; // row j has m+1 points, row j+1 has m points
            for (int i = 0; i < m; ++i) {
                // white: (i,j), (i+1,j), (i,j+1)
                process(s.rowA[i], s.cellA[i], s.rowA[i + 1], s.cellA[i + 1], s.rowB[i], s.cellB[i], true);
                if (i + 1 < m) {
                    // black: (i+1,j), (i+1,j+1), (i,j+1)
                    process(s.rowA[i + 1], s.cellA[i + 1], s.rowB[i + 1], s.cellB[i + 1], s.rowB[i],
                            s.cellB[i], false);
                }
            }
            std::swap(s.rowA, s.rowB);
            std::swap(s.cellA, s.cellB);
        }
    }

    std::sort(cells.begin() + first, cells.end());
    cells.erase(std::unique(cells.begin() + first, cells.end()), cells.end());
    if (counters) counters->add(local);
}

} // namespace levelforge
