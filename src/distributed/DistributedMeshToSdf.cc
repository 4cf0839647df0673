// SPDX-License-Identifier: Apache-2.0
// One conversion in bricks: the decomposition, one rank's part, the merge and finish, and the
// byte form of a part (distributed/DistributedMeshToSdf.h). No MPI here: the MPI side is
// MpiDistributedMeshToSdf.cc (NoMpi.cc without MPI).
#include "mesh/MeshToLevelSetInternal.h"
#include "mesh/WindingSignInternal.h"
#include "distributed/BrickUnion.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/core/MeshValidation.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/VdbIO.h>

#include <openvdb/io/Stream.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <sstream>
#include <streambuf>

namespace levelforge {
namespace {

/// Weights are summed in fixed point (1/1024 voxel), so that the sums, and the decomposition,
/// do not depend on the order TBB adds them in: every rank gets the same bricks.
constexpr double kWeightUnit = 1024.0;

uint64_t mortonKey(const openvdb::Coord& c, const openvdb::Coord& lo)
{
    uint64_t key = 0;
    const uint64_t v[3] = {uint64_t(c.x() - lo.x()), uint64_t(c.y() - lo.y()), uint64_t(c.z() - lo.z())};
    for (int bit = 20; bit >= 0; --bit)
        for (int k = 0; k < 3; ++k) key = (key << 1) | ((v[k] >> bit) & 1u);
    return key;
}

std::string notYet(const std::string& what)
{
    return "--distributed supports --method chang, --expansion none and the pseudonormal or unsigned sign (auto on "
           "a closed, consistently oriented mesh), with or without --fill-interior; not yet " + what +
           " (docs/distributed.md)";
}

/// The voxel size and the final band widths (voxels, held in float) as meshToSdf() resolves them.
struct Widths
{
    double h;
    float exterior, interior;
};

Widths resolveWidths(const TriangleMesh& mesh, const MeshToSdfOptions& o)
{
    Widths w;
    w.h = resolveVoxelSize(mesh, o);
    w.exterior = static_cast<float>(o.widthInVoxels(o.exteriorWidth, w.h));
    w.interior = static_cast<float>(o.widthInVoxels(o.interiorWidth, w.h));
    return w;
}

} // namespace

std::vector<openvdb::CoordBBox> BrickDecomposition::boxesOf(int rank) const
{
    std::vector<openvdb::CoordBBox> out;
    const int w = 1 << brickLog2;
    for (size_t i = 0; i < origins.size(); ++i)
        if (owner[i] == rank) out.emplace_back(origins[i], origins[i] + openvdb::Coord(w - 1));
    return out;
}

double BrickDecomposition::loadOf(int rank) const
{
    double s = 0.0;
    for (size_t i = 0; i < origins.size(); ++i)
        if (owner[i] == rank) s += weights[i];
    return s;
}

BrickDecomposition decomposeIntoBricks(const TriangleMesh& mesh, double h, double limit, int ranks, int brickLog2)
{
    if (ranks < 1) throw InvalidArgumentError("the number of ranks must be at least 1, got " + std::to_string(ranks));
    if (brickLog2 < 3 || brickLog2 > 12)
        throw InvalidArgumentError("the brick width must be a power of two from 8 to 4096 voxels, got 2^" +
                                   std::to_string(brickLog2));
    if (!(h > 0.0 && std::isfinite(h)) || !(limit >= 0.0 && std::isfinite(limit)))
        throw InvalidArgumentError("decomposeIntoBricks: bad voxel size or band limit");
    const double W = double(1 << brickLog2);
    // Per thread: brick → fixed-point weight. Each triangle: its band's volume, spread over the
    // bricks its box dilated by the limit touches, in proportion to the overlap.
    using Map = std::map<openvdb::Coord, uint64_t>;
    tbb::enumerable_thread_specific<Map> maps;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.triangles.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
        Map& m = maps.local();
        for (size_t t = r.begin(); t != r.end(); ++t) {
            const Vec3I& tri = mesh.triangles[t];
            const Vec3d a = mesh.points[tri[0]] / h, b = mesh.points[tri[1]] / h, c = mesh.points[tri[2]] / h;
            const double area = 0.5 * (b - a).cross(c - a).length();
            // the band on both sides of the triangle (neighbours share the rims: no caps), and a
            // voxel for the triangle's own cost in the hierarchy
            const double volume = 2.0 * limit * area + 1.0;
            double lo[3], hi[3];
            int blo[3], bhi[3];
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min({a[k], b[k], c[k]}) - limit;
                hi[k] = std::max({a[k], b[k], c[k]}) + limit;
                if (!(std::isfinite(lo[k]) && std::isfinite(hi[k]) && std::abs(lo[k]) < 1e9 && std::abs(hi[k]) < 1e9))
                    throw InvalidMeshError((mesh.source.empty() ? std::string("mesh") : mesh.source) + ": triangle " +
                                           std::to_string(t) + " has coordinates out of range at this voxel size");
                blo[k] = int(std::floor((lo[k] + 0.5) / W));
                bhi[k] = int(std::floor((hi[k] + 0.5) / W));
            }
            const double boxVolume = std::max(1e-300, (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]));
            for (int x = blo[0]; x <= bhi[0]; ++x)
                for (int y = blo[1]; y <= bhi[1]; ++y)
                    for (int z = blo[2]; z <= bhi[2]; ++z) {
                        const int bc[3] = {x, y, z};
                        double overlap = 1.0;
                        for (int k = 0; k < 3; ++k) {
                            const double s = std::max(lo[k], bc[k] * W - 0.5), e = std::min(hi[k], (bc[k] + 1) * W - 0.5);
                            overlap *= std::max(0.0, e - s);
                        }
                        const bool single = blo[0] == bhi[0] && blo[1] == bhi[1] && blo[2] == bhi[2];
                        const double share = single ? volume : volume * overlap / boxVolume;
                        const uint64_t q = uint64_t(std::llround(share * kWeightUnit));
                        if (q) m[openvdb::Coord(x * (1 << brickLog2), y * (1 << brickLog2), z * (1 << brickLog2))] += q;
                    }
        }
    });
    Map all;
    for (const Map& m : maps)
        for (const auto& [k, v] : m) all[k] += v;

    BrickDecomposition d;
    d.brickLog2 = brickLog2;
    d.ranks = ranks;
    if (all.empty()) return d;
    openvdb::Coord lo = all.begin()->first;
    for (const auto& kv : all) lo.minComponent(kv.first);
    lo = openvdb::Coord(lo.x() >> brickLog2, lo.y() >> brickLog2, lo.z() >> brickLog2);
    std::vector<std::pair<uint64_t, std::pair<openvdb::Coord, uint64_t>>> order;
    order.reserve(all.size());
    for (const auto& [origin, w] : all) {
        const openvdb::Coord c(origin.x() >> brickLog2, origin.y() >> brickLog2, origin.z() >> brickLog2);
        order.push_back({mortonKey(c, lo), {origin, w}});
    }
    std::sort(order.begin(), order.end());
    unsigned __int128 total = 0;
    for (const auto& e : order) total += e.second.second;
    // brick i goes to the rank whose share of the total holds the middle of its weight
    unsigned __int128 before = 0;
    for (const auto& e : order) {
        const uint64_t w = e.second.second;
        const unsigned __int128 mid2 = 2 * before + w; // twice the middle
        int r = int(mid2 * unsigned(ranks) / (2 * total));
        r = std::min(r, ranks - 1);
        d.origins.push_back(e.second.first);
        d.weights.push_back(double(w) / kWeightUnit);
        d.owner.push_back(r);
        before += w;
    }
    return d;
}

SignMode checkDistributable(const TriangleMesh& mesh, const MeshToSdfOptions& o)
{
    if (o.method != BandMethod::Chang) throw InvalidArgumentError(notYet("--method scan"));
    if (o.expansion != Expansion::None)
        throw InvalidArgumentError(notYet(std::string("--expansion ") +
                                          (o.expansion == Expansion::Sweep ? "sweep" : "vector") +
                                          " (an expansion across bricks needs a halo exchange)"));
    if (o.transform) throw InvalidArgumentError(notYet("--reference (a reference grid's transform)"));
    if (!o.fogGridName.empty()) throw InvalidArgumentError(notYet("--fog-grid"));
    if (!o.primitiveIndexGridName.empty()) throw InvalidArgumentError(notYet("--primitive-index-grid"));
    if (!o.attributes.empty()) throw InvalidArgumentError(notYet("--attribute"));
    MeshToLevelSetOptions mo;
    mo.sign = o.sign;
    mo.validation = o.validation;
    std::string reason;
    if (o.sign == SignMode::Auto) requireUsableMesh(mesh);
    const SignMode sign = meshtols_internal::resolveSignMode(mesh, mo, reason);
    if (sign == SignMode::Winding)
        throw InvalidArgumentError(notYet("the winding-number sign (" + reason +
                                          "; its tile signs are a pass over the whole tree)"));
    if (sign == SignMode::Unsigned && o.fillInterior)
        throw InvalidArgumentError("fill interior needs an inside: it cannot be combined with the unsigned sign mode");
    return sign;
}

openvdb::FloatGrid::Ptr meshToSdfBricks(const TriangleMesh& mesh, const MeshToSdfOptions& o,
                                        const std::vector<openvdb::CoordBBox>& boxes, MeshToSdfStats* statsOut)
{
    const auto t0 = detail::Clock::now();
    checkDistributable(mesh, o);
    // as meshToSdf(): the same report for Auto, the same band settings
    MeshReport localReport;
    const MeshReport* report = o.validation;
    if (o.sign == SignMode::Auto && !report) {
        localReport = validateMesh(mesh);
        report = &localReport;
    }
    const Widths w = resolveWidths(mesh, o);
    MeshToLevelSetOptions mo;
    static_cast<GridSpec&>(mo) = o;
    mo.voxelSize = w.h;
    mo.voxelCount = 0;
    mo.units = WidthUnits::Voxels;
    mo.exteriorWidth = w.exterior;
    mo.interiorWidth = w.interior;
    mo.sign = o.sign;
    mo.validation = report;
    mo.windingAccuracy = o.windingAccuracy;
    mo.device = o.device;
    mo.deviceMemoryBudget = o.deviceMemoryBudget;
    mo.fillInterior = false; // on the union: finishBrickUnion()
    mo.onlyLeavesIn = &boxes;
    MeshToSdfStats stats;
    openvdb::FloatGrid::Ptr grid = meshToLevelSet(mesh, mo, &stats.band);
    stats.sign = stats.band.sign;
    stats.signReason = stats.band.signReason;
    stats.voxelSize = w.h;
    stats.exteriorBandVoxels = w.exterior;
    stats.interiorBandVoxels = w.interior;
    stats.method = "chang2008-exact-band";
    stats.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = stats;
    return grid;
}

namespace {
/// The finish of a conversion of @p mesh with @p o whose parts were made with sign @p sign.
BrickFinish finishWithSign(const TriangleMesh& mesh, const MeshToSdfOptions& o, SignMode sign)
{
    BrickFinish f;
    f.sign = sign;
    const Widths w = resolveWidths(mesh, o);
    f.voxelSize = w.h;
    f.exteriorBandVoxels = w.exterior;
    f.interiorBandVoxels = w.interior;
    f.fillInterior = o.fillInterior;
    f.gridName = o.gridName;
    f.source = o.source.empty() ? mesh.source : o.source;
    return f;
}
} // namespace

BrickFinish brickFinishFor(const TriangleMesh& mesh, const MeshToSdfOptions& o)
{
    return finishWithSign(mesh, o, checkDistributable(mesh, o));
}

namespace distributed_internal {

void BrickUnion::add(openvdb::FloatGrid& g, const std::string& what)
{
    using FloatLeaf = openvdb::FloatTree::LeafNodeType;
    const auto sign = g.getMetadata<openvdb::StringMetadata>(kSignMetadata);
    const std::string signName = sign ? sign->value() : std::string();
    if (!mTree) {
        if (signName != toString(mFinish.sign))
            throw InvalidArgumentError(what + " was made with the sign '" + signName + "', not '" +
                                       toString(mFinish.sign) + "'");
        mFirst = what;
        mBackground = g.background();
        mTransform = g.transform().copy();
        // the first part's tree is the base when it holds leaves only (a part as
        // meshToSdfBricks() makes it: inactive background tiles): the other parts' leaves move in
        if (g.tree().activeTileCount() == 0) {
            mTree = g.treePtr();
            g.setTree(std::make_shared<openvdb::FloatTree>(mBackground));
            return;
        }
        mTree = std::make_shared<openvdb::FloatTree>(mBackground);
    } else if (g.background() != mBackground || g.transform() != *mTransform || signName != toString(mFinish.sign)) {
        throw InvalidArgumentError(what + " has another background, transform or sign than " + mFirst);
    }
    std::vector<FloatLeaf*> leaves;
    g.tree().stealNodes(leaves);
    std::vector<std::unique_ptr<FloatLeaf>> owned(leaves.begin(), leaves.end());
    for (auto& leaf : owned) {
        if (mTree->probeConstLeaf(leaf->origin())) {
            std::ostringstream os;
            os << what << " holds the leaf at " << leaf->origin() << ", which an earlier part holds too";
            throw InvalidArgumentError(os.str());
        }
        mTree->addLeaf(leaf.get());
        (void)leaf.release();
    }
    g.setTree(std::make_shared<openvdb::FloatTree>(mBackground));
}

uint64_t BrickUnion::leafCount() const { return mTree ? uint64_t(mTree->leafCount()) : 0; }

openvdb::FloatGrid::Ptr BrickUnion::finish(MeshToSdfStats* statsOut)
{
    const auto t0 = detail::Clock::now();
    if (!mTree) throw InvalidArgumentError("finishBrickUnion: no parts");
    const BrickFinish& f = mFinish;
    openvdb::FloatTree::Ptr tree = std::move(mTree);
    // as meshToLevelSet() finishes its tree, then as meshToSdf() stamps it
    uint64_t filled = 0;
    if (f.sign == SignMode::Pseudonormal) openvdb::tools::signedFloodFill(*tree);
    if (f.fillInterior) filled = winding_internal::activateInterior(*tree);
    auto grid = openvdb::FloatGrid::create(tree);
    grid->setTransform(mTransform);
    grid->setName(f.gridName);
    stampLevelSetMetadata(*grid, f.exteriorBandVoxels, f.interiorBandVoxels, f.source, f.method);
    if (f.sign == SignMode::Unsigned) grid->setGridClass(openvdb::GRID_UNKNOWN);
    grid->insertMeta(kSignMetadata, openvdb::StringMetadata(toString(f.sign)));
    if (f.fillInterior) grid->insertMeta(kFillInteriorMetadata, openvdb::BoolMetadata(true));
    if (statsOut) {
        statsOut->sign = f.sign;
        statsOut->voxelSize = f.voxelSize;
        statsOut->exteriorBandVoxels = f.exteriorBandVoxels;
        statsOut->interiorBandVoxels = f.interiorBandVoxels;
        statsOut->method = f.method;
        statsOut->filledVoxels = filled;
        statsOut->seconds = detail::secondsSince(t0);
    }
    return grid;
}

} // namespace distributed_internal

openvdb::FloatGrid::Ptr finishBrickUnion(const BrickFinish& finish, std::vector<openvdb::FloatGrid::Ptr>& parts,
                                         MeshToSdfStats* statsOut)
{
    if (parts.empty() || !parts[0]) throw InvalidArgumentError("finishBrickUnion: no parts");
    distributed_internal::BrickUnion u(finish);
    for (size_t p = 0; p < parts.size(); ++p) {
        if (!parts[p]) throw InvalidArgumentError("finishBrickUnion: part " + std::to_string(p) + " is missing");
        u.add(*parts[p], "finishBrickUnion: part " + std::to_string(p));
        parts[p].reset(); // released as they are merged
    }
    return u.finish(statsOut);
}

openvdb::FloatGrid::Ptr finishBrickUnion(const TriangleMesh& mesh, const MeshToSdfOptions& o,
                                         std::vector<openvdb::FloatGrid::Ptr>& parts, MeshToSdfStats* statsOut)
{
    if (parts.empty() || !parts[0]) throw InvalidArgumentError("finishBrickUnion: no parts");
    // the sign the parts were made with (checkDistributable() resolved Auto when they were made)
    const SignMode sign = signModeFromString(parts[0]->metaValue<std::string>(kSignMetadata));
    return finishBrickUnion(finishWithSign(mesh, o, sign), parts, statsOut);
}

// A part's bytes: OpenVDB's io::Stream of the one grid (uncompressed, no statistics metadata),
// then a trailer: "LFPART01" and the stream's length (a part cut short is an error, not a
// smaller grid). The stream writes straight into the string, and reads straight from it: no copy
// of a part is ever made (parts are as large as the band).
constexpr char kTrailer[8] = {'L', 'F', 'P', 'A', 'R', 'T', '0', '1'};

namespace {

/// Appends what is written to a string.
class StringSink : public std::streambuf
{
public:
    explicit StringSink(std::string& s) : mS(s) {}

protected:
    int_type overflow(int_type c) override
    {
        if (c != traits_type::eof()) mS.push_back(char(c));
        return c;
    }
    std::streamsize xsputn(const char* p, std::streamsize n) override
    {
        mS.append(p, size_t(n));
        return n;
    }

private:
    std::string& mS;
};

/// Reads the first n bytes of a buffer in place.
class MemorySource : public std::streambuf
{
public:
    MemorySource(const char* p, size_t n)
    {
        char* b = const_cast<char*>(p); // read only: the get area is never written
        setg(b, b, b + n);
    }
};

} // namespace

std::string serializeGrid(const openvdb::FloatGrid& grid)
{
    std::string bytes;
    // about the leaves' values, masks and headers, and room for the rest: one allocation
    bytes.reserve(size_t(grid.tree().leafCount()) * (512 * sizeof(float) + 64 + 32) + (size_t(1) << 20));
    {
        StringSink sink(bytes);
        std::ostream os(&sink);
        openvdb::io::Stream stream(os);
        stream.setCompression(openvdb::io::COMPRESS_NONE);
        stream.setGridStatsMetadataEnabled(false);
        openvdb::GridCPtrVec grids{grid.copyGrid()};
        stream.write(grids);
        os.flush();
        if (!os) throw IoError("a part could not be serialized");
    }
    const uint64_t n = bytes.size();
    bytes.append(kTrailer, sizeof(kTrailer));
    bytes.append(reinterpret_cast<const char*>(&n), sizeof(n));
    return bytes;
}

openvdb::FloatGrid::Ptr deserializeGrid(const std::string& bytes)
{
    const size_t tail = sizeof(kTrailer) + sizeof(uint64_t);
    uint64_t n = 0;
    if (bytes.size() >= tail) std::memcpy(&n, bytes.data() + bytes.size() - sizeof(n), sizeof(n));
    if (bytes.size() < tail || std::memcmp(bytes.data() + bytes.size() - tail, kTrailer, sizeof(kTrailer)) != 0 ||
        n != bytes.size() - tail)
        throw IoError("a rank's part is cut short or is not a part (" + std::to_string(bytes.size()) + " bytes)");
    openvdb::GridPtrVecPtr grids;
    try {
        MemorySource source(bytes.data(), size_t(n));
        std::istream is(&source);
        openvdb::io::Stream stream(is);
        grids = stream.getGrids();
    } catch (const std::exception& e) {
        throw IoError(std::string("a rank's part could not be read back (") + std::to_string(bytes.size()) +
                      " bytes): " + e.what());
    }
    if (!grids || grids->size() != 1 || !openvdb::gridPtrCast<openvdb::FloatGrid>(grids->front()))
        throw IoError("a rank's part is not one float grid (" + std::to_string(bytes.size()) + " bytes)");
    return openvdb::gridPtrCast<openvdb::FloatGrid>(grids->front());
}

} // namespace levelforge
