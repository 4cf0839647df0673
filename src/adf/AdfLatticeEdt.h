// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/adf/: the type-3 samples of all tile corners at once, by an exact
///        Euclidean distance transform of the boundary-cell centres on the 8-spaced lattice.
#pragma once

#include "adf/AdfInternal.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace levelforge {
namespace adf_internal {

/// Exact squared distances from the points of the 8-spaced lattice of the domain to the nearest
/// boundary-cell centre: the type-3 rule at the tile corners, for all of them at once. A
/// separable exact Euclidean distance transform (lower envelopes of parabolas, Felzenszwalb &
/// Huttenlocher; detail/LowerEnvelope.h) over the list tree's cells, evaluated only at the
/// lattice: columns along z, then y, then x. All in doubled integer coordinates (centre c + 1/2
/// -> 2c + 1, lattice point p -> 2p; D = 4·d²), with exact rational comparisons, so each value
/// equals the minimum the BVH finds (a half-integer sum of squares, exact in double) bit for bit.
class LatticeEdt
{
public:
    static constexpr int kStep = 8;

    /// False (nothing built; use the BVH) for empty trees, huge coordinates or huge lattices.
    bool build(const openvdb::UInt32Tree& tree, const CoordBBox& domain);

    /// Squared index-space distance from lattice point p to the nearest boundary-cell centre.
    bool lookup(const Coord& p, double& d2) const
    {
        if (mD.empty()) return false;
        int idx[3];
        for (int k = 0; k < 3; ++k) {
            const int64_t o = int64_t(p[k]) - mLo[k];
            if (o < 0 || o % kStep || o / kStep >= mN[k]) return false;
            idx[k] = int(o / kStep);
        }
        d2 = double(mD[(size_t(idx[0]) * mN[1] + size_t(idx[1])) * mN[2] + size_t(idx[2])]) * 0.25;
        return true;
    }

private:
    Coord mLo{0, 0, 0};
    int mN[3] = {0, 0, 0};
    std::vector<int64_t> mD;
};

} // namespace adf_internal
} // namespace levelforge
