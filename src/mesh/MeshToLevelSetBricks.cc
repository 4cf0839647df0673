// SPDX-License-Identifier: Apache-2.0
// Mesh → exact narrow-band level set: the brick restriction of distributed runs
// (MeshToLevelSetOptions::onlyLeavesIn; distributed/DistributedMeshToSdf.h).
#include <openvdb/openvdb.h>

#include <vector>

namespace levelforge {
namespace meshtols_internal {

using openvdb::Coord;

/// MeshToLevelSetOptions::onlyLeavesIn at leaf resolution (coordinate = leaf origin / 8): the
/// leaves whose origin lies in one of the boxes, as active tiles and voxels.
void leafBoxMask(const std::vector<openvdb::CoordBBox>& boxes, openvdb::MaskTree& mask)
{
    for (const openvdb::CoordBBox& b : boxes) {
        if (b.empty()) continue;
        const openvdb::Coord lo(b.min().x() >> 3, b.min().y() >> 3, b.min().z() >> 3);
        // the leaves whose origin (a multiple of 8) is at most b.max()
        const openvdb::Coord hi(b.max().x() >> 3, b.max().y() >> 3, b.max().z() >> 3);
        const openvdb::CoordBBox leaves(lo + openvdb::Coord((b.min().x() & 7) ? 1 : 0, (b.min().y() & 7) ? 1 : 0,
                                                            (b.min().z() & 7) ? 1 : 0), hi);
        if (!leaves.empty()) mask.fill(leaves, true, true);
    }
}

/// True when the leaf-resolution box @p q meets an active entry of @p mask.
bool meetsLeafBoxMask(const openvdb::MaskTree& mask, const openvdb::CoordBBox& q)
{
    if (q.volume() <= 512) {
        openvdb::tree::ValueAccessor<const openvdb::MaskTree> acc(mask);
        for (int x = q.min().x(); x <= q.max().x(); ++x)
            for (int y = q.min().y(); y <= q.max().y(); ++y)
                for (int z = q.min().z(); z <= q.max().z(); ++z)
                    if (acc.isValueOn(Coord(x, y, z))) return true;
        return false;
    }
    for (auto it = mask.cbeginValueOn(); it; ++it)
        if (it.getBoundingBox().hasOverlap(q)) return true;
    return false;
}

} // namespace meshtols_internal
} // namespace levelforge
