// SPDX-License-Identifier: Apache-2.0
// The mesh pipeline: exact band (Chang or T4 scan) → optional expansion → metadata. See
// pipeline/MeshToSdf.h.
#include <levelforge/pipeline/MeshToSdf.h>

#include "detail/Timer.h"
#include "mesh/WindingSignInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/mesh/FastWindingNumber.h>

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

    // The sign mode, once, for every stage.
    // (Auto with the chang method is resolved by the band stage, from the same report.)
    SignMode sign = o.sign;
    std::string signReason = std::string(toString(sign)) + ": requested";
    MeshReport localReport;
    const MeshReport* report = o.validation;
    bool resolvedHere = sign != SignMode::Auto; // else the band stage says why
    if (sign == SignMode::Auto) {
        requireUsableMesh(mesh);
        if (!report) {
            localReport = validateMesh(mesh);
            report = &localReport;
        }
        if (scan) {
            sign = SignMode::Pseudonormal;
            resolvedHere = true;
            signReason = std::string("auto: the scan method signs by pseudonormals") +
                         (report->closed() ? "" : " (the mesh is not closed: signs may be wrong away from the surface)");
        } else if (o.expansion == Expansion::Sweep && !report->closed()) {
            sign = SignMode::Pseudonormal;
            resolvedHere = true;
            signReason = "auto: the mesh is not closed, but fast sweeping needs pseudonormal signs (signs and "
                         "swept distances may be wrong across its holes; --expansion vector signs it by the winding number)";
        }
    }
    if (sign == SignMode::Winding && o.expansion == Expansion::Sweep)
        throw InvalidArgumentError("the winding sign mode cannot be fast-swept: across a hole the signed band has no zero "
                                   "crossing and the sweep makes one up; use --expansion vector");
    if (scan && (sign == SignMode::Winding || sign == SignMode::Unsigned))
        throw InvalidArgumentError(std::string("the ") + toString(sign) +
                                   " sign mode needs the chang band method (the scan method signs by pseudonormals)");
    if (sign == SignMode::Unsigned && expand)
        throw InvalidArgumentError("an unsigned distance cannot be expanded: the expansion needs inside and outside");
    if (sign == SignMode::Unsigned && o.fillInterior)
        throw InvalidArgumentError("fill interior needs an inside: it cannot be combined with the unsigned sign mode");

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
        mo.sign = sign;
        mo.validation = report;
        mo.windingAccuracy = o.windingAccuracy;
        mo.fillInterior = o.fillInterior && !expand; // after an expansion: below
        if (vector) {
            LevelSetWithClosestPoints r = meshToLevelSetWithClosestPoints(mesh, mo, &stats.band);
            grid = r.levelSet;
            closest = r.closestPoints;
            closestTriangles = r.closestTriangles;
        } else {
            grid = meshToLevelSet(mesh, mo, &stats.band);
        }
        sign = stats.band.sign;
        if (!resolvedHere) signReason = stats.band.signReason;
        stats.filledVoxels = stats.band.filledVoxels;
    }
    if (sign == SignMode::Winding && expand &&
        !(exteriorBand >= 1.0f && interiorBand >= 1.0f)) {
        std::ostringstream os;
        os << "the winding sign mode with an expansion needs an exact band of at least 1 voxel on each side, got "
           << exteriorBand << " outside and " << interiorBand << " inside";
        throw InvalidArgumentError(os.str());
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
        if (sign == SignMode::Winding) {
            // the sweep signs what it adds from a flood fill of the band: sign everything beyond
            // the exact band (and every tile) by the winding number again
            FastWindingNumberOptions fo;
            fo.accuracy = o.windingAccuracy;
            const FastWindingNumber fwn(mesh, fo);
            WindingSignStats ws;
            winding_internal::signTree(grid->tree(), grid->transform(), fwn, mesh.bounds(), true,
                                       double(std::min(exteriorBand, interiorBand)) * h, ws);
        }
    }
    if (o.fillInterior && (expand || scan)) stats.filledVoxels = winding_internal::activateInterior(grid->tree());

    stampLevelSetMetadata(*grid, exteriorTarget, interiorTarget, o.source.empty() ? mesh.source : o.source,
                          method);
    if (sign == SignMode::Unsigned) grid->setGridClass(openvdb::GRID_UNKNOWN); // a UDF has no inside
    grid->insertMeta(kSignMetadata, openvdb::StringMetadata(toString(sign)));
    if (o.fillInterior) grid->insertMeta(kFillInteriorMetadata, openvdb::BoolMetadata(true));
    else grid->removeMeta(kFillInteriorMetadata);
    stats.sign = sign;
    stats.signReason = signReason;
    stats.voxelSize = h;
    stats.exteriorBandVoxels = exteriorTarget;
    stats.interiorBandVoxels = interiorTarget;
    stats.method = method;
    stats.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = stats;
    return grid;
}

} // namespace levelforge
