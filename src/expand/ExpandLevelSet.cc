// SPDX-License-Identifier: Apache-2.0
// The front door of the expansion: option checks, band widths and metadata, the candidate
// topology, the dispatch to the Sweep or Vector method, and the trim to the kept widths (see
// include/levelforge/expand/ExpandLevelSet.h).
#include "detail/ProgressCheck.h"
#include <levelforge/expand/ExpandLevelSet.h>

#include "detail/NumberFormat.h"
#include "detail/Timer.h"
#include "detail/VoxelBudget.h"
#include "expand/FastSweepingInternal.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/core/Progress.h>
#include "expand/VectorExpansion.h"

#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/Morphology.h>
#include <openvdb/tools/Prune.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tree/LeafManager.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace levelforge {

namespace {

using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using detail::Clock;
using detail::formatDouble;
using detail::secondsSince;
using fast_sweeping_internal::kBig;

double readBandMeta(const openvdb::FloatGrid& g, const char* key, double fallback)
{
    if (auto m = g.getMetadata<openvdb::FloatMetadata>(key)) return m->value();
    if (auto m = g.getMetadata<openvdb::DoubleMetadata>(key)) return m->value();
    return fallback;
}

void checkWidth(double v, const char* name, bool allowZero = false)
{
    if (!std::isfinite(v) || v < 0 || (!allowZero && v == 0)) {
        throw InvalidArgumentError(std::string("expandLevelSet: ") + name + " must be finite and " +
                                   (allowZero ? ">= 0" : "> 0") + ", got " + formatDouble(v));
    }
}

/// The GridSpec fields an expansion does not use must stay unset: the input grid keeps its
/// voxel size.
void checkGridSpec(const ExpandLevelSetOptions& opt)
{
    if (opt.voxelSize != 0.0 || opt.voxelCount != 0) {
        throw InvalidArgumentError("expandLevelSet: voxelSize and voxelCount must be 0 (the result keeps the "
                                   "input grid's voxel size), got voxelSize " + formatDouble(opt.voxelSize) +
                                   ", voxelCount " + std::to_string(opt.voxelCount));
    }
}

} // namespace

openvdb::FloatGrid::Ptr expandLevelSet(const openvdb::FloatGrid& input,
                                       const ExpandLevelSetOptions& opt,
                                       ExpandLevelSetStats* statsOut)
{
    using fast_sweeping_internal::dilationPattern;
    using fast_sweeping_internal::leafDomain;
    ExpandLevelSetStats stats;
    auto t0 = Clock::now();

    // ---- validate
    if (input.tree().activeVoxelCount() == 0) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' has no active voxels (an empty level set)");
    }
    if (!input.hasUniformVoxels()) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' has non-uniform voxels; a level set needs cubic voxels");
    }
    if (input.getGridClass() != openvdb::GRID_LEVEL_SET &&
        input.getGridClass() != openvdb::GRID_UNKNOWN) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' is not a level set (class " +
                                   openvdb::GridBase::gridClassToString(input.getGridClass()) + ")");
    }
    const double h = input.voxelSize()[0];
    const float inBackground = input.background();
    if (!(inBackground > 0) || !std::isfinite(inBackground)) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' has background " + formatDouble(inBackground) +
                                   "; a level set needs a positive background");
    }
    checkGridSpec(opt);
    checkWidth(opt.exteriorWidth, "exteriorWidth");
    if (!opt.fillInterior) checkWidth(opt.interiorWidth, "interiorWidth");
    checkWidth(opt.coverageMargin, "coverageMargin", true);
    checkWidth(opt.coverageMarginPerVoxel, "coverageMarginPerVoxel", true);
    checkWidth(opt.inputExteriorWidth, "inputExteriorWidth", true);
    checkWidth(opt.inputInteriorWidth, "inputInteriorWidth", true);
    if (opt.domain == ExpansionDomain::BoundingBox) checkWidth(opt.boundingBoxMargin, "boundingBoxMargin", true);
    if (!(opt.tolerance > 0) || !std::isfinite(opt.tolerance)) {
        throw InvalidArgumentError("expandLevelSet: tolerance must be finite and > 0, got " +
                                   formatDouble(opt.tolerance));
    }
    if (opt.maxIterations < 1) {
        throw InvalidArgumentError("expandLevelSet: maxIterations must be >= 1, got " +
                                   std::to_string(opt.maxIterations));
    }
    const double wExt = opt.widthInVoxels(opt.exteriorWidth, h);
    const double wInt = opt.fillInterior ? 0.0 : opt.widthInVoxels(opt.interiorWidth, h);
    const double bboxMargin = opt.widthInVoxels(opt.boundingBoxMargin, h);
    constexpr double kMaxWidth = 100000.0;
    for (double w : {wExt, wInt, bboxMargin}) {
        if (w > kMaxWidth) {
            throw ResourceLimitError("expandLevelSet: a width of " + formatDouble(w) +
                                     " voxels is beyond what fits in memory (limit " +
                                     formatDouble(kMaxWidth) + " voxels)");
        }
    }
    double w0Ext = opt.inputExteriorWidth > 0 ? opt.inputExteriorWidth
                   : readBandMeta(input, meta::kExteriorBandVoxels, inBackground / h);
    double w0Int = opt.inputInteriorWidth > 0 ? opt.inputInteriorWidth
                   : readBandMeta(input, meta::kInteriorBandVoxels, inBackground / h);
    w0Ext = std::max(0.0, w0Ext);
    w0Int = std::max(0.0, w0Int);
    stats.voxelSize = h;
    stats.inputExteriorWidth = w0Ext;
    stats.inputInteriorWidth = w0Int;
    stats.frozenVoxels = input.tree().activeVoxelCount();

    // ---- resource estimate before any allocation: a shell of the input's surface area
    const double area = double(stats.frozenVoxels) / std::max(1.0, w0Ext + w0Int);
    const bool vectorMethod = opt.method == ExpansionMethod::Vector;
    const double perVoxel = vectorMethod ? 0.0 : opt.coverageMarginPerVoxel;
    const double keepExt = wExt + opt.coverageMargin + perVoxel * std::max(0.0, wExt - w0Ext);
    const double keepInt = wInt + opt.coverageMargin + perVoxel * std::max(0.0, wInt - w0Int);
    stats.method = opt.method;
    const openvdb::CoordBBox inBox = input.evalActiveVoxelBoundingBox();
    double lowerEstimate = 0;
    if (opt.domain == ExpansionDomain::BoundingBox) {
        const double e = 2 * std::ceil(bboxMargin);
        lowerEstimate = (inBox.dim().x() + e) * (inBox.dim().y() + e) * (inBox.dim().z() + e);
    } else {
        lowerEstimate = area * (std::max(0.0, keepExt - w0Ext) + (opt.fillInterior ? 0.0 : std::max(0.0, keepInt - w0Int)));
        lowerEstimate += double(stats.frozenVoxels);
        // the ball of radius wExt around a surface point, less the object, is in the band
        const double r = wExt - 1.0;
        if (r > 0) {
            lowerEstimate = std::max(lowerEstimate,
                                     4.0 / 3.0 * M_PI * r * r * r - double(inBox.volume()));
        }
    }
    detail::checkVoxelBudget({"expand level set", "the expanded band", "a lower estimate before the dilation",
                              std::round(lowerEstimate), 0.0, opt.maxVoxels, "use narrower widths or a larger voxel size"});
    if (opt.interrupter) opt.interrupter->start("fast sweeping");
    progress_internal::check(opt.interrupter, 0);

    // ---- topology: flood-filled copy of the input, dilated Euclidean-completely
    FloatTree::Ptr tree(new FloatTree(input.tree()));
    openvdb::tools::signedFloodFill(*tree);
    openvdb::MaskTree::Ptr interior;
    if (opt.fillInterior) {
        openvdb::FloatGrid::Ptr tmp = openvdb::FloatGrid::create(tree);
        auto boolMask = openvdb::tools::sdfInteriorMask(*tmp, 0.0f);
        interior.reset(new openvdb::MaskTree(boolMask->tree(), false, openvdb::TopologyCopy()));
    }
    openvdb::MaskTree band(input.tree(), false, openvdb::TopologyCopy());
    band.voxelizeActiveTiles();
    if (opt.domain == ExpansionDomain::BoundingBox) {
        openvdb::CoordBBox box = inBox;
        box.expand(int(std::ceil(bboxMargin)));
        openvdb::MaskTree boxMask(false);
        boxMask.sparseFill(box, true, true);
        tree->topologyUnion(boxMask);
    } else {
        // (the candidates only need to hold every voxel with d < w; the margin is trimmed from)
        const double rExt = std::max(0.0, wExt - w0Ext + std::sqrt(3.0));
        const double rInt = opt.fillInterior ? 0.0 : std::max(0.0, wInt - w0Int + std::sqrt(3.0));
        const double rSmall = std::min(rExt, rInt), rLarge = std::max(rExt, rInt);
        auto dilated = [&](double r) {
            openvdb::MaskTree::Ptr m(new openvdb::MaskTree(band));
            int a = 0, b = 0;
            dilationPattern(r, a, b);
            if (r == rLarge) { stats.dilationCubeSteps = a; stats.dilationFaceSteps = b; }
            if (a > 0) openvdb::tools::dilateActiveValues(*m, a, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                                         openvdb::tools::IGNORE_TILES);
            progress_internal::check(opt.interrupter, 0);
            if (b > 0) openvdb::tools::dilateActiveValues(*m, b, openvdb::tools::NN_FACE,
                                                         openvdb::tools::IGNORE_TILES);
            progress_internal::check(opt.interrupter, 0);
            return m;
        };
        uint64_t domainLeaves = 0;
        openvdb::MaskTree::Ptr domain =
            vectorMethod ? nullptr : leafDomain(band, rLarge, domainLeaves);
        if (domain) {
            // Sweep: whole leaves, the values capped at the kept widths (see Sweeper)
            detail::checkVoxelBudget({"expand level set", "the candidate band",
                                      std::to_string(domainLeaves) + " leaf nodes", double(domainLeaves) * 512.0,
                                      0.0, opt.maxVoxels, "use narrower widths or a larger voxel size"});
            progress_internal::check(opt.interrupter, 0);
            tree->topologyUnion(*domain);
        } else {
            openvdb::MaskTree::Ptr large = dilated(rLarge);
            detail::checkVoxelBudget({"expand level set", "the dilated band", "", double(large->activeVoxelCount()),
                                      0.0, opt.maxVoxels, "use narrower widths or a larger voxel size"});
            tree->topologyUnion(*large);
            if (rSmall < rLarge) {
                // Keep the larger dilation only on the side that asked for it.
                openvdb::MaskTree::Ptr small = dilated(rSmall);
                const bool dropNegative = rInt < rExt; // interior is the small side
                openvdb::tree::LeafManager<FloatTree> lm(*tree);
                lm.foreach([&](LeafT& leaf, size_t) {
                    const openvdb::MaskTree::LeafNodeType* sl = small->probeConstLeaf(leaf.origin());
                    const openvdb::MaskTree::LeafNodeType* bl = band.probeConstLeaf(leaf.origin());
                    for (auto it = leaf.beginValueOn(); it; ++it) {
                        const openvdb::Index j = it.pos();
                        if ((sl && sl->isValueOn(j)) || (bl && bl->isValueOn(j))) continue;
                        const bool neg = *it < 0;
                        if (neg == dropNegative) leaf.setValueOff(j);
                    }
                });
            }
        }
    }
    if (interior) tree->topologyUnion(*interior);
    tree->voxelizeActiveTiles();
    stats.secondsTopology = secondsSince(t0);
    detail::checkVoxelBudget({"expand level set", "the expanded grid", "", double(tree->activeVoxelCount()), 0.0,
                              opt.maxVoxels, "use narrower widths or a larger voxel size"});
    progress_internal::check(opt.interrupter, 0);

    // ---- sweeps
    auto t1 = Clock::now();
    if (vectorMethod) {
        vector_expansion_internal::PropagationStats ps;
        stats.candidateVoxels = tree->activeVoxelCount();
        vector_expansion_internal::ShellVectors shell;
        shell.points = opt.closestPoints;
        if (opt.closestPoints && opt.closestTriangles && opt.mesh) {
            requireUsableMesh(*opt.mesh); // indices in range, finite points, not empty
            shell.triangles = opt.closestTriangles;
            shell.mesh = opt.mesh;
        }
        vector_expansion_internal::propagateClosestVectors(*tree, input.tree(), shell, input.transform(),
                                                           kBig, opt.interrupter, &ps);
        stats.refinedVoxels = ps.refinedVoxels;
        stats.walkSteps = ps.walkSteps;
        stats.refineEvaluations = ps.refineEvaluations;
        stats.refineRounds = ps.refineRounds;
        stats.secondsVectorSetup = ps.secondsSetup;
        stats.secondsVectorPasses = ps.secondsPasses;
        stats.secondsVectorFinish = ps.secondsFinish;
        stats.iterations = 1;
        stats.converged = true;
        stats.estimatedVectors = ps.estimatedVectors;
        stats.unreachedVoxels = ps.unreachedVoxels;
    } else {
        // values at or beyond the kept widths are trimmed afterwards: leave them unreached
        const bool capped = opt.domain == ExpansionDomain::Band;
        const float capPos = capped ? float(keepExt * h) : kBig;
        const float capNeg = capped && !opt.fillInterior ? float(keepInt * h) : kBig;
        fast_sweeping_internal::sweepLeaves(*tree, input.tree(), float(h), float(opt.tolerance * h), capPos, capNeg,
                                            opt.maxIterations, opt.interrupter, stats);
    }
    stats.secondsSweep = secondsSince(t1);

    // ---- finish: keep |φ| < width + margin, background, prune
    auto t2 = Clock::now();
    const bool box = opt.domain == ExpansionDomain::BoundingBox;
    const float keepExtW = float(keepExt * h), keepIntW = float(keepInt * h);
    float background = 0;
    {
        openvdb::tree::LeafManager<FloatTree> lm(*tree);
        // trim, and find the largest kept magnitude (for the box / fill modes)
        std::vector<float> leafMax(lm.leafCount(), 0.0f);
        lm.foreach([&](LeafT& leaf, size_t idx) {
            float mx = 0;
            for (auto it = leaf.beginValueOn(); it; ++it) {
                const float v = *it;
                const float a = std::abs(v);
                bool keep = a < kBig * 0.5f;
                if (keep && !box) keep = v < 0 ? (opt.fillInterior || a < keepIntW) : a < keepExtW;
                if (keep) mx = std::max(mx, a);
                else leaf.setValueOff(it.pos());
            }
            leafMax[idx] = mx;
        });
        float mx = 0;
        for (float m : leafMax) mx = std::max(mx, m);
        background = box || opt.fillInterior ? std::max({mx, keepExtW, float(h)})
                                             : std::max(keepExtW, keepIntW);
        if (opt.fillInterior && !box) background = std::max(background, keepExtW);
        // values just above the kept width must not exceed the background
        background = std::nextafter(background, std::numeric_limits<float>::max());
    }
    openvdb::tools::changeLevelSetBackground(*tree, background);
    openvdb::tools::pruneLevelSet(*tree);
    openvdb::FloatGrid::Ptr out = openvdb::FloatGrid::create(tree);
    out->setTransform(input.transform().copy());
    for (auto it = input.beginMeta(); it != input.endMeta(); ++it) {
        out->insertMeta(it->first, *it->second);
    }
    // The band is now complete (every voxel with |d| < width is active) to the target widths.
    const double bgVoxels = background / h;
    if (input.getMetadata<openvdb::FloatMetadata>(meta::kExteriorBandVoxels)) {
        out->insertMeta(meta::kExteriorBandVoxels,
                        openvdb::FloatMetadata(float(box ? bgVoxels : wExt)));
    }
    if (input.getMetadata<openvdb::FloatMetadata>(meta::kInteriorBandVoxels)) {
        out->insertMeta(meta::kInteriorBandVoxels,
                        openvdb::FloatMetadata(float(box || opt.fillInterior ? bgVoxels : wInt)));
    }
    out->setName(input.getName());
    out->setGridClass(openvdb::GRID_LEVEL_SET);
    stats.activeVoxels = out->activeVoxelCount();
    stats.secondsFinish = secondsSince(t2);
    if (opt.interrupter) { opt.interrupter->wasInterrupted(100); opt.interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return out;
}

} // namespace levelforge
