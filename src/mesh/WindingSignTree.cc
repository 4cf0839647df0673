// SPDX-License-Identifier: Apache-2.0
// The winding-number signing of a level set's inactive region (see signInactiveByWindingNumber()
// in mesh/FastWindingNumber.h): segment crossings, the tile pass over the VDB nodes with
// first-order models, and the fill of the interior.
#include <levelforge/mesh/FastWindingNumber.h>

#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>

#include <openvdb/tree/LeafManager.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <vector>

namespace levelforge {


// ==================================================================== signing inactive regions
namespace winding_internal {

bool crossingChange(const FastWindingNumber& fwn, const std::vector<uint32_t>& tris, const Vec3d& P, const Vec3d& Q,
                    int& change)
{
    constexpr double kRel = 1e-10;
    change = 0;
    const Vec3d D = Q - P;
    const double lenD = D.length();
    for (uint32_t i : tris) {
        const double* t = FastWindingNumberAccess::triangle(fwn, i);
        const Vec3d a(t), b(t + 3), c(t + 6);
        bool miss = false;
        for (int k = 0; k < 3 && !miss; ++k)
            miss = std::max(P[k], Q[k]) < std::min({a[k], b[k], c[k]}) || std::min(P[k], Q[k]) > std::max({a[k], b[k], c[k]});
        if (miss) continue;
        const Vec3d n = (b - a).cross(c - a);
        const double ln = n.length();
        const Vec3d pa = P - a, qa = Q - a;
        const double sp = n.dot(pa), sq = n.dot(qa);
        const double tolP = kRel * ln * (pa.length() + (b - a).length() + (c - a).length());
        const double tolQ = kRel * ln * (qa.length() + (b - a).length() + (c - a).length());
        if ((sp > tolP && sq > tolQ) || (sp < -tolP && sq < -tolQ)) continue; // both on one side
        // the line P→Q against the three edges
        const Vec3d va = a - P, vb = b - P, vc = c - P;
        const double la = va.length(), lb = vb.length(), lc = vc.length();
        const double e0 = D.dot(va.cross(vb)), e1 = D.dot(vb.cross(vc)), e2 = D.dot(vc.cross(va));
        const double t0 = kRel * lenD * la * lb, t1 = kRel * lenD * lb * lc, t2 = kRel * lenD * lc * la;
        const bool pos = e0 > t0 && e1 > t1 && e2 > t2, neg = e0 < -t0 && e1 < -t1 && e2 < -t2;
        const bool outside = (e0 > t0 || e1 > t1 || e2 > t2) && (e0 < -t0 || e1 < -t1 || e2 < -t2);
        if (outside) continue;                // the line passes clearly beside the triangle
        if (!pos && !neg) return false;       // near an edge or a vertex
        if (std::abs(sp) <= tolP || std::abs(sq) <= tolQ) return false; // ends in its plane
        change += sp > 0.0 ? 1 : -1;          // front to back: w grows by one
    }
    return true;
}

using openvdb::Coord;
using openvdb::CoordBBox;
using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using RootT = FloatTree::RootNodeType;
using Node2 = RootT::ChildNodeType;
using Node1 = Node2::ChildNodeType;

namespace {

constexpr double kSqrt3 = 1.7320508075688772;

/// What the tile pass needs: the transform (voxel centres at integer index coordinates), the
/// fast winding number and its bounds in voxel units.
/// Polls the interrupter by work done (once per kEvaluationsPerPoll winding evaluations of all
/// threads together); once it says stop, the pass returns without finishing and signTree() throws.
struct TilePoller
{
    static constexpr uint64_t kEvaluationsPerPoll = 4096;
    openvdb::util::NullInterrupter* interrupter = nullptr;
    mutable std::atomic<uint64_t> work{0}, polls{0};
    mutable std::atomic<bool> stop{false};

    void report(WindingSignStats& st, uint64_t& reported) const
    {
        if (!interrupter) return;
        const uint64_t delta = st.evaluations - reported;
        if (delta == 0) return;
        reported = st.evaluations;
        const uint64_t owed = (work.fetch_add(delta, std::memory_order_relaxed) + delta) / kEvaluationsPerPoll;
        uint64_t p = polls.load(std::memory_order_relaxed);
        while (p < owed)
            if (polls.compare_exchange_weak(p, p + 1, std::memory_order_relaxed)) {
                poll();
                ++p;
            }
    }
    bool stopped() const { return stop.load(std::memory_order_relaxed); }
    /// One poll (also made between the passes, whatever the work done). 97 %: the finish of a
    /// conversion whose distances took 20-95 %.
    void poll() const
    {
        if (interrupter && interrupter->wasInterrupted(97)) stop.store(true, std::memory_order_relaxed);
    }
};

struct Signer
{
    const openvdb::math::Transform& xform;
    const FastWindingNumber& fwn;
    double h; // voxel size, world units
    bool hasCurrents;
    const TilePoller& poller;

    Vec3d world(const Vec3d& index) const { return xform.indexToWorld(index); }
    /// Bound of |∇w| over the index-space box [lo, hi], per voxel.
    double gradient(const Vec3d& lo, const Vec3d& hi) const
    {
        if (!hasCurrents) return 0.0;
        const BBoxd wb = xform.indexToWorld(BBoxd(lo, hi));
        return fwn.gradientBound(wb.min(), wb.max()) * h;
    }
    double estimate(const Vec3d& index, WindingSignStats& st) const
    {
        ++st.evaluations;
        return fwn(world(index));
    }
};

/// A first-order model of w about the centre c of a surface-free cube (index space):
/// w(x) = w + B·(x − c) ± (kWindingTolerance + ½ |x − c|² H + Be |x − c|), B, Be and H per
/// voxel (B the fast gradient, Be its error bound).
struct Model
{
    Vec3d c;
    double w = 0.0;
    Vec3d B{0.0};
    double Be = 0.0; // bound of |B − ∇w(c)| (the far edges' approximation), per voxel
    double H = 0.0;

    int at(const Vec3d& x) const
    {
        const Vec3d d = x - c;
        const double d2 = d.lengthSqr();
        return decide(w + B.dot(d), 0.5 * d2 * H + Be * std::sqrt(d2));
    }
    /// The verdict for every voxel centre of the cube of `size` voxels centred at c.
    int uniform(int size) const
    {
        const double half = 0.5 * (size - 1);
        const double lin = half * (std::abs(B[0]) + std::abs(B[1]) + std::abs(B[2]) + kSqrt3 * Be);
        return decide(w, lin + 0.5 * 3.0 * half * half * H);
    }
};

Model modelOf(const Signer& s, const Coord& o, int size, WindingSignStats& st)
{
    Model m;
    const double half = 0.5 * (size - 1);
    m.c = Vec3d(o.x() + half, o.y() + half, o.z() + half);
    m.w = s.estimate(m.c, st);
    if (s.hasCurrents) {
        double be = 0.0;
        m.B = s.fwn.gradient(s.world(m.c), be) * s.h;
        m.Be = be * s.h;
        const BBoxd wb = s.xform.indexToWorld(BBoxd(Vec3d(o.x() - 0.5, o.y() - 0.5, o.z() - 0.5),
                                                     Vec3d(o.x() + size - 0.5, o.y() + size - 0.5, o.z() + size - 0.5)));
        m.H = s.fwn.hessianBound(wb.min(), wb.max()) * s.h * s.h;
    }
    return m;
}

/// Signs the voxels `cells` (index coordinates) of the surface-free cube [o, o + size)³ into
/// inside[] (offsets of the 8³ leaf at leafOrigin): a first-order model at the cube's centre
/// decides what it can; where it cannot (a boundary edge close by: the Hessian bound is large)
/// and more than kSplitVoxels voxels are left, the cube is halved and each half that holds some
/// of them gets a model of its own (the models' error falls with the square of the size);
/// what is left is evaluated voxel by voxel, in one traversal.
constexpr size_t kSplitVoxels = 16;

void modelCells(const Signer& s, const Coord& o, int size, std::vector<Coord>& cells, const Coord& leafOrigin,
                uint8_t* inside, WindingSignStats& st)
{
    const auto put = [&](const Coord& c, bool in) {
        const Coord l = c - leafOrigin;
        inside[(l.x() << 6) | (l.y() << 3) | l.z()] = uint8_t(in ? 1 : 0);
    };
    const auto split = [&](std::vector<Coord>& list) {
        const int half = size / 2;
        std::vector<Coord> part;
        for (int i = 0; i < 8; ++i) {
            const Coord so = o + Coord((i >> 2) * half, ((i >> 1) & 1) * half, (i & 1) * half);
            part.clear();
            for (const Coord& c : list)
                if (c.x() - so.x() >= 0 && c.x() - so.x() < half && c.y() - so.y() >= 0 && c.y() - so.y() < half &&
                    c.z() - so.z() >= 0 && c.z() - so.z() < half)
                    part.push_back(c);
            if (!part.empty()) modelCells(s, so, half, part, leafOrigin, inside, st);
        }
    };
    const Model m = modelOf(s, o, size, st);
    const bool finite = std::isfinite(m.H);
    if (!finite && size > 1) { split(cells); return; }
    const int u = finite ? m.uniform(size) : -1;
    std::vector<Coord> rest; // undecided
    for (const Coord& c : cells) {
        const int v = u >= 0 ? u : (size == 1 ? (insideByEstimate(m.w) ? 1 : 0) : (finite ? m.at(Vec3d(c.x(), c.y(), c.z())) : -1));
        if (v < 0) rest.push_back(c);
        else put(c, v == 1);
    }
    if (rest.empty()) return;
    if (size > 2 && rest.size() > kSplitVoxels) { split(rest); return; }
    std::vector<Vec3d> pts(rest.size());
    std::vector<double> w(rest.size());
    for (size_t i = 0; i < rest.size(); ++i) pts[i] = s.world(Vec3d(rest[i].x(), rest[i].y(), rest[i].z()));
    s.fwn.evaluate(pts.data(), pts.size(), w.data());
    st.evaluations += rest.size();
    st.individual += rest.size();
    for (size_t i = 0; i < rest.size(); ++i) put(rest[i], insideByEstimate(w[i]));
}

/// Signs every voxel of the surface-free cube [o, o + size)³ (size <= 8) into inside[] (see
/// modelCells()).
void modelVoxels(const Signer& s, const Coord& o, int size, const Coord& leafOrigin, uint8_t* inside, WindingSignStats& st)
{
    std::vector<Coord> cells;
    cells.reserve(size_t(size) * size * size);
    for (int x = 0; x < size; ++x)
        for (int y = 0; y < size; ++y)
            for (int z = 0; z < size; ++z) cells.push_back(o + Coord(x, y, z));
    modelCells(s, o, size, cells, leafOrigin, inside, st);
}

/// Where a node's tiles are set: uniform cubes (a whole number of tiles, or part of one tile
/// of a Node2, which then gets a Node1 child) and leaves.
template<typename NodeT>
struct TileSetter
{
    NodeT& node;
    float bg;
    WindingSignStats& st;
    uint64_t& reported; // evaluations handed to the poller

    void cube(const Coord& o, int size, bool inside)
    {
        constexpr int tile = int(NodeT::ChildNodeType::DIM);
        const float v = inside ? -bg : bg;
        if (size >= tile) {
            for (int x = 0; x < size; x += tile)
                for (int y = 0; y < size; y += tile)
                    for (int z = 0; z < size; z += tile) {
                        const openvdb::Index i = NodeT::coordToOffset(o + Coord(x, y, z));
                        node.addTile(i, v, node.isValueMaskOn(i));
                        if (inside) ++st.insideTiles;
                    }
            return;
        }
        // inside one tile of a Node2: Node1 tiles of 8³ (the Node1 is made on the first)
        for (int x = 0; x < size; x += 8)
            for (int y = 0; y < size; y += 8)
                for (int z = 0; z < size; z += 8) {
                    node.addTile(1, o + Coord(x, y, z), v, false);
                    if (inside) ++st.insideTiles;
                }
    }
    void leaf(const Coord& o, const uint8_t* inside)
    {
        bool mixed = false;
        for (int k = 1; k < 512; ++k) mixed = mixed || inside[k] != inside[0];
        if (!mixed) { cube(o, 8, inside[0] != 0); return; }
        auto* leaf = new LeafT(o, bg, false);
        for (int k = 0; k < 512; ++k) {
            leaf->setValueOnly(openvdb::Index(k), inside[k] ? -bg : bg);
            if (inside[k]) ++st.insideVoxels;
        }
        node.addLeaf(leaf);
        ++st.leavesCreated;
    }
};

/// Signs the undecided tiles of a node within the cube [o, o + size)³ by first-order models:
/// a cube with a child (band leaves, surface) is halved; a surface-free cube with undecided
/// tiles gets a model at its centre, set whole if the model decides it, halved otherwise; an
/// 8³ cube is decided voxel by voxel (modelVoxels()).
template<typename NodeT>
void modelCubes(const Signer& s, TileSetter<NodeT>& set, const std::vector<uint8_t>& slot, const Coord& o, int size)
{
    constexpr int tile = int(NodeT::ChildNodeType::DIM);
    s.poller.report(set.st, set.reported);
    if (s.poller.stopped()) return;
    if (size >= tile) {
        bool undecided = false, child = false;
        for (int x = 0; x < size && !(undecided && child); x += tile)
            for (int y = 0; y < size; y += tile)
                for (int z = 0; z < size; z += tile) {
                    const uint8_t st = slot[NodeT::coordToOffset(o + Coord(x, y, z))];
                    undecided = undecided || st == 1;
                    child = child || st == 0;
                }
        if (!undecided) return;
        if (child) {
            const int half = size / 2;
            for (int i = 0; i < 8; ++i)
                modelCubes(s, set, slot, o + Coord((i >> 2) * half, ((i >> 1) & 1) * half, (i & 1) * half), half);
            return;
        }
    }
    if (size == 8) {
        uint8_t inside[512];
        modelVoxels(s, o, 8, o, inside, set.st);
        set.leaf(o, inside);
        return;
    }
    const Model m = modelOf(s, o, size, set.st);
    const int v = std::isfinite(m.H) ? m.uniform(size) : -1;
    if (v >= 0) {
        if (size >= tile) {
            // only the undecided tiles (the decided ones agree)
            for (int x = 0; x < size; x += tile)
                for (int y = 0; y < size; y += tile)
                    for (int z = 0; z < size; z += tile)
                        if (slot[NodeT::coordToOffset(o + Coord(x, y, z))] == 1) set.cube(o + Coord(x, y, z), tile, v == 1);
        } else {
            set.cube(o, size, v == 1);
        }
        return;
    }
    ++set.st.individual;
    const int half = size / 2;
    for (int i = 0; i < 8; ++i)
        modelCubes(s, set, slot, o + Coord((i >> 2) * half, ((i >> 1) & 1) * half, (i & 1) * half), half);
}

struct Scratch
{
    WindingSignStats st;
    uint64_t reported = 0; // st.evaluations handed to the poller
    std::vector<uint8_t> member, slot;
    std::vector<int32_t> hops;
    std::vector<uint32_t> order;
};

/// Signs the tiles of an internal node (Node1 or Node2): face-connected groups of tiles (no
/// surface between them) from one estimate each, carried with the node's gradient bound times
/// the hops (for a mesh without boundary current, exactly: w is constant there); the tiles this
/// leaves undecided by first-order models (modelCubes()).
template<typename NodeT>
void signNodeTiles(const Signer& s, NodeT& node, float bg, Scratch& sc)
{
    constexpr int log2n = NodeT::LOG2DIM;
    constexpr uint32_t n3 = NodeT::NUM_VALUES;
    const int tile = int(NodeT::ChildNodeType::DIM);
    sc.member.assign(n3, 0);
    sc.hops.assign(n3, -1);
    sc.slot.assign(n3, 0); // 0 child, 1 undecided tile, 2 decided tile
    bool any = false;
    for (uint32_t i = 0; i < n3; ++i)
        if (!node.isChildMaskOn(i)) { sc.member[i] = 1; sc.slot[i] = 1; any = true; }
    if (!any) return;
    const Coord o = node.origin();
    const double g = s.gradient(Vec3d(o.x() - 0.5, o.y() - 0.5, o.z() - 0.5),
                                Vec3d(o.x() + NodeT::DIM - 0.5, o.y() + NodeT::DIM - 0.5, o.z() + NodeT::DIM - 0.5));
    const double inner = 0.5 * (tile - 1) * kSqrt3; // tile centre to its farthest voxel
    bool undecided = false;
    for (uint32_t start = 0; start < n3; ++start) {
        if (!sc.member[start] || sc.hops[start] >= 0) continue;
        bfs(log2n, start, sc.member.data(), [](uint32_t, uint32_t) { return true; }, sc.hops.data(), sc.order);
        ++sc.st.components;
        const Coord rep = node.offsetToGlobalCoord(start);
        const double half = 0.5 * (tile - 1);
        const double w = s.estimate(Vec3d(rep.x() + half, rep.y() + half, rep.z() + half), sc.st);
        if (!std::isfinite(g)) { undecided = true; continue; }
        for (uint32_t i : sc.order) {
            const int v = decide(w, g * (double(sc.hops[i]) * tile + inner));
            if (v < 0) { undecided = true; continue; }
            node.addTile(i, v == 1 ? -bg : bg, node.isValueMaskOn(i));
            if (v == 1) ++sc.st.insideTiles;
            sc.slot[i] = 2;
        }
    }
    s.poller.report(sc.st, sc.reported);
    if (!undecided || s.poller.stopped()) return;
    TileSetter<NodeT> set{node, bg, sc.st, sc.reported};
    modelCubes(s, set, sc.slot, o, int(NodeT::DIM));
}

/// Signs a leaf's voxels with |φ| >= exactBand and its inactive voxels: groups of them (all
/// adjacent ones are joined: none is within 1 voxel of the surface) from one estimate each,
/// carried with the leaf's gradient bound; each voxel this leaves undecided from a model at
/// it (its own estimate).
void signLeaf(const Signer& s, LeafT& leaf, double exactBand, Scratch& sc)
{
    sc.member.assign(512, 0);
    sc.hops.assign(512, -1);
    bool any = false;
    for (openvdb::Index i = 0; i < 512; ++i) {
        const float v = leaf.getValue(i);
        if (!leaf.isValueOn(i) || std::abs(double(v)) >= exactBand) { sc.member[i] = 1; any = true; }
    }
    if (!any) return;
    const Coord o = leaf.origin();
    const double g = s.gradient(Vec3d(o.x() - 0.5, o.y() - 0.5, o.z() - 0.5), Vec3d(o.x() + 7.5, o.y() + 7.5, o.z() + 7.5));
    const auto set = [&](uint32_t i, int v) {
        const float a = std::abs(leaf.getValue(i));
        leaf.setValueOnly(i, v == 1 ? -a : a);
        if (v == 1 && !leaf.isValueOn(i)) ++sc.st.insideVoxels;
    };
    for (uint32_t start = 0; start < 512; ++start) {
        if (!sc.member[start] || sc.hops[start] >= 0) continue;
        bfs(3, start, sc.member.data(), [](uint32_t, uint32_t) { return true; }, sc.hops.data(), sc.order);
        ++sc.st.components;
        const Coord rep = leaf.offsetToGlobalCoord(start);
        const double w = s.estimate(Vec3d(rep.x(), rep.y(), rep.z()), sc.st);
        for (uint32_t i : sc.order) {
            int v = i == start ? (insideByEstimate(w) ? 1 : 0)
                               : (std::isfinite(g) ? decide(w, g * double(sc.hops[i])) : -1);
            if (v < 0) {
                ++sc.st.individual;
                const Coord c = leaf.offsetToGlobalCoord(i);
                v = insideByEstimate(s.estimate(Vec3d(c.x(), c.y(), c.z()), sc.st)) ? 1 : 0;
            }
            set(i, v);
        }
    }
    s.poller.report(sc.st, sc.reported);
}

void add(WindingSignStats& a, const WindingSignStats& b)
{
    a.evaluations += b.evaluations;
    a.components += b.components;
    a.individual += b.individual;
    a.insideTiles += b.insideTiles;
    a.insideVoxels += b.insideVoxels;
    a.leavesCreated += b.leavesCreated;
}

} // namespace

void signTree(FloatTree& tree, const openvdb::math::Transform& xform, const FastWindingNumber& fwn,
              const BBoxd& meshBounds, bool leavesToo, double exactBand, WindingSignStats& stats,
              openvdb::util::NullInterrupter* interrupter)
{
    const float bg = std::abs(tree.background());
    TilePoller poller;
    poller.interrupter = interrupter;
    const Signer s{xform, fwn, xform.voxelSize()[0], fwn.currentEdges() > 0, poller};
    const auto checkStop = [&] {
        poller.poll();
        if (poller.stopped()) throw InterruptedError("interrupted while signing by the winding number");
    };
    checkStop();
    tbb::enumerable_thread_specific<Scratch> tls;

    // leaves (their values with |φ| >= exactBand and their inactive voxels)
    if (leavesToo) {
        std::vector<LeafT*> leaves;
        tree.getNodes(leaves);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
            Scratch& sc = tls.local();
            for (size_t i = r.begin(); i != r.end() && !poller.stopped(); ++i) signLeaf(s, *leaves[i], exactBand, sc);
        });
        checkStop();
    }
    // the tiles of the existing Node1s, then of the existing Node2s (whose split tiles get
    // Node1 children signed on the spot)
    {
        std::vector<Node1*> n1;
        tree.getNodes(n1);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n1.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
            Scratch& sc = tls.local();
            for (size_t i = r.begin(); i != r.end() && !poller.stopped(); ++i) signNodeTiles(s, *n1[i], bg, sc);
        });
        checkStop();
        std::vector<Node2*> n2;
        tree.getNodes(n2);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n2.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
            Scratch& sc = tls.local();
            for (size_t i = r.begin(); i != r.end() && !poller.stopped(); ++i) signNodeTiles(s, *n2[i], bg, sc);
        });
        checkStop();
    }
    // root: regions of the mesh's bounding box without a node (no surface there): a model at
    // the centre; undecided: a Node2 of undecided tiles, signed on the spot
    {
        Scratch& sc = tls.local();
        const BBoxd ib = xform.worldToIndex(meshBounds);
        const Coord lo = Coord::floor(ib.min()) - Coord(1), hi = Coord::ceil(ib.max()) + Coord(1);
        constexpr int D = int(Node2::DIM);
        const auto key = [](int v) { return int(std::floor(double(v) / D)) * D; };
        for (int x = key(lo.x()); x <= hi.x(); x += D)
            for (int y = key(lo.y()); y <= hi.y(); y += D)
                for (int z = key(lo.z()); z <= hi.z(); z += D) {
                    const Coord c(x, y, z);
                    const int depth = tree.getValueDepth(c); // -1: nothing there; 0: a root tile
                    if (depth > 0) continue;
                    ++sc.st.components;
                    const Model m = modelOf(s, c, D, sc.st);
                    const int v = std::isfinite(m.H) ? m.uniform(D) : -1;
                    if (v == 1) {
                        tree.root().addTile(c, -bg, false);
                        ++sc.st.insideTiles;
                    } else if (v == 0) {
                        if (depth == 0) tree.root().addTile(c, bg, false);
                    } else {
                        tree.addTile(Node2::LEVEL, c, bg, false); // a Node2 of undecided tiles
                        Node2* node = tree.root().probeNode<Node2>(c);
                        if (node) signNodeTiles(s, *node, bg, sc);
                        checkStop();
                    }
                }
    }
    for (const Scratch& sc : tls) add(stats, sc.st);
}


std::unique_ptr<FastWindingNumber> signingWindingNumber(const TriangleMesh& mesh, const FastWindingNumberOptions& options,
                                                        int64_t& leftOut)
{
    leftOut = -1;
    auto fwn = std::make_unique<FastWindingNumber>(mesh, options);
    if (fwn->currentEdges() != 3 || mesh.triangles.size() < 2) return fwn;
    // the three current edges, each with |I| = 1, forming a triangle's boundary
    using Key = std::array<double, 3>;
    const auto key = [](const Vec3d& p) { return Key{p[0], p[1], p[2]}; };
    std::array<std::pair<Key, Key>, 3> current; // directed by the sign of the current
    for (size_t i = 0; i < 3; ++i) {
        Vec3d a, b;
        double I = 0.0;
        FastWindingNumberAccess::currentEdge(*fwn, i, a, b, I);
        if (std::abs(I) != 1.0) return fwn;
        current[i] = I > 0.0 ? std::make_pair(key(a), key(b)) : std::make_pair(key(b), key(a));
    }
    std::sort(current.begin(), current.end());
    // the vertices of the loop: a triangle of the mesh with exactly these corners, in this
    // orientation, is the candidate (one with the opposite orientation would be a hole's mirror)
    int64_t found = -1;
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const Vec3I& tri = mesh.triangles[t];
        std::array<std::pair<Key, Key>, 3> edges;
        for (int k = 0; k < 3; ++k)
            edges[k] = std::make_pair(key(mesh.points[tri[k]]), key(mesh.points[tri[(k + 1) % 3]]));
        std::sort(edges.begin(), edges.end());
        if (edges != current) continue;
        if (found >= 0) return fwn; // two such triangles: not this case
        found = int64_t(t);
    }
    if (found < 0) return fwn;
    TriangleMesh rest;
    rest.points = mesh.points;
    rest.source = mesh.source;
    rest.triangles.reserve(mesh.triangles.size() - 1);
    for (size_t t = 0; t < mesh.triangles.size(); ++t)
        if (int64_t(t) != found) rest.triangles.push_back(mesh.triangles[t]);
    auto without = std::make_unique<FastWindingNumber>(rest, options);
    if (without->currentEdges() != 0) return fwn;
    leftOut = found;
    return without;
}

namespace {
template<typename NodeT>
uint64_t activateNodeTiles(NodeT& node)
{
    uint64_t n = 0;
    for (openvdb::Index i = 0; i < NodeT::NUM_VALUES; ++i) {
        if (node.isChildMaskOn(i) || node.isValueMaskOn(i)) continue;
        const float v = node.getValue(node.offsetToGlobalCoord(i));
        if (!(v < 0.0f)) continue;
        node.addTile(i, v, true);
        n += uint64_t(NodeT::ChildNodeType::NUM_VOXELS);
    }
    return n;
}
} // namespace

uint64_t activateInterior(FloatTree& tree)
{
    std::atomic<uint64_t> count{0};
    openvdb::tree::LeafManager<FloatTree> leaves(tree);
    leaves.foreach([&](LeafT& leaf, size_t) {
        uint64_t n = 0;
        for (auto it = leaf.beginValueOff(); it; ++it)
            if (*it < 0.0f) { it.setValueOn(); ++n; }
        count.fetch_add(n, std::memory_order_relaxed);
    });
    std::vector<Node1*> n1;
    std::vector<Node2*> n2;
    tree.getNodes(n1);
    tree.getNodes(n2);
    uint64_t tiles = 0;
    for (Node1* n : n1) tiles += activateNodeTiles(*n);
    for (Node2* n : n2) tiles += activateNodeTiles(*n);
    for (auto it = tree.root().beginValueOff(); it; ++it) {
        if (*it < 0.0f) {
            it.setValueOn();
            tiles += uint64_t(Node2::NUM_VOXELS);
        }
    }
    return count.load() + tiles;
}

} // namespace winding_internal

void signInactiveByWindingNumber(openvdb::FloatGrid& grid, const FastWindingNumber& fwn, const BBoxd& meshBounds,
                                 WindingSignStats* statsOut, openvdb::util::NullInterrupter* interrupter)
{
    if (!grid.hasUniformVoxels()) throw InvalidArgumentError("signInactiveByWindingNumber: the grid's voxels are not cubes");
    WindingSignStats st;
    winding_internal::signTree(grid.tree(), grid.transform(), fwn, meshBounds, true,
                               std::numeric_limits<double>::infinity(), st, interrupter);
    if (statsOut) *statsOut = st;
}

} // namespace levelforge
