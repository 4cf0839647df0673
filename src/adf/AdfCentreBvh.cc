// SPDX-License-Identifier: Apache-2.0
// The BVH of the type-3 estimator (see AdfCentreBvh.h).
#include "adf/AdfCentreBvh.h"

#include <numeric>

namespace levelforge {
namespace adf_internal {

CentreBvh::CentreBvh(const openvdb::UInt32Tree& tree)
{
    // primitives: the non-empty 4³ quarters of every leaf (tight boxes prune well)
    std::vector<CoordBBox> cells;
    for (auto it = tree.cbeginLeaf(); it; ++it) {
        const auto& mask = it->getValueMask();
        for (int q = 0; q < 8; ++q) {
            const int x0 = (q >> 2) * 4, y0 = ((q >> 1) & 1) * 4, z0 = (q & 1) * 4;
            CoordBBox bb;
            for (int x = x0; x < x0 + 4; ++x)
                for (int y = y0; y < y0 + 4; ++y)
                    for (int z = z0; z < z0 + 4; ++z)
                        if (mask.isOn(openvdb::Index((x << 6) | (y << 3) | z))) bb.expand(it->origin() + Coord(x, y, z));
            if (bb.empty()) continue;
            mLeaves.push_back(&*it);
            mQuarter.push_back(uint8_t(q));
            cells.push_back(bb);
        }
    }
    // the boxes of the cell centres (c + 1/2)
    std::vector<BBoxd> centres(cells.size());
    for (size_t i = 0; i < cells.size(); ++i) {
        const CoordBBox& bb = cells[i];
        centres[i] = BBoxd(Vec3d(bb.min()[0] + 0.5, bb.min()[1] + 0.5, bb.min()[2] + 0.5),
                           Vec3d(bb.max()[0] + 0.5, bb.max()[1] + 0.5, bb.max()[2] + 0.5));
    }
    std::vector<uint32_t> idx(mLeaves.size());
    std::iota(idx.begin(), idx.end(), 0u);
    mBvh.build(
        std::move(idx), centres, 1,
        [](const uint32_t*, size_t, const detail::Bvh::Node& n) {
            int axis = 0;
            for (int k = 1; k < 3; ++k)
                if (n.hi[k] - n.lo[k] > n.hi[axis] - n.lo[axis]) axis = k;
            return axis;
        },
        [&](uint32_t a, uint32_t c, int axis) {
            const int ka = cells[a].min()[axis], kc = cells[c].min()[axis];
            return ka != kc ? ka < kc : a < c;
        });
}

// inline: called only by nearest2 below, into which it is meant to be inlined
inline void CentreBvh::scanLeaf(uint32_t li, const Vec3d& p, double& best2, Vec3d& hint) const
{
    const ListLeaf& leaf = *mLeaves[li];
    const Coord o = leaf.origin();
    const auto& mask = leaf.getValueMask();
    const int q = mQuarter[li], x0 = (q >> 2) * 4, y0 = ((q >> 1) & 1) * 4, z0 = (q & 1) * 4;
    for (int x = x0; x < x0 + 4; ++x) {
        const double dx = o.x() + x + 0.5 - p[0], dx2 = dx * dx;
        if (dx2 >= best2) continue;
        const uint64_t w = mask.template getWord<uint64_t>(openvdb::Index(x));
        if (!w) continue;
        for (int y = y0; y < y0 + 4; ++y) {
            uint32_t zb = uint32_t(w >> (8 * y)) & (0xfu << z0);
            if (!zb) continue;
            const double dy = o.y() + y + 0.5 - p[1], dxy2 = dx2 + dy * dy;
            if (dxy2 >= best2) continue;
            // nearest set z bit to p: scan outward is overkill for 8 bits; check all
            while (zb) {
                const int z = __builtin_ctz(zb);
                zb &= zb - 1;
                const double dz = o.z() + z + 0.5 - p[2];
                const double d2 = dxy2 + dz * dz;
                if (d2 < best2) {
                    best2 = d2;
                    hint = Vec3d(o.x() + x + 0.5, o.y() + y + 0.5, o.z() + z + 0.5);
                }
            }
        }
    }
}

double CentreBvh::nearest2(const Vec3d& p, Vec3d& hint) const
{
    double best2 = (p - hint).lengthSqr();
    mBvh.nearest<false>(p, best2, [&](const uint32_t* ids, uint32_t n) {
        for (uint32_t i = 0; i < n; ++i) scanLeaf(ids[i], p, best2, hint);
    });
    return best2;
}

} // namespace adf_internal
} // namespace levelforge
