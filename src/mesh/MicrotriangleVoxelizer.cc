// SPDX-License-Identifier: Apache-2.0
// Microtriangle voxelization (Chang, Cha, Ihm 2008, §3.1, §3.3). See MicrotriangleVoxelizer.h.
#include <levelforge/mesh/MicrotriangleVoxelizer.h>

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
    // Triangle plane first: the cheapest and most often separating axis.
    {
        const Vec3d n = e[0].cross(e[1]);
        const double len2 = n.lengthSqr();
        if (len2 > 0.0) {
            const double d = n.dot(v0);
            const double r = h[0] * std::abs(n[0]) + h[1] * std::abs(n[1]) + h[2] * std::abs(n[2]);
            if (separated(d, d, r, tol * std::sqrt(len2))) return false;
        }
    }
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
    return true;
}

inline openvdb::math::Coord cellOf(const Vec3d& p)
{
    return openvdb::math::Coord(int(std::floor(p[0])), int(std::floor(p[1])), int(std::floor(p[2])));
}

/// Cells already reported for the current triangle: open addressing with generation stamps,
/// so nothing is cleared between triangles and a cell is tested at most once (the paper's
/// "some of the cells may have been marked already while processing adjacent microtriangles").
struct CellSet
{
    std::vector<openvdb::math::Coord> key;
    std::vector<uint32_t> stamp;
    uint32_t gen = 0, count = 0, mask = 0;

    void reset(size_t expected)
    {
        size_t cap = 64;
        while (cap < 2 * expected) cap <<= 1;
        if (key.size() < cap) {
            key.assign(cap, openvdb::math::Coord());
            stamp.assign(cap, 0u);
            gen = 0;
        }
        mask = uint32_t(cap - 1);
        count = 0;
        if (++gen == 0) { std::fill(stamp.begin(), stamp.end(), 0u); gen = 1; }
    }
    static uint32_t hash(const openvdb::math::Coord& c)
    {
        return uint32_t(c.x()) * 73856093u ^ uint32_t(c.y()) * 19349663u ^ uint32_t(c.z()) * 83492791u;
    }
    bool contains(const openvdb::math::Coord& c) const
    {
        for (uint32_t h = hash(c) & mask;; h = (h + 1) & mask) {
            if (stamp[h] != gen) return false;
            if (key[h] == c) return true;
        }
    }
    /// Inserts c; returns true if it was new. Grows when half full.
    bool insert(const openvdb::math::Coord& c)
    {
        if (2 * (count + 1) > mask + 1) grow();
        for (uint32_t h = hash(c) & mask;; h = (h + 1) & mask) {
            if (stamp[h] != gen) { stamp[h] = gen; key[h] = c; ++count; return true; }
            if (key[h] == c) return false;
        }
    }
    void grow()
    {
        std::vector<openvdb::math::Coord> old;
        old.reserve(count);
        for (size_t i = 0; i <= mask; ++i)
            if (stamp[i] == gen) old.push_back(key[i]);
        const size_t cap = 2 * (size_t(mask) + 1);
        key.assign(cap, openvdb::math::Coord());
        stamp.assign(cap, 0u);
        gen = 1;
        mask = uint32_t(cap - 1);
        count = 0;
        for (const auto& c : old) insert(c);
    }
};

struct Scratch
{
    std::vector<Vec3d> lattice;
    std::vector<openvdb::math::Coord> latticeCell;
    CellSet set;
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

    const Vec3d ab = b - a, ac = c - a, bc = c - b;
    auto infNorm = [](const Vec3d& v) { return std::max({std::abs(v[0]), std::abs(v[1]), std::abs(v[2])}); };
    const double dT = std::max({infNorm(ab), infNorm(bc), infNorm(ac)});
    const int n = dT > 1.0 ? int(std::ceil(dT)) : 1;
    const double inv = 1.0 / double(n);

    // Lattice P(i, j) = a + (i/n) ab + (j/n) ac, i + j <= n, stored row by row (row j has n-j+1
    // points). The same formula for every point makes shared vertices bit-identical.
    const size_t nPts = size_t(n + 1) * size_t(n + 2) / 2;
    s.lattice.resize(nPts);
    s.latticeCell.resize(nPts);
    s.set.reset(nPts + 8);
    thread_local std::vector<size_t> rows;
    rows.resize(size_t(n) + 2);
    {
        size_t k = 0;
        for (int j = 0; j <= n; ++j) {
            rows[j] = k;
            for (int i = 0; i <= n - j; ++i, ++k) {
                const Vec3d p = (i == 0 && j == 0) ? a
                              : (i == n)           ? b
                              : (j == n)           ? c
                              : a + ab * (double(i) * inv) + ac * (double(j) * inv);
                s.lattice[k] = p;
                s.latticeCell[k] = cellOf(p);
                // vertex scan: every lattice point's cell holds the triangle
                if (s.set.insert(s.latticeCell[k])) cells.push_back(s.latticeCell[k]);
            }
        }
        rows[n + 1] = k;
    }
    auto at = [&](int i, int j) { return rows[j] + size_t(i); };

    auto process = [&](size_t k0, size_t k1, size_t k2, bool white) {
        const Vec3d &p0 = s.lattice[k0], &p1 = s.lattice[k1], &p2 = s.lattice[k2];
        const Coord &c0 = s.latticeCell[k0], &c1 = s.latticeCell[k1], &c2 = s.latticeCell[k2];
        ++local.microtriangles;
        int same[3];
        for (int k = 0; k < 3; ++k) same[k] = (c0[k] == c1[k] && c1[k] == c2[k]) ? 1 : 0;
        const int I = same[0] + same[1] + same[2];
        ++local.cases[3 - I];
        if (I >= 2) return;
        const Coord lo(std::min({c0[0], c1[0], c2[0]}), std::min({c0[1], c1[1], c2[1]}),
                       std::min({c0[2], c1[2], c2[2]}));
        if (I == 1) {
            if (!white) return; // its edges were covered by white microtriangles (§3.3)
            const int w = same[0] ? 0 : (same[1] ? 1 : 2);
            const int u = (w + 1) % 3, v = (w + 2) % 3;
            for (int du = 0; du < 2; ++du) {
                for (int dv = 0; dv < 2; ++dv) {
                    Coord q = lo;
                    q[u] += du;
                    q[v] += dv;
                    if (s.set.contains(q)) continue; // a vertex cell, or found already
                    const double cu = q[u] + 0.5, cv = q[v] + 0.5;
                    const double qq[3][2] = {{p0[u] - cu, p0[v] - cv}, {p1[u] - cu, p1[v] - cv},
                                             {p2[u] - cu, p2[v] - cv}};
                    ++local.boxTests;
                    if (overlap2D(qq, kTolerance)) { s.set.insert(q); cells.push_back(q); }
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
                    if (s.set.contains(q)) continue;
                    const Vec3d ctr(q[0] + 0.5, q[1] + 0.5, q[2] + 0.5);
                    ++local.boxTests;
                    if (overlap3D(p0 - ctr, p1 - ctr, p2 - ctr, half, kTolerance, false)) {
                        s.set.insert(q);
                        cells.push_back(q);
                    }
                }
    };

    // White microtriangles first, then black ones (which only need case 4), as in §3.3.
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n - j; ++i) process(at(i, j), at(i + 1, j), at(i, j + 1), true);
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n - j; ++i) process(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1), false);

    if (counters) counters->add(local);
}

} // namespace levelforge
