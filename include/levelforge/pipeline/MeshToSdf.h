// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The library's front door for meshes: triangle mesh → signed distance level set, the
///        whole pipeline of `levelforge mesh-to-sdf` (Houdini's *VDB from Polygons*, vdb_tool's
///        `-mesh2ls`) in one call.
///
/// The pipeline:
///   1. the exact band, by one of two methods:
///      - BandMethod::Chang (default): Chang, Cha, Ihm, "Computing Local Signed Distance Fields
///        for Large Polygonal Models", CGF 2008 — microtriangle voxelization, triangle lists,
///        layered culled search (mesh/MeshToLevelSet.h);
///      - BandMethod::Scan: Erleben, Dohlmann, "Scan Conversion of Signed Distance Fields" —
///        T4 scan conversion of tetrahedral shells (scan/TetScanConversion.h);
///   2. optionally, expansion of that band to the requested widths (expand/ExpandLevelSet.h):
///      - Expansion::None (default): the whole band is exact (every active voxel holds the exact
///        Euclidean distance to the closest triangle, double precision, stored as float);
///      - Expansion::Sweep: exact within exactBandVoxels, then Zhao's fast sweeping (first-order
///        upwind; approximate beyond the exact band);
///      - Expansion::Vector: exact within exactBandVoxels with its closest points, then the
///        Satherley–Jones VCVDT over the sparse tree; each new voxel gets the exact distance to
///        the triangle its vector came from (an upper bound of the true distance, usually equal);
///   3. the sign (MeshToSdfOptions::sign, see SignMode in mesh/MeshToLevelSet.h): Auto
///      (default) signs closed, consistently oriented meshes by the angle-weighted pseudonormal
///      of the closest feature (exact for them) and every other mesh by the generalized winding
///      number (inside where |w| > 1/2; fast winding number, mesh/FastWindingNumber.h); Unsigned
///      gives the unsigned distance (GRID_UNKNOWN class). BandMethod::Scan signs by
///      pseudonormals only. After a vector expansion of a winding-signed band, every value
///      beyond the exact band and every tile is signed again by the winding number (the
///      expansion's signs come from a flood fill, which leaks through a broken mesh's holes);
///      fast sweeping cannot carry winding signs (across a hole the band has no zero crossing
///      and the sweep makes one up);
///   4. with fillInterior every inside voxel is active: exact in the band, −background deeper
///      (active tiles where a whole tile is inside);
///   5. the grid is stamped with the levelforge metadata (io/VdbIO.h: band widths in voxels,
///      source, generator, method; kSignMetadata; kFillInteriorMetadata when filled);
///   6. optional extra outputs of meshToSdfGrids() (meshToSdf() makes only the level set):
///      - a fog volume (MeshToSdfOptions::fogGridName; Houdini's *Build Fog*): sdfToFog() of the
///        level set with the interior band as the ramp (levelset/SdfToFog.h);
///      - a primitive index grid (MeshToSdfOptions::primitiveIndexGridName): an Int32Grid that
///        holds, for every active voxel of the level set, the input face (polygon, before
///        triangulation: TriangleMesh::sourceFace()) of the triangle that decided its exact
///        distance — the closest face, exactly (ties between faces at the same distance go to
///        either). Only the exact band knows its closest triangles, so this needs
///        BandMethod::Chang, Expansion::None and no fillInterior (InvalidArgumentError
///        otherwise: fast sweeping carries no triangle, the vector expansion's triangle is an
///        upper bound that is not always the closest, the scan method keeps no triangle, and
///        filled voxels deeper than the band were never searched).
///      - attribute grids (MeshToSdfOptions::attributes; Houdini's attribute transfer): for each
///        named per-corner attribute of the mesh (TriangleMesh::attributes, read with
///        MeshReadOptions), a grid of that name (FloatGrid for 1 component, Vec3SGrid for 3:
///        "Cd", "N", "uv") with the level set's transform and active voxels, holding the
///        barycentric interpolation of the attribute at the exact closest point of the closest
///        triangle (mesh/AttributeTransfer.h). Same requirements as the primitive index grid.
///
/// The grid's transform: by default a linear transform of the resolved voxel size (voxel ijk
/// centred at world ijk × voxelSize). MeshToSdfOptions::transform replaces it (and voxelSize /
/// voxelCount) by any linear transform with a uniform scale, e.g. that of a reference grid
/// (readReferenceGrid()), so the voxel centres coincide with the reference's: the mesh is
/// moved into the transform's frame by the rigid motion (rotation, translation; a reflection
/// also reverses the triangles' winding) that maps it to index space × voxel size, converted
/// there, and the result carries the given transform. Rigid motions keep distances, so the
/// values stay exact, in world units.
///
/// The result follows OpenVDB's level-set conventions (GRID_LEVEL_SET, world-unit values,
/// negative inside, background = exterior width in world units; inactive values ±background)
/// and does not depend on the number of threads.
#pragma once

#include <levelforge/core/GridSpec.h>
#include <levelforge/core/TriangleMesh.h>
#include <levelforge/expand/ExpandLevelSet.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/scan/TetScanConversion.h>

#include <openvdb/openvdb.h>
#include <openvdb/math/Transform.h>

#include <string>
#include <vector>

namespace levelforge {

/// How the exact band is computed.
enum class BandMethod
{
    Chang, ///< exact band by microtriangle voxelization + triangle lists (Chang et al. 2008)
    Scan   ///< T4 scan conversion of tetrahedral shells (Erleben–Dohlmann)
};

/// How the band is widened past the exact band.
enum class Expansion
{
    None,   ///< no expansion: the whole requested band is exact
    Sweep,  ///< fast sweeping (Zhao 2005) from an exact band of exactBandVoxels
    Vector  ///< closest-point vectors (Satherley–Jones VCVDT) from an exact band of exactBandVoxels
};

/// "chang" / "scan"; throws InvalidArgumentError for other names.
BandMethod bandMethodFromString(const std::string& name);
/// "none" (or "exact") / "sweep" / "vector"; throws InvalidArgumentError for other names.
Expansion expansionFromString(const std::string& name);

/// Options of meshToSdf(). GridSpec holds the voxel size or count, the final band widths
/// (voxels or world units), the grid name, the voxel budget (checked by every stage) and the
/// interrupter (progress of every stage).
struct MeshToSdfOptions : GridSpec
{
    BandMethod method = BandMethod::Chang;
    Expansion expansion = Expansion::None;
    /// With an expansion: half-width of the exact band computed first, in voxels (>= 1); the
    /// exact band is min(this, width) on each side.
    double exactBandVoxels = 3.0;
    /// BandMethod::Scan only: the tetrahedral shell, its coverage and conservative
    /// rasterization (see TetScanOptions).
    ShellMethod shell = ShellMethod::Obb;
    ShellCoverage coverage = ShellCoverage::Complete;
    bool conservative = false;
    /// Value of the "levelforge:source" metadata; empty: mesh.source.
    std::string source;
    /// How the distance is signed (SignMode; Auto: pseudonormal for closed meshes, winding
    /// number otherwise). Winding and Unsigned need BandMethod::Chang; Unsigned no expansion;
    /// Winding with an expansion needs Expansion::Vector (fast sweeping makes up a zero crossing
    /// across a hole: Auto with Expansion::Sweep signs an open mesh by pseudonormals, as before)
    /// and band widths of at least 1 voxel.
    SignMode sign = SignMode::Auto;
    /// Every inside voxel active (see MeshToLevelSetOptions::fillInterior); not with Unsigned.
    bool fillInterior = false;
    /// Winding: the fast winding number's accuracy β (> 1).
    double windingAccuracy = 2.0;
    /// Where BandMethod::Chang's per-voxel search runs (MeshToLevelSetOptions::device): the CPU,
    /// a Vulkan device, or Auto (a discrete GPU for large bands). Bit-identical grids.
    ComputeDevice device = ComputeDevice::Auto;
    /// Vulkan: device memory per batch slot (bytes); 0: automatic.
    uint64_t deviceMemoryBudget = 0;
    /// Auto: an existing validateMesh() report of this mesh (not owned); null: validate here.
    const MeshReport* validation = nullptr;
    /// Optional: the transform of the output grids (e.g. a reference grid's, see
    /// readReferenceGrid()); when set it replaces voxelSize and voxelCount (the voxel size is its
    /// scale). It must be linear with a uniform scale (rotation and translation allowed;
    /// checkUniformLinearTransform()), else meshToSdf() throws InvalidArgumentError.
    openvdb::math::Transform::ConstPtr transform;
    /// meshToSdfGrids() only: the name of a fog volume to make too (see the file comment, step
    /// 6); empty (default): none. Not with SignMode::Unsigned (a fog needs an inside).
    std::string fogGridName;
    /// meshToSdfGrids() only: the name of a primitive index grid (Int32) to make too (see the
    /// file comment, step 6); empty (default): none. Needs BandMethod::Chang, Expansion::None
    /// and no fillInterior.
    std::string primitiveIndexGridName;
    /// meshToSdfGrids() only: attributes of the mesh (TriangleMesh::attributes, by name: "Cd",
    /// "N", "uv", ...) to transfer to grids of the same names (see the file comment, step 6);
    /// empty (default): none. Needs BandMethod::Chang, Expansion::None and no fillInterior; a
    /// name the mesh does not have throws InvalidArgumentError listing those it has.
    std::vector<std::string> attributes;
};

/// The grids meshToSdfGrids() makes (the optional ones are null unless asked for).
struct MeshToSdfGrids
{
    openvdb::FloatGrid::Ptr sdf;            ///< the level set, named gridName (as meshToSdf())
    openvdb::FloatGrid::Ptr fog;            ///< fogGridName: the fog volume (GRID_FOG_VOLUME)
    openvdb::Int32Grid::Ptr primitiveIndex; ///< primitiveIndexGridName: closest input face, background -1
    /// attributes: one grid per attribute, in the order asked for (FloatGrid or Vec3SGrid)
    openvdb::GridPtrVec attributes;

    /// The grids that exist, in the order above (for writeGridsAtomic()).
    openvdb::GridPtrVec all() const
    {
        openvdb::GridPtrVec v;
        if (sdf) v.push_back(sdf);
        if (fog) v.push_back(fog);
        if (primitiveIndex) v.push_back(primitiveIndex);
        for (const openvdb::GridBase::Ptr& a : attributes) v.push_back(a);
        return v;
    }
};

/// What a reference grid gives a conversion (readReferenceGrid()).
struct ReferenceGrid
{
    std::string path;                          ///< the file it was read from
    std::string name;                          ///< the grid's name
    openvdb::math::Transform::Ptr transform;   ///< its transform (checked: linear, uniform scale)
    double voxelSize = 0.0;                    ///< world units
    /// Band half-widths, voxels: the levelforge metadata (meta::kExteriorBandVoxels /
    /// kInteriorBandVoxels) when present, else background / voxel size on both sides for a level
    /// set; 0 when neither says (a fog volume without metadata).
    double exteriorBandVoxels = 0.0;
    double interiorBandVoxels = 0.0;
};

/// @brief Checks that @p transform is linear with a uniform scale (its index-to-world matrix is
///        a positive multiple of an orthogonal matrix: rotation, reflection, translation allowed).
/// @param[in] transform  the transform
/// @param[in] what       how messages name it, e.g. "reference 'ref.vdb'"
/// @return the voxel size (the scale, world units)
/// @throws InvalidArgumentError naming @p what: not linear (frustum), non-uniform scale, shear,
///         zero or non-finite scale
double checkUniformLinearTransform(const openvdb::math::Transform& transform, const std::string& what);

/// @brief Reads the first FloatGrid of a .vdb file as a reference: its transform (checked with
///        checkUniformLinearTransform()) and band widths, for MeshToSdfOptions::transform and the
///        widths (Houdini's *Reference VDB*).
/// @param[in] path  the .vdb file
/// @return what the reference gives (see ReferenceGrid)
/// @throws IoError naming @p path: missing, unreadable, not a VDB file, corrupt
/// @throws InvalidArgumentError naming @p path: no FloatGrid in it, or a transform that is not
///         linear with a uniform scale
ReferenceGrid readReferenceGrid(const std::string& path);

/// What each stage did (the stage that did not run keeps its zeros).
struct MeshToSdfStats
{
    MeshToLevelSetStats band;         ///< BandMethod::Chang
    TetScanStats scan;                ///< BandMethod::Scan
    ExpandLevelSetStats expansion;    ///< with an expansion
    double voxelSize = 0.0;           ///< world units
    double exteriorBandVoxels = 0.0;  ///< final band half-widths, voxels
    double interiorBandVoxels = 0.0;
    std::string method;               ///< the "levelforge:method" stamped on the grid
    SignMode sign = SignMode::Pseudonormal; ///< the sign mode used (never Auto)
    std::string signReason;           ///< why (Auto: what validation found)
    uint64_t filledVoxels = 0;        ///< fillInterior: voxels activated (tiles counted by volume)
    double seconds = 0.0;             ///< the whole call
};

/// @brief Converts a triangle mesh to a signed distance level set (see the file comment).
/// @param[in]  mesh     the triangle mesh (world units); checked with requireUsableMesh()
/// @param[in]  options  grid, band, method and expansion settings (fogGridName and
///                      primitiveIndexGridName are ignored here: see meshToSdfGrids())
/// @param[out] stats    optional: what each stage did
/// @return the level set, named options.gridName, stamped with the levelforge metadata
/// @throws InvalidArgumentError (bad options, a transform that is not linear with a uniform
///         scale, or a combination that cannot work: winding or
///         unsigned with the scan method, unsigned with an expansion or fillInterior, winding
///         with fast sweeping, winding with an expansion and a band under 1 voxel), InvalidMeshError (empty mesh, NaN, bad
///         index), ResourceLimitError (band larger than options.maxVoxels), InterruptedError.
openvdb::FloatGrid::Ptr meshToSdf(const TriangleMesh& mesh, const MeshToSdfOptions& options = {},
                                  MeshToSdfStats* stats = nullptr);

/// @brief meshToSdf() and the optional grids of step 6 (fog volume, primitive index), all with
///        the same transform.
/// @param[in]  mesh     as for meshToSdf(); mesh.faceIndex, when not empty, must have one entry
///                      per triangle (InvalidMeshError)
/// @param[in]  options  as for meshToSdf(), with fogGridName / primitiveIndexGridName
/// @param[out] stats    optional: what each stage did
/// @return the level set (identical to meshToSdf()'s) and the grids asked for
/// @throws as meshToSdf(), and InvalidArgumentError when two grid names are equal, for a fog with
///         SignMode::Unsigned, for a primitive index or attributes with BandMethod::Scan, an
///         expansion or fillInterior, or for an attribute the mesh does not have (before any
///         work; the message lists the attributes it has)
MeshToSdfGrids meshToSdfGrids(const TriangleMesh& mesh, const MeshToSdfOptions& options = {},
                              MeshToSdfStats* stats = nullptr);

} // namespace levelforge
