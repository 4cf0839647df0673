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

/// @brief A dense box of samples of type T on an axis-aligned lattice with per-axis spacing.
///
/// Sample (i,j,k) is data[index(i,j,k)] (x fastest) and sits at the world position
/// origin + (i*sx, j*sy, k*sz) (see the file comment).
template<typename T>
struct DenseVolume
{
    using ValueType = T;

    openvdb::Coord dims{0, 0, 0};          ///< samples along x, y, z
    openvdb::Vec3d spacing{1.0, 1.0, 1.0}; ///< world units between samples along x, y, z (> 0)
    openvdb::Vec3d origin{0.0, 0.0, 0.0};  ///< world position of sample (0,0,0)
    std::vector<T> data;                   ///< dims.x*dims.y*dims.z values, x fastest

    /// @brief An empty volume: dims 0, spacing 1, origin 0, no data.
    DenseVolume() = default;
    /// @brief A volume of @p d samples, all set to @p fill.
    /// @param[in] d     samples along x, y, z (each >= 0)
    /// @param[in] fill  the value of every sample
    /// @param[in] s     world units between samples along x, y, z (> 0)
    /// @param[in] o     world position of sample (0,0,0)
    DenseVolume(const openvdb::Coord& d, const T& fill = T(),
                const openvdb::Vec3d& s = openvdb::Vec3d(1.0), const openvdb::Vec3d& o = openvdb::Vec3d(0.0))
        : dims(d), spacing(s), origin(o), data(size_t(d.x()) * size_t(d.y()) * size_t(d.z()), fill) {}

    size_t voxelCount() const { return size_t(dims.x()) * size_t(dims.y()) * size_t(dims.z()); }
    bool empty() const { return data.empty(); }

    /// @brief The position of sample (i,j,k) in `data`: (k*ny + j)*nx + i. Not bounds-checked.
    /// @param[in] i  sample index along x, in [0, dims.x)
    /// @param[in] j  sample index along y, in [0, dims.y)
    /// @param[in] k  sample index along z, in [0, dims.z)
    /// @return the offset into `data`
    size_t index(int i, int j, int k) const
    {
        return (size_t(k) * size_t(dims.y()) + size_t(j)) * size_t(dims.x()) + size_t(i);
    }
    /// @brief Whether (i,j,k) is a sample of the volume.
    /// @param[in] i  sample index along x
    /// @param[in] j  sample index along y
    /// @param[in] k  sample index along z
    /// @return true when 0 <= i < dims.x, 0 <= j < dims.y and 0 <= k < dims.z
    bool inside(int i, int j, int k) const
    {
        return i >= 0 && j >= 0 && k >= 0 && i < dims.x() && j < dims.y() && k < dims.z();
    }
    /// @brief Sample (i,j,k), writable. Not bounds-checked (see inside()).
    /// @param[in] i  sample index along x, in [0, dims.x)
    /// @param[in] j  sample index along y, in [0, dims.y)
    /// @param[in] k  sample index along z, in [0, dims.z)
    /// @return a reference to data[index(i, j, k)]
    T& operator()(int i, int j, int k) { return data[index(i, j, k)]; }
    /// @brief Sample (i,j,k), read-only. Not bounds-checked (see inside()).
    /// @param[in] i  sample index along x, in [0, dims.x)
    /// @param[in] j  sample index along y, in [0, dims.y)
    /// @param[in] k  sample index along z, in [0, dims.z)
    /// @return a reference to data[index(i, j, k)]
    const T& operator()(int i, int j, int k) const { return data[index(i, j, k)]; }

    /// @brief The world position of the (possibly fractional) sample coordinates (i,j,k).
    /// @param[in] i  sample coordinate along x (index space; fractions allowed)
    /// @param[in] j  sample coordinate along y (index space; fractions allowed)
    /// @param[in] k  sample coordinate along z (index space; fractions allowed)
    /// @return origin + (i*sx, j*sy, k*sz), world units
    openvdb::Vec3d worldPosition(double i, double j, double k) const
    {
        return origin + openvdb::Vec3d(i * spacing[0], j * spacing[1], k * spacing[2]);
    }
    /// @brief True when the spacing is the same along x, y and z.
    bool isotropic() const { return spacing[0] == spacing[1] && spacing[1] == spacing[2]; }
};

using ScalarVolume = DenseVolume<float>;
using MaskVolume = DenseVolume<uint8_t>;

/// @brief Checks that a volume is usable.
///
/// Throws InvalidArgumentError, naming `what`, unless the volume has dims > 0, exactly
/// dims.x*dims.y*dims.z values and a finite spacing > 0 (also in single precision) on each axis.
/// @param[in] v     the volume to check
/// @param[in] what  a label for the messages (e.g. the file or the function), prefixed to them
/// @throws InvalidArgumentError an empty dimension, a data size that does not match dims, or a
///         spacing that is not finite and > 0 (in double or in float) along some axis
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

/// @brief An analytic sphere field, for tests.
///
/// The analytic field radius - |x - centre| (world units; positive inside the sphere) sampled on
/// `dims` samples with `spacing` from the origin: a test volume whose iso-surface 0 is a sphere.
/// @param[in] dims     samples along x, y, z
/// @param[in] centre   sphere centre, world units
/// @param[in] radius   sphere radius, world units
/// @param[in] spacing  world units between samples along x, y, z (> 0); the origin is (0,0,0)
/// @return the sampled field, float, positive inside the sphere
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
