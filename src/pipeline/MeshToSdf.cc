// SPDX-License-Identifier: Apache-2.0
// The mesh pipeline: exact band (Chang or T4 scan) → optional expansion → metadata. See
// pipeline/MeshToSdf.h.
#include <levelforge/pipeline/MeshToSdf.h>

#include "detail/Timer.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace levelforge {

BandMethod bandMethodFromString(const std::string& name)
{
    if (name == "chang") return BandMethod::Chang;
    if (name == "scan") return BandMethod::Scan;
    throw InvalidArgumentError("unknown band method '" + name + "' (chang, scan)");
}

Expansion expansionFromString(const std::string& name)
{
    if (name == "none" || name == "exact") return Expansion::None;
    if (name == "sweep") return Expansion::Sweep;
    if (name == "vector") return Expansion::Vector;
    throw InvalidArgumentError("unknown expansion '" + name + "' (none, exact, sweep, vector)");
}

openvdb::FloatGrid::Ptr meshToSdf(const TriangleMesh& mesh, const MeshToSdfOptions& o, MeshToSdfStats* statsOut)
{
    const auto t0 = detail::Clock::now();
    MeshToSdfStats stats;
    const bool scan = o.method == BandMethod::Scan;
    const bool expand = o.expansion != Expansion::None;
    const bool vector = o.expansion == Expansion::Vector;
    if (expand && !(std::isfinite(o.exactBandVoxels) && o.exactBandVoxels >= 1.0)) {
        std::ostringstream os;
        os << "the exact band must be at least 1 voxel, got " << o.exactBandVoxels;
        throw InvalidArgumentError(os.str());
    }

    // One voxel size and the final widths in voxels, held in float as the band stages hold them.
    const double h = resolveVoxelSize(mesh, o);
    const float exteriorTarget = static_cast<float>(o.widthInVoxels(o.exteriorWidth, h));
    const float interiorTarget = static_cast<float>(o.widthInVoxels(o.interiorWidth, h));
    float exteriorBand = exteriorTarget, interiorBand = interiorTarget;
    if (expand) {
        const float exact = static_cast<float>(o.exactBandVoxels);
        exteriorBand = std::min(exteriorBand, exact);
        interiorBand = std::min(interiorBand, exact);
    }

    // The exact band, in voxels, at the resolved voxel size.
    GridSpec band = o;
    band.voxelSize = h;
    band.voxelCount = 0;
    band.units = WidthUnits::Voxels;
    band.exteriorWidth = exteriorBand;
    band.interiorWidth = interiorBand;

    openvdb::FloatGrid::Ptr grid;
    openvdb::Vec3fGrid::Ptr closest;
    openvdb::Int32Grid::Ptr closestTriangles;
    if (scan) {
        TetScanOptions so;
        static_cast<GridSpec&>(so) = band;
        so.shell = o.shell;
        so.coverage = o.coverage;
        so.conservative = o.conservative;
        grid = meshToLevelSetScan(mesh, so, &stats.scan);
    } else {
        MeshToLevelSetOptions mo;
        static_cast<GridSpec&>(mo) = band;
        if (vector) {
            LevelSetWithClosestPoints r = meshToLevelSetWithClosestPoints(mesh, mo, &stats.band);
            grid = r.levelSet;
            closest = r.closestPoints;
            closestTriangles = r.closestTriangles;
        } else {
            grid = meshToLevelSet(mesh, mo, &stats.band);
        }
    }

    std::string method = scan ? "erleben-dohlmann-t4-scan" : "chang2008-exact-band";
    if (expand) {
        ExpandLevelSetOptions eo;
        eo.exteriorWidth = exteriorTarget;
        eo.interiorWidth = interiorTarget;
        eo.inputExteriorWidth = exteriorBand;
        eo.inputInteriorWidth = interiorBand;
        eo.maxVoxels = o.maxVoxels;
        eo.interrupter = o.interrupter;
        if (vector) {
            // After a scan band there are no closest points: the offsets are estimated from φ.
            eo.method = ExpansionMethod::Vector;
            if (closest) eo.closestPoints = &closest->tree();
            if (closestTriangles) {
                eo.closestTriangles = &closestTriangles->tree();
                eo.mesh = &mesh;
            }
        }
        grid = expandLevelSet(*grid, eo, &stats.expansion);
        method += vector ? "+satherley-jones-vcvdt8" : "+zhao2005-fast-sweeping";
    }

    stampLevelSetMetadata(*grid, exteriorTarget, interiorTarget, o.source.empty() ? mesh.source : o.source,
                          method);
    stats.voxelSize = h;
    stats.exteriorBandVoxels = exteriorTarget;
    stats.interiorBandVoxels = interiorTarget;
    stats.method = method;
    stats.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = stats;
    return grid;
}

} // namespace levelforge
