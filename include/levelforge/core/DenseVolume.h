// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief A dense scalar volume with anisotropic voxel spacing.
///
/// The common currency of the volume road (Satherley–Jones): readers (VolumeIO.h) produce it,
/// the dense distance transforms (ChamferDistanceTransform.h, VectorDistanceTransform.h,
/// ExactDistanceTransform.h) consume and produce it, and volumeToLevelSet()
/// (VolumeToLevelSet.h) turns it into a sparse FloatGrid.
///
/// Layout: x fastest, then y, then z (index = (k*ny + j)*nx + i). Sample (i,j,k) sits at the
/// world position origin + (i*sx, j*sy, k*sz): voxel centres, the convention of OpenVDB's
/// cell-centred index space with a scale transform (and of NIfTI/INR voxel coordinates).
#pragma once

#include <levelforge/core/Exceptions.h>

#include <openvdb/Types.h> // openvdb::Coord, openvdb::Vec3d

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

namespace levelforge {

template<typename T>
struct DenseVolume
{
    using ValueType = T;

    openvdb::Coord dims{0, 0, 0};          ///< samples along x, y, z
    openvdb::Vec3d spacing{1.0, 1.0, 1.0}; ///< world units between samples along x, y, z (> 0)
    openvdb::Vec3d origin{0.0, 0.0, 0.0};  ///< world position of sample (0,0,0)
    std::vector<T> data;                   ///< dims.x*dims.y*dims.z values, x fastest

    DenseVolume() = default;
    DenseVolume(const openvdb::Coord& d, const T& fill = T(),
                const openvdb::Vec3d& s = openvdb::Vec3d(1.0), const openvdb::Vec3d& o = openvdb::Vec3d(0.0))
        : dims(d), spacing(s), origin(o), data(size_t(d.x()) * size_t(d.y()) * size_t(d.z()), fill) {}

    size_t voxelCount() const { return size_t(dims.x()) * size_t(dims.y()) * size_t(dims.z()); }
    bool empty() const { return data.empty(); }

    size_t index(int i, int j, int k) const
    {
        return (size_t(k) * size_t(dims.y()) + size_t(j)) * size_t(dims.x()) + size_t(i);
    }
    bool inside(int i, int j, int k) const
    {
        return i >= 0 && j >= 0 && k >= 0 && i < dims.x() && j < dims.y() && k < dims.z();
    }
    T& operator()(int i, int j, int k) { return data[index(i, j, k)]; }
    const T& operator()(int i, int j, int k) const { return data[index(i, j, k)]; }

    openvdb::Vec3d worldPosition(double i, double j, double k) const
    {
        return origin + openvdb::Vec3d(i * spacing[0], j * spacing[1], k * spacing[2]);
    }
    bool isotropic() const { return spacing[0] == spacing[1] && spacing[1] == spacing[2]; }
};

using ScalarVolume = DenseVolume<float>;
using MaskVolume = DenseVolume<uint8_t>;

/// Throws InvalidArgumentError, naming `what`, unless the volume has dims > 0, exactly
/// dims.x*dims.y*dims.z values and a finite spacing > 0 (also in single precision) on each axis.
template<typename T>
void requireValidVolume(const DenseVolume<T>& v, const char* what)
{
    const auto& d = v.dims;
    if (d.x() <= 0 || d.y() <= 0 || d.z() <= 0) {
        std::ostringstream ss;
        ss << what << ": empty volume (dims " << d.x() << " x " << d.y() << " x " << d.z() << ")";
        throw InvalidArgumentError(ss.str());
    }
    if (v.data.size() != v.voxelCount()) {
        std::ostringstream ss;
        ss << what << ": data holds " << v.data.size() << " values but dims " << d.x() << " x " << d.y()
           << " x " << d.z() << " need " << v.voxelCount();
        throw InvalidArgumentError(ss.str());
    }
    for (int a = 0; a < 3; ++a) {
        const double s = v.spacing[a];
        if (!(std::isfinite(s) && s > 0.0) || !std::isfinite(float(s)) || float(s) <= 0.0f) {
            std::ostringstream ss;
            ss << what << ": voxel spacing along " << "xyz"[a] << " is " << s
               << " (must be finite and > 0, world units)";
            throw InvalidArgumentError(ss.str());
        }
    }
}

/// The analytic field radius - |x - centre| (world units; positive inside the sphere) sampled on
/// `dims` samples with `spacing` from the origin: a test volume whose iso-surface 0 is a sphere.
inline ScalarVolume makeSphereField(const openvdb::Coord& dims, const openvdb::Vec3d& centre, double radius,
                                    const openvdb::Vec3d& spacing = openvdb::Vec3d(1.0))
{
    ScalarVolume v(dims, 0.0f, spacing);
    for (int k = 0; k < dims.z(); ++k)
        for (int j = 0; j < dims.y(); ++j)
            for (int i = 0; i < dims.x(); ++i)
                v(i, j, k) = float(radius - (v.worldPosition(i, j, k) - centre).length());
    return v;
}

} // namespace levelforge
