// SPDX-License-Identifier: Apache-2.0
// Feature voxels, classification and signing of a dense volume (Satherley & Jones, Eq. 2–6);
// see include/levelforge/volume/VolumeFeatures.h.
#include <levelforge/volume/VolumeFeatures.h>

#include "volume/DenseVolumeHelpers.h"

#include <levelforge/core/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace levelforge {

namespace {

using volume_internal::like;
using volume_internal::requireSameDims;

/// Calls f(i, j, k) for every voxel, parallel over slices.
template<typename F>
void forEachVoxel(const openvdb::Coord& dims, const F& f)
{
    tbb::parallel_for(tbb::blocked_range<int>(0, dims.z()), [&](const tbb::blocked_range<int>& r) {
        for (int k = r.begin(); k != r.end(); ++k)
            for (int j = 0; j < dims.y(); ++j)
                for (int i = 0; i < dims.x(); ++i) f(i, j, k);
    });
}

/// Counts inside voxels among the 26 neighbours of (i,j,k) (beyond the volume = outside).
inline int insideNeighbours(const MaskVolume& in, int i, int j, int k)
{
    const int nx = in.dims.x(), ny = in.dims.y(), nz = in.dims.z();
    int n = 0;
    for (int dz = -1; dz <= 1; ++dz) {
        const int z = k + dz;
        if (z < 0 || z >= nz) continue;
        for (int dy = -1; dy <= 1; ++dy) {
            const int y = j + dy;
            if (y < 0 || y >= ny) continue;
            const uint8_t* row = in.data.data() + in.index(0, y, z);
            for (int dx = -1; dx <= 1; ++dx) {
                const int x = i + dx;
                if (x < 0 || x >= nx || (dx == 0 && dy == 0 && dz == 0)) continue;
                n += row[x] ? 1 : 0;
            }
        }
    }
    return n;
}

} // namespace

MaskVolume insideMask(const ScalarVolume& field, float iso)
{
    requireValidVolume(field, "insideMask");
    if (std::isnan(iso)) throw InvalidArgumentError("insideMask: iso value is NaN");
    MaskVolume m = like<uint8_t>(field);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) m.data[i] = field.data[i] >= iso ? 1 : 0;
    });
    return m;
}

MaskVolume transverseFeatures(const MaskVolume& inside)
{
    requireValidVolume(inside, "transverseFeatures");
    MaskVolume f = like<uint8_t>(inside);
    forEachVoxel(inside.dims, [&](int i, int j, int k) {
        const size_t idx = inside.index(i, j, k);
        uint8_t v = 0;
        if (inside.data[idx]) {
            const int n = insideNeighbours(inside, i, j, k);
            v = (n > 0 && n < 26) ? 1 : 0;
        }
        f.data[idx] = v;
    });
    return f;
}

DenseVolume<int8_t> classification(const MaskVolume& inside, const MaskVolume& features)
{
    requireValidVolume(inside, "classification");
    requireValidVolume(features, "classification");
    requireSameDims(inside, features, "classification");
    DenseVolume<int8_t> c = like<int8_t>(inside);
    forEachVoxel(inside.dims, [&](int i, int j, int k) {
        const size_t idx = inside.index(i, j, k);
        int8_t v = 1;
        if (features.data[idx]) v = 0;
        else if (insideNeighbours(inside, i, j, k) == 26) v = -1;
        c.data[idx] = v;
    });
    return c;
}

ScalarVolume applySign(const ScalarVolume& unsignedDistance, const DenseVolume<int8_t>& sign)
{
    requireValidVolume(unsignedDistance, "applySign");
    requireValidVolume(sign, "applySign");
    requireSameDims(unsignedDistance, sign, "applySign");
    ScalarVolume out = like<float>(unsignedDistance);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, out.data.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const int8_t s = sign.data[i];
            out.data[i] = s == 0 ? 0.0f : (s < 0 ? -unsignedDistance.data[i] : unsignedDistance.data[i]);
        }
    });
    return out;
}

} // namespace levelforge
