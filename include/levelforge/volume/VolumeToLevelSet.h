// levelforge — scalar volume (CT, MRI, any sampled field) to a signed distance level set, by the
// distance transforms of Satherley & Jones, "Vector-City Vector Distance Transform" (CVIU 2001).
//
// Two classifications of the surface:
//  - binary (§2): inside = f >= iso (Eq. 2); the feature voxels are the transverse inside voxels
//    (26-bit flag, Eq. 3); distances are to feature voxel centres, signed by Eq. 5–6 (feature
//    voxels get 0, interior voxels whose 26 neighbours are all inside are negative);
//  - sub-voxel (§4): the shell of exact closest-point vectors to the interpolated surface
//    (SubvoxelShell.h), signed by the inside flag of each voxel.
// Then a transform fills the whole volume: the chamfer family (binary only), EVDT (two-slice or
// full vector grid), VCVDT 4 or 8 passes, or the exact one (binary: exact EDT of the feature
// voxels; sub-voxel: the exact distance to the triangulated surface for every voxel, BVH).
//
// Output: a level-set FloatGrid in world units whose transform carries the volume's spacing
// (anisotropic spacing is kept: voxel (i,j,k) sits at origin + (i sx, j sy, k sz), and distances
// are Euclidean in world space). The band keeps voxels with -interior < φ < exterior, the widths
// counted in units of the smallest spacing; everything else is inactive ±background with the
// sign of a signed flood fill. fillInterior keeps every inside voxel active.
//
// What is exact and what is approximate: "exact" is exact for the chosen classification; the
// vector transforms are exact except at the Voronoi-corner configurations of §3.2 (measured by
// `levelforge dt-report`), the chamfer transforms follow their metrics (not Euclidean).
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/volume/SubvoxelShell.h>

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <string>

namespace levelforge {

enum class VolumeDistanceMethod
{
    CityBlock, Chessboard, QuasiEuclidean3, Complete3, QuasiEuclidean5, // chamfer (binary only)
    EVDT, EVDTFullGrid, VCVDT4, VCVDT8,                                 // vector transforms
    Exact                                                               // ground truth
};

/// CLI names: city-block, chessboard, quasi-euclidean-3, complete-3, quasi-euclidean-5, evdt,
/// evdt-grid, vcvdt4, vcvdt8, exact.
const char* volumeDistanceMethodName(VolumeDistanceMethod method);
/// Inverse of volumeDistanceMethodName (InvalidArgumentError for an unknown name).
VolumeDistanceMethod volumeDistanceMethodFromName(const std::string& name);

struct VolumeToLevelSetOptions
{
    /// Iso-value τ: samples >= iso are inside (negative), unless insideBelow.
    float iso = 0.0f;
    bool insideBelow = false;
    VolumeDistanceMethod method = VolumeDistanceMethod::VCVDT8;
    /// Sub-voxel shell (§4) instead of binary feature voxels (§2); needs a vector method or Exact.
    bool subvoxel = true;
    /// Half-widths of the band kept active, in units of the smallest voxel spacing (> 0).
    double exteriorWidth = 3.0, interiorWidth = 3.0;
    /// Keep every inside voxel active (interiorWidth is then ignored).
    bool fillInterior = false;
    std::string gridName = "surface";
    /// Refuse volumes with more samples than this (ResourceLimitError); 0 = no limit.
    uint64_t maxVoxels = 1ull << 31;
    openvdb::util::NullInterrupter* interrupter = nullptr;
};

struct VolumeToLevelSetStats
{
    SubvoxelShellStats shell;       ///< sub-voxel only
    uint64_t featureVoxels = 0;     ///< binary only: transverse inside voxels
    uint64_t activeVoxels = 0;
    double secondsClassify = 0;     ///< shell or features
    double secondsTransform = 0;    ///< the distance transform
    double secondsBuild = 0;        ///< dense field -> sparse level set
};

/// The dense signed distance field (world units, negative inside) of the whole volume.
ScalarVolume volumeSignedDistance(const ScalarVolume& field, const VolumeToLevelSetOptions& options,
                                  VolumeToLevelSetStats* stats = nullptr);

/// The level set (see the file comment). Throws InvalidArgumentError (bad options, empty volume,
/// NaN samples, no surface at this iso-value), ResourceLimitError, InterruptedError.
openvdb::FloatGrid::Ptr volumeToLevelSet(const ScalarVolume& field, const VolumeToLevelSetOptions& options,
                                         VolumeToLevelSetStats* stats = nullptr);

/// A dense signed field (world units) to a level-set FloatGrid with the field's spacing/origin.
openvdb::FloatGrid::Ptr denseToLevelSet(const ScalarVolume& signedDistance, double exteriorWorld,
                                        double interiorWorld, bool fillInterior, const std::string& name);

} // namespace levelforge
