// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/adf/: the reconstruction over an ADF tree, the layout of its cells and
///        the value pipeline shared by the mesh builder and CSG. See AdaptiveDistanceField.h.
#pragma once

#include <levelforge/adf/AdaptiveDistanceField.h>

#include <openvdb/openvdb.h>
#include <openvdb/tree/ValueAccessor.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace levelforge {
namespace adf_internal {

using openvdb::Coord;
using openvdb::CoordBBox;
using FloatTree = openvdb::FloatTree;
using FloatLeaf = FloatTree::LeafNodeType;
using Internal2 = FloatTree::RootNodeType::ChildNodeType;
using Internal1 = Internal2::ChildNodeType;
using LeafMask = FloatLeaf::NodeMaskType;

constexpr uint32_t kNone = 0xffffffffu;
/// Layout version, the value of the meta::kAdf metadata.
constexpr const char* kAdfVersion = "yin2011-vdb-tiles-1";

/// Index into kAdfCellSize, -1 for other sizes.
int levelOfSize(int size);

/// Whether unit cell (or block origin) c lies inside the domain's cells [min, max).
inline bool inDomainCell(const CoordBBox& dom, const Coord& c)
{
    for (int k = 0; k < 3; ++k)
        if (c[k] < dom.min()[k] || c[k] >= dom.max()[k]) return false;
    return true;
}

/// A reconstruction cell: size 1, 2, 4, 8 or 128 (0 = none), minimum corner (index space).
struct CellInfo
{
    int size = 0;
    Coord origin{0, 0, 0};
};

/// The cell holding unit cell c inside a leaf (sizes 1, 2, 4 from the refined-cell mask).
CellInfo cellInLeaf(const FloatLeaf& leaf, const Coord& c);

/// Reads an ADF tree (one per thread: it owns an unregistered accessor).
class Reconstruction
{
public:
    Reconstruction(const FloatTree& tree, const CoordBBox& domain) : mAcc(tree), mDomain(domain) {}

    /// The cell holding unit cell c (c inside the domain's cells [min, max)).
    CellInfo cellAt(const Coord& c);
    /// The stored value at lattice point p, if p is a storage location (leaf voxel or tile origin).
    bool stored(const Coord& p, float& v);
    /// The value of lattice point p: stored, or the trilinear value of the coarse cell it hangs on.
    double value(const Coord& p);
    /// Trilinear value of cell X at q (index space); dvdt = derivative w.r.t. q/size.
    double interp(const CellInfo& X, const Vec3d& q, Vec3d* dvdt);
    /// The reconstruction at any index-space point (clamped to the domain + distance to it).
    double distanceIndex(const Vec3d& q, Vec3d* gradIndex, int* level);

    static double trilinear(const double* v, const Vec3d& t, Vec3d* dvdt);
    static bool subdividedIn(const FloatLeaf& leaf, int x0, int y0, int z0, int n);

    /// Longest chain of value() calls a lattice point can need (cell sizes 1, 2, 4, 8, 128
    /// strictly growing along it; see AdfReconstruction.cc), with room to spare.
    static constexpr int kMaxDepth = 16;

private:
    Coord clampCell(const Coord& p) const;
    double valueAt(const Coord& p, int depth);
    double interpAt(const CellInfo& X, const Vec3d& q, Vec3d* dvdt, int depth);
    openvdb::tree::ValueAccessor<const FloatTree, false> mAcc;
    CoordBBox mDomain;
};

/// Which blocks are leaves (with their refined-cell masks), which 128³ blocks are internal-1
/// nodes and which level-2 tiles; domain = lattice points [min, max], max on 128 multiples.
struct Layout
{
    CoordBBox domain;
    std::vector<Coord> leafOrigins;
    std::vector<LeafMask> leafMasks;
    std::vector<Coord> subdividedL2; ///< input: forced ones; finish() adds the leaves' blocks
    std::vector<Coord> tileL2;       ///< filled by finish()
    /// Sorts and merges leaves, derives the internal-1 nodes and tiles (domain + one storage
    /// layer past its maximum faces).
    void finish();
};

/// The domain of a set of cells: box grown by max(9, padding) voxels, rounded out to 128.
void makeDomain(Layout& layout, const CoordBBox& cellBox, double paddingVoxels);
FloatTree::Ptr createTree(const Layout& layout, float background);

/// Cell sizes inside a leaf from its refined-cell mask (as cellInLeaf, by bit operations):
/// bit q of sub4 / sub2 tells whether 4³ block q / 2³ block q holds an active voxel.
struct LeafCellSizes
{
    uint8_t sub4 = 0;
    uint64_t sub2 = 0;
    LeafCellSizes() = default;
    explicit LeafCellSizes(const LeafMask& m)
    {
        for (int bx = 0; bx < 4; ++bx) {
            const uint64_t w = m.template getWord<uint64_t>(openvdb::Index(2 * bx)) | m.template getWord<uint64_t>(openvdb::Index(2 * bx + 1));
            if (!w) continue;
            for (int by = 0; by < 4; ++by)
                for (int bz = 0; bz < 4; ++bz)
                    if ((w >> (16 * by + 2 * bz)) & 0x303u) {
                        sub2 |= uint64_t(1) << ((bx << 4) | (by << 2) | bz);
                        sub4 |= uint8_t(1u << (((bx >> 1) << 2) | ((by >> 1) << 1) | (bz >> 1)));
                    }
        }
    }
    /// Size of the cell holding local unit cell (x, y, z), x, y, z in [0, 8).
    int size(int x, int y, int z) const
    {
        if (!((sub4 >> (((x >> 2) << 2) | ((y >> 2) << 1) | (z >> 2))) & 1)) return 4;
        if (!((sub2 >> (((x >> 1) << 4) | ((y >> 1) << 2) | (z >> 1))) & 1)) return 2;
        return 1;
    }
    /// Cells of sizes 1, 2 and 4 in the leaf.
    void count(uint64_t& n1, uint64_t& n2, uint64_t& n4) const
    {
        const int s4 = __builtin_popcount(sub4), s2 = __builtin_popcountll(sub2);
        n4 += uint64_t(8 - s4);
        n2 += uint64_t(8 * s4 - s2);
        n1 += uint64_t(8 * s2);
    }
};

/// Source of the free samples.
class SampleProvider
{
public:
    virtual ~SampleProvider() = default;
    /// Fills out[off] for every off with isFree[off] (world units, signed). Called in parallel.
    virtual void leafSamples(size_t leafIndex, FloatLeaf& leaf, const uint8_t* isFree, float* out) = 0;
    /// Called once after all leaves, before the tiles.
    virtual void afterLeaves(FloatTree&) {}
    /// The sample at a free tile origin. Called in parallel.
    virtual double tileSample(const Coord& p) = 0;
};

struct PipelineResult
{
    uint64_t hanging = 0, level1Tiles = 0, level2Tiles = 0;
    std::array<uint64_t, kAdfLevels> cells{};
    double secondsLeaves = 0, secondsTiles = 0, secondsHanging = 0;
};

/// Classifies every storage location of the tree (free corner / hanging / unused), asks the
/// provider for the free samples and resolves the hanging ones, coarsest cells first.
PipelineResult fillValues(FloatTree& tree, const Layout& layout, SampleProvider& provider,
                          openvdb::util::NullInterrupter* interrupter);

/// The metadata key of the stated bound of a level (meta::kAdfBoundLevelPattern).
std::string boundLevelKey(int level);

/// Marks the grid as an ADF: class, layout version, domain, sampling description, the stated
/// bound per level and the generator (the meta:: keys).
void stampAdfMetadata(openvdb::FloatGrid& grid, const CoordBBox& domain,
                      const std::array<double, kAdfLevels>& bounds);

} // namespace adf_internal
} // namespace levelforge
