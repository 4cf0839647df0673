// SPDX-License-Identifier: Apache-2.0
// Bit-for-bit comparison of two float grids: the same tree (leaves with the same value bits and
// active states, the same tiles at the same levels), the same transform, class, name, background
// and grid metadata. Used by the distributed tests (in-process and under mpirun).
#pragma once

#include <openvdb/openvdb.h>

#include <cstring>
#include <sstream>
#include <string>

namespace levelforge_test {

/// "" when @p a and @p b are identical, else the first difference found.
inline std::string gridDifference(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b)
{
    std::ostringstream os;
    auto bits = [](float v) { uint32_t u; std::memcpy(&u, &v, 4); return u; };
    if (a.getName() != b.getName()) return "names differ: " + a.getName() + " vs " + b.getName();
    if (a.getGridClass() != b.getGridClass()) return "grid classes differ";
    if (a.transform() != b.transform()) return "transforms differ";
    if (bits(a.background()) != bits(b.background())) return "backgrounds differ";
    // grid metadata (every entry, by its text)
    std::ostringstream ma, mb;
    for (auto it = a.beginMeta(); it != a.endMeta(); ++it) ma << it->first << "=" << it->second->str() << ";";
    for (auto it = b.beginMeta(); it != b.endMeta(); ++it) mb << it->first << "=" << it->second->str() << ";";
    if (ma.str() != mb.str()) return "metadata differ: " + ma.str() + " vs " + mb.str();
    const openvdb::FloatTree &ta = a.tree(), &tb = b.tree();
    if (ta.nodeCount() != tb.nodeCount()) return "node counts differ";
    if (ta.activeVoxelCount() != tb.activeVoxelCount()) {
        os << "active voxel counts differ: " << ta.activeVoxelCount() << " vs " << tb.activeVoxelCount();
        return os.str();
    }
    for (auto it = ta.cbeginLeaf(); it; ++it) {
        const auto* lb = tb.probeConstLeaf(it->origin());
        if (!lb) { os << "leaf " << it->origin() << " missing in the second grid"; return os.str(); }
        if (it->getValueMask() != lb->getValueMask()) { os << "active states differ in leaf " << it->origin(); return os.str(); }
        for (openvdb::Index i = 0; i < openvdb::FloatTree::LeafNodeType::SIZE; ++i)
            if (bits(it->getValue(i)) != bits(lb->getValue(i))) {
                os << "values differ at " << it->offsetToGlobalCoord(i) << ": " << it->getValue(i) << " vs "
                   << lb->getValue(i);
                return os.str();
            }
    }
    // tiles (every level), both ways
    for (int pass = 0; pass < 2; ++pass) {
        const openvdb::FloatTree& x = pass ? tb : ta;
        const openvdb::FloatTree& y = pass ? ta : tb;
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(y);
        for (auto it = x.cbeginValueAll(); it; ++it) {
            if (it.isVoxelValue()) continue;
            const openvdb::Coord c = it.getCoord();
            if (acc.getValueDepth(c) != int(it.getDepth()) || bits(acc.getValue(c)) != bits(*it) ||
                acc.isValueOn(c) != it.isValueOn()) {
                os << "tiles differ at " << c << " (depth " << it.getDepth() << ")";
                return os.str();
            }
        }
    }
    return {};
}

} // namespace levelforge_test
