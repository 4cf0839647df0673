// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Scalar volume (CT, MRI, any sampled field) to a signed distance level set, by the
///        dense distance transforms.
///
/// Paper: R. Satherley and M. W. Jones, "Vector-City Vector Distance Transform", Computer Vision
/// and Image Understanding 82 (2001).
///
/// Two classifications of the surface:
///  - binary (§2): inside = f >= iso (Eq. 2); the feature voxels are the transverse inside voxels
///    (26-bit flag, Eq. 3); distances are to feature voxel centres, signed by Eq. 5–6 (feature
///    voxels get 0, interior voxels whose 26 neighbours are all inside are negative;
///    VolumeFeatures.h);
///  - sub-voxel (§4): the shell of exact closest-point vectors to the interpolated surface
///    (SubvoxelShell.h), signed by the inside flag of each voxel.
/// Then a transform fills the whole volume: the chamfer family (binary only), EVDT (two-slice or
/// full vector grid), VCVDT 4 or 8 passes, or the exact one (binary: exact EDT of the feature
/// voxels; sub-voxel: the exact distance to the triangulated surface for every voxel, BVH).
///
/// Output: a level-set FloatGrid in world units whose transform carries the volume's spacing
/// (anisotropic spacing is kept: voxel (i,j,k) sits at origin + (i sx, j sy, k sz), and distances
/// are Euclidean in world space). The band keeps voxels with -interior < φ < exterior, the widths
/// in voxels of the smallest spacing (or in world units with WidthUnits::World); everything else
/// is inactive ±background with the sign of a signed flood fill. fillInterior keeps every inside
/// voxel active.
///
/// What is exact and what is approximate: "exact" is exact for the chosen classification; the
/// vector transforms are exact except at the Voronoi-corner configurations of §3.2 (measured by
/// `levelforge dt-report`), the chamfer transforms follow their metrics (not Euclidean).
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/GridSpec.h>
#include <levelforge/gpu/VulkanDevices.h>
#include <levelforge/volume/SubvoxelShell.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <string>

namespace levelforge {

/// The distance transform that fills the volume.
enum class VolumeDistanceMethod
{
    CityBlock, Chessboard, QuasiEuclidean3, Complete3, QuasiEuclidean5, // chamfer (binary only)
    EVDT, EVDTFullGrid, VCVDT4, VCVDT8,                                 // vector transforms
    Exact                                                               // ground truth
};

/// @brief The CLI name of a method.
/// @param[in] method  a volume distance method
/// @return city-block, chessboard, quasi-euclidean-3, complete-3, quasi-euclidean-5, evdt,
///         evdt-grid, vcvdt4, vcvdt8 or exact ("unknown" for a value outside the enum).
const char* volumeDistanceMethodName(VolumeDistanceMethod method);

/// @brief Inverse of volumeDistanceMethodName().
/// @param[in] name  a CLI name
/// @return the method of that name.
/// @throws InvalidArgumentError for an unknown name (the message lists the valid ones).
VolumeDistanceMethod volumeDistanceMethodFromName(const std::string& name);

/// Options of the volume conversions (dense: volumeToLevelSet(), volumeSignedDistance();
/// sparse: sparseVolumeToLevelSet()).
///
/// From GridSpec: exteriorWidth / interiorWidth (in `units`; WidthUnits::Voxels counts voxels of
/// the smallest spacing), units, gridName, maxVoxels (dense: a limit on the volume's samples;
/// sparse: on the band's voxels; 2^31 by default) and interrupter. voxelSize and voxelCount must stay 0: the volume's spacing
/// sets the voxel size (InvalidArgumentError otherwise).
struct VolumeToLevelSetOptions : GridSpec
{
    /// The volume defaults: widths 3 voxels (GridSpec's), maxVoxels = 2^31 samples.
    VolumeToLevelSetOptions() { maxVoxels = 1ull << 31; }

    /// Iso-value τ: samples >= iso are inside (negative), unless insideBelow.
    float iso = 0.0f;
    bool insideBelow = false;
    VolumeDistanceMethod method = VolumeDistanceMethod::VCVDT8;
    /// Sub-voxel shell (§4) instead of binary feature voxels (§2); needs a vector method or Exact.
    bool subvoxel = true;
    /// Keep every inside voxel active (interiorWidth is then ignored).
    bool fillInterior = false;
    /// Where the exact transform of binary features (method Exact, subvoxel false) runs:
    /// ExactTransformOptions::device (bit-identical on every device). The other methods run on
    /// the CPU; with Vulkan, stats.deviceNote then says so.
    ComputeDevice device = ComputeDevice::Cpu;
    /// ExactTransformOptions::deviceMemoryBudget (bytes; 0: automatic).
    uint64_t deviceMemoryBudget = 0;
};

/// What a volume conversion did.
struct VolumeToLevelSetStats
{
    SubvoxelShellStats shell;       ///< sub-voxel only
    uint64_t featureVoxels = 0;     ///< binary only: transverse inside voxels
    uint64_t activeVoxels = 0;      ///< active voxels of the level set (volumeToLevelSet() only)
    double secondsClassify = 0;     ///< shell or features
    double secondsTransform = 0;    ///< the distance transform
    double secondsBuild = 0;        ///< dense field -> sparse level set
    std::string device = "cpu";     ///< where the transform ran: "cpu" or "vulkan: <name> (<type>)"
    std::string deviceNote;         ///< why a device asked for was not used (empty otherwise)
    double secondsDeviceTransfer = 0; ///< device: host copies and copy submissions
    double secondsDeviceCompute = 0;  ///< device: waiting for the kernels
    uint64_t devicePeakBytes = 0;     ///< device: device memory held at most
};

/// @brief The dense signed distance field of the whole volume (see the file comment).
/// @param[in]  field    the sampled field (no NaN samples)
/// @param[in]  options  iso, insideBelow, method, subvoxel, maxVoxels, interrupter (the widths
///                      are checked but not used)
/// @param[out] stats    optional: shell or feature counts, stage times
/// @return distances in world units, negative inside; same dims, spacing, origin.
/// @throws InvalidArgumentError (bad options, empty volume, NaN samples, no surface at this
///         iso-value);
/// @throws ResourceLimitError (more samples than maxVoxels);
/// @throws InterruptedError.
ScalarVolume volumeSignedDistance(const ScalarVolume& field, const VolumeToLevelSetOptions& options,
                                  VolumeToLevelSetStats* stats = nullptr);

/// @brief The level set of a scalar volume (see the file comment).
/// @param[in]  field    the sampled field (no NaN samples)
/// @param[in]  options  see VolumeToLevelSetOptions
/// @param[out] stats    optional: shell or feature counts, active voxels, stage times
/// @return a GRID_LEVEL_SET FloatGrid named options.gridName, with the volume's spacing and
///         origin as its transform.
/// @throws InvalidArgumentError (bad options, empty volume, NaN samples, no surface at this
///         iso-value);
/// @throws ResourceLimitError (more samples than maxVoxels);
/// @throws InterruptedError.
openvdb::FloatGrid::Ptr volumeToLevelSet(const ScalarVolume& field, const VolumeToLevelSetOptions& options,
                                         VolumeToLevelSetStats* stats = nullptr);

/// @brief A dense signed field to a level-set FloatGrid with the field's spacing and origin.
/// @param[in] signedDistance  distances in world units, negative inside (non-finite samples
///                            are left out)
/// @param[in] exteriorWorld   voxels with 0 <= φ < exteriorWorld stay active; also the
///                            background
/// @param[in] interiorWorld   voxels with -interiorWorld < φ < 0 stay active
/// @param[in] fillInterior    keep every voxel with φ < 0 active instead
/// @param[in] name            the grid name
/// @return the level set; inactive inside voxels hold -background.
openvdb::FloatGrid::Ptr denseToLevelSet(const ScalarVolume& signedDistance, double exteriorWorld,
                                        double interiorWorld, bool fillInterior, const std::string& name);

} // namespace levelforge
