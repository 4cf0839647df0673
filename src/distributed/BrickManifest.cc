// SPDX-License-Identifier: Apache-2.0
// One file per rank (distributed/DistributedMeshToSdf.h): the names of the pieces and of the
// manifest, writing a piece, the manifest as JSON (written and read back with every field
// checked), and the merge of the pieces into the finished grid. No MPI here: `levelforge merge`
// runs anywhere.
#include "detail/AtomicFile.h"
#include "detail/MessageText.h"
#include "detail/ProgressCheck.h"
#include "detail/Timer.h"
#include "distributed/BrickUnion.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>

#include <nlohmann/json.hpp>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>
#include <unordered_set>

#include <unistd.h>

namespace fs = std::filesystem;

namespace levelforge {
namespace {

using Json = nlohmann::json;

/// The "format" of a manifest and the version this program writes and reads.
constexpr const char* kManifestFormat = "levelforge-pieces";
constexpr int kManifestVersion = 1;

std::string inQuotes(const std::string& s) { return "'" + s + "'"; }

/// The entries of an index-to-world matrix, row by row (16 numbers).
Json matrixJson(const openvdb::math::Transform& t)
{
    const openvdb::Mat4d m = t.baseMap()->getAffineMap()->getMat4();
    Json a = Json::array();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) a.push_back(m[r][c]);
    return a;
}

/// True when the two transforms have exactly the same index-to-world matrix.
bool sameMatrix(const openvdb::math::Transform& a, const openvdb::math::Transform& b)
{
    if (!a.isLinear() || !b.isLinear()) return a == b;
    const openvdb::Mat4d ma = a.baseMap()->getAffineMap()->getMat4(), mb = b.baseMap()->getAffineMap()->getMat4();
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            if (!(ma[r][c] == mb[r][c])) return false;
    return true;
}

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

/// Reads the manifest's fields, each checked; errors name the manifest and the field.
class Fields
{
public:
    explicit Fields(const std::string& path) : mPath(path) {}

    [[noreturn]] void fail(const std::string& what) const { throw IoError("manifest " + inQuotes(mPath) + ": " + what); }

    const Json& at(const Json& j, const std::string& key, const std::string& where) const
    {
        if (!j.is_object() || !j.contains(key)) fail("the field '" + where + key + "' is missing");
        return j.at(key);
    }
    std::string string(const Json& j, const std::string& key, const std::string& where = "") const
    {
        const Json& v = at(j, key, where);
        if (!v.is_string()) fail("the field '" + where + key + "' is not a string");
        return v.get<std::string>();
    }
    double number(const Json& j, const std::string& key, const std::string& where = "") const
    {
        const Json& v = at(j, key, where);
        if (!v.is_number()) fail("the field '" + where + key + "' is not a number");
        return v.get<double>();
    }
    int64_t integer(const Json& j, const std::string& key, int64_t lo, int64_t hi, const std::string& where = "") const
    {
        const Json& v = at(j, key, where);
        if (!v.is_number_integer() || v.get<int64_t>() < lo || v.get<int64_t>() > hi)
            fail("the field '" + where + key + "' is not an integer from " + std::to_string(lo) + " to " +
                 std::to_string(hi));
        return v.get<int64_t>();
    }
    uint64_t count(const Json& j, const std::string& key, const std::string& where = "") const
    {
        const Json& v = at(j, key, where);
        if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0))
            fail("the field '" + where + key + "' is not a count (an integer >= 0)");
        return v.get<uint64_t>();
    }
    bool flag(const Json& j, const std::string& key, const std::string& where = "") const
    {
        const Json& v = at(j, key, where);
        if (!v.is_boolean()) fail("the field '" + where + key + "' is not true or false");
        return v.get<bool>();
    }

private:
    std::string mPath;
};

} // namespace

std::string pieceFileName(const std::string& output, int rank)
{
    const fs::path p(output);
    char digits[32];
    std::snprintf(digits, sizeof(digits), ".rank%04d", rank);
    const std::string ext = p.has_extension() ? p.extension().string() : std::string(".vdb");
    const fs::path name = p.stem().string() + digits + ext;
    return p.has_parent_path() ? (p.parent_path() / name).string() : name.string();
}

std::string manifestFileName(const std::string& output) { return output + ".manifest.json"; }

std::string newPieceRunId()
{
    std::random_device rd;
    char buf[40];
    std::snprintf(buf, sizeof(buf), "%08x%08x%08x%08x", unsigned(rd()), unsigned(rd()), unsigned(rd()), unsigned(rd()));
    return buf;
}

BrickPiece writeBrickPiece(const std::string& path, const openvdb::FloatGrid& part, const std::string& id, int rank,
                           int ranks)
{
    // a grid sharing the part's tree and transform, with metadata of its own
    openvdb::FloatGrid::Ptr g = std::const_pointer_cast<openvdb::FloatGrid>(part.copy());
    g->insertMeta(kPieceOfMetadata, openvdb::StringMetadata(id));
    g->insertMeta(kPieceRankMetadata, openvdb::Int32Metadata(rank));
    g->insertMeta(kPieceRanksMetadata, openvdb::Int32Metadata(ranks));
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsAtomic(path, {g}, fileMeta);
    BrickPiece piece;
    piece.rank = rank;
    piece.file = fs::path(path).filename().string();
    piece.leaves = part.tree().leafCount();
    piece.activeVoxels = part.tree().activeVoxelCount();
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    piece.bytes = ec ? 0 : uint64_t(size);
    return piece;
}

void writeBrickManifest(const std::string& path, const BrickManifest& m)
{
    if (!m.transform) throw InvalidArgumentError("writeBrickManifest: no transform");
    Json j;
    j["format"] = kManifestFormat;
    j["version"] = kManifestVersion;
    j["id"] = m.id;
    j["generator"] = m.generator;
    j["output"] = m.output;
    j["ranks"] = m.ranks;
    j["brick_size"] = 1 << m.brickLog2;
    Json grid;
    grid["name"] = m.finish.gridName;
    grid["background"] = double(m.background);
    grid["voxel_size"] = m.finish.voxelSize;
    grid["index_to_world"] = matrixJson(*m.transform);
    grid["exterior_band_voxels"] = double(m.finish.exteriorBandVoxels);
    grid["interior_band_voxels"] = double(m.finish.interiorBandVoxels);
    grid["sign"] = toString(m.finish.sign);
    grid["fill_interior"] = m.finish.fillInterior;
    grid["source"] = m.finish.source;
    grid["method"] = m.finish.method;
    j["grid"] = grid;
    uint64_t bricks = 0, leaves = 0, active = 0, bytes = 0;
    Json pieces = Json::array();
    for (const BrickPiece& p : m.pieces) {
        Json e;
        e["rank"] = p.rank;
        e["file"] = p.file;
        e["leaves"] = p.leaves;
        e["active_voxels"] = p.activeVoxels;
        e["bytes"] = p.bytes;
        Json origins = Json::array();
        for (const openvdb::Coord& c : p.bricks) origins.push_back(Json::array({c.x(), c.y(), c.z()}));
        e["bricks"] = origins;
        pieces.push_back(e);
        bricks += p.bricks.size();
        leaves += p.leaves;
        active += p.activeVoxels;
        bytes += p.bytes;
    }
    j["totals"] = {{"bricks", bricks}, {"leaves", leaves}, {"active_voxels", active}, {"bytes", bytes}};
    j["pieces"] = pieces;
    // one field a line, one piece a line (a piece's bricks can be thousands of origins)
    auto dump = [](const Json& v) { return v.dump(-1, ' ', false, Json::error_handler_t::replace); };
    std::string text = "{\n";
    bool first = true;
    for (const auto& item : j.items()) {
        text += first ? "  " : ",\n  ";
        first = false;
        text += dump(Json(item.key())) + ": ";
        if (item.key() != "pieces") {
            text += dump(item.value());
            continue;
        }
        text += "[";
        for (size_t i = 0; i < item.value().size(); ++i) text += (i ? ",\n    " : "\n    ") + dump(item.value()[i]);
        text += "\n  ]";
    }
    text += "\n}\n";
    detail::writeTextAtomic(path, text);
}

BrickManifest readBrickManifest(const std::string& path)
{
    std::error_code ec;
    if (!fs::exists(path, ec)) throw IoError("cannot read manifest " + inQuotes(path) + ": no such file");
    if (!fs::is_regular_file(path, ec)) throw IoError("cannot read manifest " + inQuotes(path) + ": not a regular file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError("cannot read manifest " + inQuotes(path) + ": " + std::strerror(errno));
    Json j;
    try {
        j = Json::parse(in);
    } catch (const std::exception& e) {
        throw IoError("manifest " + inQuotes(path) + " is not valid JSON: " +
                      message_internal::cutDependencyMessage(e.what()));
    }
    const Fields f(path);
    if (!j.is_object() || !j.contains("format") || !j["format"].is_string() || j["format"] != kManifestFormat)
        f.fail(std::string("not a manifest of levelforge pieces (no \"format\": \"") + kManifestFormat + "\")");
    const int64_t version = f.integer(j, "version", 1, 1000000);
    if (version != kManifestVersion)
        f.fail("version " + std::to_string(version) + " is not one this levelforge reads (" +
               std::to_string(kManifestVersion) + ")");
    BrickManifest m;
    m.id = f.string(j, "id");
    if (m.id.empty()) f.fail("the field 'id' is empty");
    m.generator = f.string(j, "generator");
    m.output = f.string(j, "output");
    m.ranks = int(f.integer(j, "ranks", 1, 1 << 24));
    const int64_t brick = f.integer(j, "brick_size", 8, 4096);
    m.brickLog2 = 3;
    while ((int64_t(1) << m.brickLog2) < brick) ++m.brickLog2;
    if ((int64_t(1) << m.brickLog2) != brick) f.fail("the field 'brick_size' is not a power of two");
    const Json& grid = f.at(j, "grid", "");
    m.finish.gridName = f.string(grid, "name", "grid.");
    m.background = float(f.number(grid, "background", "grid."));
    m.finish.voxelSize = f.number(grid, "voxel_size", "grid.");
    if (!(m.finish.voxelSize > 0.0)) f.fail("the field 'grid.voxel_size' is not > 0");
    const Json& mat = f.at(grid, "index_to_world", "grid.");
    if (!mat.is_array() || mat.size() != 16) f.fail("the field 'grid.index_to_world' is not 16 numbers");
    openvdb::Mat4d m4;
    for (int k = 0; k < 16; ++k) {
        if (!mat[size_t(k)].is_number()) f.fail("the field 'grid.index_to_world' is not 16 numbers");
        m4[k / 4][k % 4] = mat[size_t(k)].get<double>();
    }
    const double det = m4.getMat3().det();
    if (!std::isfinite(det) || !(std::abs(det) > 0.0) || m4[0][3] != 0.0 || m4[1][3] != 0.0 || m4[2][3] != 0.0 ||
        m4[3][3] != 1.0)
        f.fail("the field 'grid.index_to_world' is not an invertible affine matrix");
    for (int k = 0; k < 16; ++k)
        if (!std::isfinite(m4[k / 4][k % 4])) f.fail("the field 'grid.index_to_world' has a non-finite entry");
    m.transform = openvdb::math::Transform::createLinearTransform(m4);
    m.finish.exteriorBandVoxels = float(f.number(grid, "exterior_band_voxels", "grid."));
    m.finish.interiorBandVoxels = float(f.number(grid, "interior_band_voxels", "grid."));
    const std::string sign = f.string(grid, "sign", "grid.");
    if (sign != toString(SignMode::Pseudonormal) && sign != toString(SignMode::Unsigned))
        f.fail("the field 'grid.sign' is '" + sign + "', not pseudonormal or unsigned");
    m.finish.sign = signModeFromString(sign);
    m.finish.fillInterior = f.flag(grid, "fill_interior", "grid.");
    m.finish.source = f.string(grid, "source", "grid.");
    m.finish.method = f.string(grid, "method", "grid.");
    const Json& pieces = f.at(j, "pieces", "");
    if (!pieces.is_array()) f.fail("the field 'pieces' is not a list");
    if (pieces.size() != size_t(m.ranks))
        f.fail("'ranks' is " + std::to_string(m.ranks) + " but " + std::to_string(pieces.size()) +
               (pieces.size() == 1 ? " piece is" : " pieces are") + " listed");
    std::set<std::string> files;
    std::set<openvdb::Coord> bricks;
    for (size_t i = 0; i < pieces.size(); ++i) {
        const std::string where = "pieces[" + std::to_string(i) + "].";
        const Json& e = pieces[i];
        BrickPiece p;
        p.rank = int(f.integer(e, "rank", 0, m.ranks - 1, where));
        if (p.rank != int(i)) f.fail("piece " + std::to_string(i) + " is rank " + std::to_string(p.rank) + "'s (listed in rank order)");
        p.file = f.string(e, "file", where);
        if (p.file.empty()) f.fail("the field '" + where + "file' is empty");
        if (!files.insert(p.file).second) f.fail("two pieces are the file " + inQuotes(p.file));
        p.leaves = f.count(e, "leaves", where);
        p.activeVoxels = f.count(e, "active_voxels", where);
        p.bytes = f.count(e, "bytes", where);
        const Json& origins = f.at(e, "bricks", where);
        if (!origins.is_array()) f.fail("the field '" + where + "bricks' is not a list");
        for (const Json& o : origins) {
            if (!o.is_array() || o.size() != 3 || !o[0].is_number_integer() || !o[1].is_number_integer() ||
                !o[2].is_number_integer())
                f.fail("the field '" + where + "bricks' holds something other than [x, y, z] origins");
            const openvdb::Coord c(o[0].get<int>(), o[1].get<int>(), o[2].get<int>());
            if ((c.x() & (brick - 1)) || (c.y() & (brick - 1)) || (c.z() & (brick - 1)))
                f.fail("the field '" + where + "bricks' holds an origin that is not a multiple of the brick size");
            if (!bricks.insert(c).second) f.fail("two pieces list the same brick");
            p.bricks.push_back(c);
        }
        m.pieces.push_back(std::move(p));
    }
    return m;
}

openvdb::FloatGrid::Ptr mergeBrickPieces(const std::string& manifestPath, const MergeOptions& options,
                                         MergeStats* statsOut)
{
    const auto t0 = detail::Clock::now();
    openvdb::initialize();
    const BrickManifest m = readBrickManifest(manifestPath);
    const fs::path folder = fs::path(manifestPath).parent_path();
    MergeStats st;
    distributed_internal::BrickUnion u(m.finish);
    double secondsRead = 0.0;
    for (const BrickPiece& p : m.pieces) {
        progress_internal::check(options.interrupter, int(100 * p.rank / m.ranks));
        const std::string file = fs::path(p.file).is_absolute() ? p.file : (folder / p.file).string();
        const std::string name = "piece " + inQuotes(file) + " (rank " + std::to_string(p.rank) + " of manifest " +
                                 inQuotes(manifestPath) + ")";
        auto bad = [&](const std::string& why) { throw IoError(name + ": " + why); };
        std::error_code ec;
        if (!fs::exists(file, ec)) bad("no such file");
        const auto size = fs::file_size(file, ec);
        if (!ec && uint64_t(size) != p.bytes)
            bad("the file is " + std::to_string(size) + " bytes, the manifest says " + std::to_string(p.bytes) +
                " (a piece of another run, or a damaged file)");
        const auto tr = detail::Clock::now();
        openvdb::GridPtrVecPtr grids;
        try {
            grids = readGrids(file);
        } catch (const IoError& e) {
            bad(e.what());
        }
        secondsRead += detail::secondsSince(tr);
        openvdb::FloatGrid::Ptr g =
            grids->size() == 1 ? openvdb::gridPtrCast<openvdb::FloatGrid>(grids->front()) : openvdb::FloatGrid::Ptr();
        grids.reset();
        if (!g) bad("not a piece (it does not hold exactly one float grid)");
        const auto id = g->getMetadata<openvdb::StringMetadata>(kPieceOfMetadata);
        const auto rank = g->getMetadata<openvdb::Int32Metadata>(kPieceRankMetadata);
        const auto ranks = g->getMetadata<openvdb::Int32Metadata>(kPieceRanksMetadata);
        if (!id || !rank || !ranks) bad("not a piece (no levelforge:piece_of metadata)");
        if (id->value() != m.id)
            bad("not a piece of this manifest: it belongs to the run " + id->value() + ", the manifest to " + m.id);
        if (rank->value() != p.rank || ranks->value() != m.ranks)
            bad("it is rank " + std::to_string(rank->value()) + " of " + std::to_string(ranks->value()) +
                "'s piece, the manifest lists it as rank " + std::to_string(p.rank) + " of " + std::to_string(m.ranks));
        if (!sameMatrix(g->transform(), *m.transform)) bad("its transform is not the manifest's");
        if (!sameBits(g->background(), m.background)) bad("its background is not the manifest's");
        if (g->tree().activeTileCount() != 0) bad("it holds active tiles (a piece holds leaves only)");
        const uint64_t leaves = g->tree().leafCount(), active = g->tree().activeVoxelCount();
        if (leaves != p.leaves || active != p.activeVoxels)
            bad("it holds " + std::to_string(leaves) + " leaves and " + std::to_string(active) +
                " active voxels, the manifest says " + std::to_string(p.leaves) + " and " +
                std::to_string(p.activeVoxels));
        const std::unordered_set<openvdb::Coord> bricks(p.bricks.begin(), p.bricks.end());
        const int mask = ~((1 << m.brickLog2) - 1);
        for (auto it = g->tree().cbeginLeaf(); it; ++it) {
            const openvdb::Coord o = it->origin();
            if (!bricks.count(openvdb::Coord(o.x() & mask, o.y() & mask, o.z() & mask))) {
                std::ostringstream os;
                os << "it holds the leaf at " << o << ", outside its rank's bricks";
                bad(os.str());
            }
        }
        try {
            u.add(*g, name);
        } catch (const InvalidArgumentError& e) {
            throw IoError(e.what());
        }
        ++st.pieces;
        st.leaves += leaves;
        st.activeVoxels += active;
        st.bytesRead += p.bytes;
    }
    progress_internal::check(options.interrupter, 100);
    const auto tf = detail::Clock::now();
    MeshToSdfStats fin;
    openvdb::FloatGrid::Ptr grid = u.finish(&fin);
    st.filledVoxels = fin.filledVoxels;
    st.activeVoxels = grid->activeVoxelCount();
    st.secondsFinish = detail::secondsSince(tf);
    st.secondsRead = secondsRead;
    st.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = st;
    return grid;
}

} // namespace levelforge
