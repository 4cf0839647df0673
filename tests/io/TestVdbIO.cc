// SPDX-License-Identifier: Apache-2.0
// Tests for VdbIO.h: atomic writes, reading with clear errors, level-set metadata.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include "detail/MessageText.h"
#include "io/VdbHeaderCheck.h"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using levelforge_test::scratchDir;

namespace {

/// A small level-set-like FloatGrid: a few voxels set by hand (no template-heavy tools).
openvdb::FloatGrid::Ptr makeGrid(const std::string& name = "surface", double voxelSize = 0.1)
{
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(/*background=*/0.3f);
    grid->setName(name);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
    auto acc = grid->getAccessor();
    for (int i = -3; i <= 3; ++i) {
        for (int j = -3; j <= 3; ++j) acc.setValue(openvdb::Coord(i, j, 0), 0.1f * float(i + j));
    }
    return grid;
}

std::vector<std::string> listDir(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename());
    return names;
}

std::string readText(const fs::path& path)
{
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

} // namespace

TEST(VdbIO, AtomicWriteLeavesOnlyTheFile)
{
    const fs::path dir = scratchDir("vdbio_atomic");
    const std::string path = (dir / "out.vdb").string();
    levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{makeGrid()});
    EXPECT_TRUE(fs::is_regular_file(path));
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.vdb"});

    // Overwriting an existing file replaces it, again with no temporary left behind.
    levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{makeGrid("second")});
    EXPECT_EQ(listDir(dir), std::vector<std::string>{"out.vdb"});
    const auto grids = levelforge::readGrids(path);
    ASSERT_EQ(grids->size(), 1u);
    EXPECT_EQ((*grids)[0]->getName(), "second");
}

TEST(VdbIO, FailureIntoMissingDirectoryLeavesNothing)
{
    const fs::path dir = scratchDir("vdbio_missing_dir");
    const std::string path = (dir / "no" / "such" / "dir" / "out.vdb").string();
    try {
        levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{makeGrid()});
        FAIL() << "expected IoError";
    } catch (const levelforge::IoError& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(path));
    EXPECT_TRUE(listDir(dir).empty());
}

TEST(VdbIO, FailureUnderARegularFileOrOntoADirectory)
{
    const fs::path dir = scratchDir("vdbio_not_dir");
    { std::ofstream(dir / "file.txt") << "not a directory\n"; }
    const std::string under = (dir / "file.txt" / "out.vdb").string();
    EXPECT_THROW(levelforge::writeGridsAtomic(under, openvdb::GridPtrVec{makeGrid()}),
                 levelforge::IoError);
    fs::create_directory(dir / "adir");
    EXPECT_THROW(levelforge::writeGridsAtomic((dir / "adir").string(),
                                              openvdb::GridPtrVec{makeGrid()}),
                 levelforge::IoError);
    EXPECT_EQ(readText(dir / "file.txt"), "not a directory\n");
    std::vector<std::string> names = listDir(dir);
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"adir", "file.txt"}));
    EXPECT_TRUE(listDir(dir / "adir").empty());
}

TEST(VdbIO, RoundTripWithMetadata)
{
    const fs::path dir = scratchDir("vdbio_roundtrip");
    const std::string path = (dir / "meta.vdb").string();
    auto grid = makeGrid("surface", 0.25);
    levelforge::stampLevelSetMetadata(*grid, 3.0, 2.5, "meshes/bunny.obj", "test-method");
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata("unit test"));
    levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{grid}, fileMeta);

    const auto grids = levelforge::readGrids(path);
    ASSERT_EQ(grids->size(), 1u);
    auto back = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[0]);
    ASSERT_TRUE(back);
    EXPECT_EQ(back->getName(), "surface");
    EXPECT_EQ(back->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_DOUBLE_EQ(back->voxelSize()[0], 0.25);
    EXPECT_FLOAT_EQ(back->background(), 0.3f);
    EXPECT_EQ(back->activeVoxelCount(), grid->activeVoxelCount());
    EXPECT_FLOAT_EQ(back->tree().getValue(openvdb::Coord(2, 3, 0)), 0.5f);
    EXPECT_FLOAT_EQ(back->metaValue<float>("levelforge:exterior_band_voxels"), 3.0f);
    EXPECT_FLOAT_EQ(back->metaValue<float>("levelforge:interior_band_voxels"), 2.5f);
    EXPECT_EQ(back->metaValue<std::string>("levelforge:source"), "meshes/bunny.obj");
    EXPECT_EQ(back->metaValue<std::string>("levelforge:method"), "test-method");
    EXPECT_EQ(back->metaValue<std::string>("levelforge:generator"),
              levelforge::generatorString());
    EXPECT_EQ(levelforge::generatorString().rfind("levelforge ", 0), 0u);
    if (openvdb::io::Archive::hasBloscCompression()) {
        const auto compression = back->metaValue<std::string>("file_compression");
        EXPECT_NE(compression.find("blosc"), std::string::npos) << compression;
    }
}

TEST(VdbIO, ReadErrorsNameTheFile)
{
    const fs::path dir = scratchDir("vdbio_read_errors");
    auto expectIoError = [](const std::string& path, const std::string& what) {
        try {
            levelforge::readGrids(path);
            ADD_FAILURE() << "expected IoError for " << what;
        } catch (const levelforge::IoError& e) {
            EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        }
    };
    expectIoError((dir / "missing.vdb").string(), "a missing file");
    expectIoError(dir.string(), "a directory");
    { std::ofstream(dir / "text.vdb") << "this is not a vdb file\n"; }
    expectIoError((dir / "text.vdb").string(), "a text file");
    { std::ofstream(dir / "empty.vdb"); }
    expectIoError((dir / "empty.vdb").string(), "an empty file");

    // A real file cut short.
    const fs::path good = dir / "good.vdb";
    levelforge::writeGridsAtomic(good.string(), openvdb::GridPtrVec{makeGrid()});
    const std::string bytes = readText(good);
    ASSERT_GT(bytes.size(), 64u);
    { std::ofstream(dir / "cut.vdb", std::ios::binary) << bytes.substr(0, bytes.size() / 2); }
    expectIoError((dir / "cut.vdb").string(), "a truncated file");
}

TEST(VdbIO, ASingularTransformIsOneTypedErrorNamingTheGrid)
{
    // A scale map is stored as its scale and four values derived from it (voxel size, inverse
    // scale, ...), read back as they are: a file whose scale is zero but whose voxel size is not
    // reads without complaint, and the first use of the transform's affine form (index to world of
    // a volume, a reference transform) throws ArithmeticError. The reader refuses it with an
    // IoError naming the file and the grid (the volume fuzzer's finding,
    // tests/data/fuzz/volume/crash-89cd…, replayed by Fuzz.Replay.volume).
    const fs::path dir = scratchDir("vdbio_singular");
    auto grid = makeGrid();
    grid->setName("flat");
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
    const std::string good = (dir / "good.vdb").string();
    levelforge::writeGridsAtomic(good, openvdb::GridPtrVec{grid});
    EXPECT_NO_THROW(levelforge::readGrids(good));
    // the scale (0.5, 0.5, 0.5) followed by the voxel size (0.5, 0.5, 0.5) and the inverse scale
    // (2, 2, 2): set the scale to zero
    std::string bytes = readText(good);
    std::string pattern;
    for (double v : {0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 2.0, 2.0, 2.0}) pattern.append(reinterpret_cast<const char*>(&v), 8);
    const size_t at = bytes.find(pattern);
    ASSERT_NE(at, std::string::npos) << "the scale map's values were not found in the file";
    const double zero = 0.0;
    for (int k = 0; k < 3; ++k) bytes.replace(at + 8 * k, 8, reinterpret_cast<const char*>(&zero), 8);
    const std::string bad = (dir / "singular.vdb").string();
    { std::ofstream(bad, std::ios::binary) << bytes; }
    try {
        levelforge::readGrids(bad);
        ADD_FAILURE() << "expected IoError for a zero scale";
    } catch (const levelforge::IoError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find(bad), std::string::npos) << m;
        EXPECT_NE(m.find("grid 'flat' has a singular transform"), std::string::npos) << m;
    }
}

TEST(VdbIO, ExternalToolsReadTheFile)
{
    const fs::path dir = scratchDir("vdbio_external");
    const std::string path = (dir / "ext.vdb").string();
    auto grid = makeGrid();
    levelforge::stampLevelSetMetadata(*grid, 3.0, 3.0, "unit-test", "test-method");
    levelforge::writeGridsAtomic(path, openvdb::GridPtrVec{grid});

    bool ranOne = false;
    if (std::system("command -v vdb_print >/dev/null 2>&1") == 0) {
        ranOne = true;
        const std::string log = (dir / "vdb_print.txt").string();
        ASSERT_EQ(std::system(("vdb_print -l '" + path + "' >'" + log + "' 2>&1").c_str()), 0)
            << readText(log);
        const std::string text = readText(log);
        EXPECT_NE(text.find("levelforge:generator"), std::string::npos) << text;
        EXPECT_NE(text.find("level set"), std::string::npos) << text;
    }
    // Debian's pyopenvdb is built for the system python, not for a pyenv one.
    const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
    if (std::system((python + " -c 'import pyopenvdb' >/dev/null 2>&1").c_str()) == 0) {
        ranOne = true;
        const std::string log = (dir / "python.txt").string();
        const std::string script =
            "import pyopenvdb as vdb; g = vdb.read('" + path + "', 'surface'); "
            "assert g.gridClass == vdb.GridClass.LEVEL_SET, g.gridClass; "
            "print(g['levelforge:generator'], g['levelforge:exterior_band_voxels'])";
        ASSERT_EQ(std::system((python + " -c \"" + script + "\" >'" + log + "' 2>&1").c_str()), 0)
            << readText(log);
        EXPECT_NE(readText(log).find("levelforge "), std::string::npos) << readText(log);
    }
    if (!ranOne) GTEST_SKIP() << "neither vdb_print nor pyopenvdb is installed";
}

// ===================================================== corrupt files: short, typed messages

namespace {

void writeText(const fs::path& path, const std::string& bytes)
{
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size()));
}

template<typename T>
void putField(std::string& bytes, size_t offset, T v)
{
    ASSERT_LE(offset + sizeof(T), bytes.size());
    std::memcpy(&bytes[offset], &v, sizeof(T));
}

/// A written level set with file metadata and level-set metadata, as bytes.
std::string goodVdbBytes(const fs::path& dir)
{
    const fs::path good = dir / "good.vdb";
    auto grid = makeGrid();
    levelforge::stampLevelSetMetadata(*grid, 3.0, 3.0, "unit-test", "test-method");
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata("unit test"));
    levelforge::writeGridsAtomic(good.string(), openvdb::GridPtrVec{grid}, fileMeta);
    return readText(good);
}

/// readGrids() on @p bytes written to @p path: must succeed or throw IoError whose message
/// names the file and is short. Returns the message ("" on success).
std::string readCorrupt(const fs::path& path, const std::string& bytes, bool mustFail, const std::string& what)
{
    writeText(path, bytes);
    try {
        levelforge::readGrids(path.string());
        if (mustFail) ADD_FAILURE() << "expected IoError for " << what;
        return {};
    } catch (const levelforge::IoError& e) {
        const std::string msg = e.what();
        EXPECT_LT(msg.size(), 1000u) << what << ": " << msg.substr(0, 2000);
        EXPECT_NE(msg.find(path.string()), std::string::npos) << what << ": " << msg;
        return msg;
    } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": wrong exception type: " << std::string(e.what()).substr(0, 2000);
        return {};
    }
}

} // namespace

TEST(VdbIO, DependencyMessagesAreCut)
{
    using levelforge::message_internal::cutDependencyMessage;
    EXPECT_EQ(cutDependencyMessage("short"), "short");
    EXPECT_EQ(cutDependencyMessage(nullptr), "unknown error");
    EXPECT_EQ(cutDependencyMessage("a\nb\tc\x01"), "a b c?");
    const std::string huge(3221225, 'x');
    const std::string cut = cutDependencyMessage(huge.c_str());
    EXPECT_LT(cut.size(), 560u);
    EXPECT_EQ(cut.substr(0, 500), std::string(500, 'x'));
    EXPECT_NE(cut.find("(message cut, 3.2 MB in all)"), std::string::npos) << cut;
    // A UTF-8 sequence is not split at the cut.
    const std::string accents = std::string(499, 'a') + "\xc3\xa9" + std::string(100, 'b');
    EXPECT_EQ(cutDependencyMessage(accents.c_str()).substr(0, 503), std::string(499, 'a') + "... ");
    EXPECT_EQ(levelforge::message_internal::byteSize(3221225472u), "3.2 GB");
    EXPECT_EQ(levelforge::message_internal::groupedCount(3221225472u), "3,221,225,472");
}

TEST(VdbIO, CorruptLengthFieldsAreRefusedBeforeOpenVdbReadsThem)
{
    const fs::path dir = scratchDir("vdbio_corrupt_lengths");
    const std::string good = goodVdbBytes(dir);
    const auto summary = levelforge::vdbio_internal::checkVdbHeader((dir / "good.vdb").string());
    EXPECT_GE(summary.fileVersion, 221u);
    EXPECT_TRUE(summary.hasGridOffsets);
    EXPECT_EQ(summary.gridCount, 1);
    EXPECT_GT(summary.firstTreeOffset, 100u);
    EXPECT_LT(summary.firstTreeOffset, good.size());

    const size_t creator = good.find("creator");
    const size_t name = good.find("surface", creator);
    const size_t treeType = good.find("Tree_float_5_4_3", name);
    const size_t source = good.find("levelforge:source", treeType);
    ASSERT_NE(creator, std::string::npos);
    ASSERT_NE(name, std::string::npos);
    ASSERT_NE(treeType, std::string::npos);
    ASSERT_NE(source, std::string::npos);
    struct Case
    {
        const char* what;
        size_t offset;
        uint32_t value;
    };
    const Case cases[] = {
        {"file metadata count", 57, 0x7fffffffu},
        {"file metadata name length", creator - 4, 0xC0000000u},
        {"file metadata type-name length", creator + 7, 0x7fffffffu},
        {"file metadata value size", creator + 7 + 4 + 6, 0x7fffffffu},
        {"grid count", name - 8, 0x7fffffffu},
        {"grid name length", name - 4, 0x7fffffffu},
        {"grid type length", name + 7, 0x7fffffffu},
        {"grid metadata name length", source - 4, 0x7fffffffu},
        {"grid metadata value size", source + 17 + 4 + 6, 0x7fffffffu},
    };
    for (const Case& c : cases) {
        std::string bytes = good;
        putField(bytes, c.offset, c.value);
        const std::string msg = readCorrupt(dir / "bad.vdb", bytes, true, c.what);
        EXPECT_NE(msg.find("corrupt VDB file"), std::string::npos) << c.what << ": " << msg;
    }
    {
        std::string bytes = good;
        putField(bytes, creator - 4, 0xC0000000u);
        const std::string msg = readCorrupt(dir / "bad.vdb", bytes, true, "the issue's example");
        EXPECT_NE(msg.find("claims 3,221,225,472 bytes"), std::string::npos) << msg;
    }
    {
        // The grid's data position (after the type and the empty instance-parent name).
        std::string bytes = good;
        putField(bytes, treeType + 16 + 4, int64_t(0x7fffffffffffffff));
        const std::string msg = readCorrupt(dir / "bad.vdb", bytes, true, "grid position");
        EXPECT_NE(msg.find("positions of grid 0"), std::string::npos) << msg;
    }
}

TEST(VdbIO, TruncatedCopiesGiveOneShortTypedError)
{
    const fs::path dir = scratchDir("vdbio_truncated");
    const std::string good = goodVdbBytes(dir);
    for (size_t n = 0; n < good.size(); n += (n < 160 ? 1 : 23)) {
        readCorrupt(dir / "cut.vdb", good.substr(0, n), true, "cut at " + std::to_string(n));
    }
    readCorrupt(dir / "cut.vdb", good.substr(0, good.size() - 1), true, "cut by one byte");
}

TEST(VdbIO, FlippedHeaderBytesGiveATypedErrorOrAGoodRead)
{
    const fs::path dir = scratchDir("vdbio_flipped");
    const std::string good = goodVdbBytes(dir);
    const auto summary = levelforge::vdbio_internal::checkVdbHeader((dir / "good.vdb").string());
    // The grid's compression flags steer how OpenVDB decodes the tree (not pre-scanned).
    const size_t treeType = good.find("Tree_float_5_4_3");
    ASSERT_NE(treeType, std::string::npos);
    int64_t gridPos = 0;
    std::memcpy(&gridPos, good.data() + treeType + 16 + 4, 8);
    int refused = 0;
    for (size_t i = 0; i < summary.firstTreeOffset; ++i) {
        if (i >= size_t(gridPos) && i < size_t(gridPos) + 4) continue;
        std::string bytes = good;
        bytes[i] = char(bytes[i] ^ 0xFF);
        if (!readCorrupt(dir / "flip.vdb", bytes, false, "byte " + std::to_string(i) + " flipped").empty()) ++refused;
    }
    EXPECT_GT(refused, 20);
}

// ===================================================== the tree pre-scan (VdbHeaderCheck.h)

namespace {

using levelforge::vdbio_internal::checkVdbHeader;

enum class Codec { None, Zip, Blosc };

uint32_t compressionFlags(Codec codec, bool activeMask)
{
    uint32_t c = activeMask ? openvdb::io::COMPRESS_ACTIVE_MASK : openvdb::io::COMPRESS_NONE;
    if (codec == Codec::Zip) c |= openvdb::io::COMPRESS_ZIP;
    if (codec == Codec::Blosc) c |= openvdb::io::COMPRESS_BLOSC;
    return c;
}

/// Writes @p grids with OpenVDB's own writer (io::File), @p compression as given.
void writeWithOpenVdb(const fs::path& path, const openvdb::GridPtrVec& grids, uint32_t compression)
{
    openvdb::io::File file(path.string());
    file.setCompression(compression);
    file.write(grids);
    file.close();
}

/// A tree with leaves, active and inactive tiles at every level (root, both internal levels),
/// values on both sides of the background; values from @p value(i).
template<typename GridT, typename F>
typename GridT::Ptr makeTree(const std::string& name, typename GridT::ValueType background, F value)
{
    using V = typename GridT::ValueType;
    auto grid = GridT::create(background);
    grid->setName(name);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
    auto& tree = grid->tree();
    int n = 0;
    for (int i = -12; i <= 12; i += 3) {
        for (int j = -12; j <= 12; j += 4) tree.setValue(openvdb::Coord(i, j, i * j), value(n++));
    }
    tree.setValueOff(openvdb::Coord(40, 1, 1), value(n++));
    tree.addTile(/*level=*/1, openvdb::Coord(128, 0, 0), V(value(n++)), /*active=*/true);
    tree.addTile(1, openvdb::Coord(136, 0, 0), V(value(n++)), false);
    tree.addTile(2, openvdb::Coord(0, 4096 - 128, 0), V(value(n++)), true);
    tree.addTile(3, openvdb::Coord(8192, 0, 0), V(value(n++)), true);
    tree.addTile(3, openvdb::Coord(-8192, 4096, 0), V(value(n++)), false);
    return grid;
}

openvdb::GridPtrVec everyGridType(bool half)
{
    using namespace openvdb;
    auto f = [](int i) { return float(i % 7) * 0.25f - 1.0f; };
    GridPtrVec grids;
    auto fl = makeTree<FloatGrid>("float", 0.75f, f);
    fl->setGridClass(GRID_LEVEL_SET);
    grids.push_back(fl);
    grids.push_back(makeTree<DoubleGrid>("double", 2.0, [&](int i) { return double(f(i)); }));
    grids.push_back(makeTree<Int32Grid>("int32", -3, [](int i) { return i - 20; }));
    grids.push_back(makeTree<Int64Grid>("int64", 7, [](int i) { return int64_t(i) << 33; }));
    grids.push_back(makeTree<Vec3SGrid>("vec3s", Vec3s(1, 0, 0), [&](int i) { return Vec3s(f(i), 1, f(i + 1)); }));
    grids.push_back(makeTree<Vec3DGrid>("vec3d", Vec3d(0), [&](int i) { return Vec3d(f(i), 2, 3); }));
    grids.push_back(makeTree<Vec3IGrid>("vec3i", Vec3i(0), [](int i) { return Vec3i(i, -i, 3); }));
    grids.push_back(makeTree<BoolGrid>("bool", false, [](int i) { return i % 3 != 0; }));
    grids.push_back(makeTree<BoolGrid>("bool-true-background", true, [](int i) { return i % 2 == 0; }));
    grids.push_back(makeTree<MaskGrid>("mask", false, [](int) { return true; }));
    if (half) {
        for (auto& g : grids) g->setSaveFloatAsHalf(true);
    }
    return grids;
}

/// checkVdbHeader() and readGrids() both accept @p path.
void expectAccepted(const fs::path& path, const std::string& what)
{
    try {
        const auto summary = checkVdbHeader(path.string());
        (void)summary;
    } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": the pre-scan refuses a good file: " << e.what();
        return;
    }
    try {
        levelforge::readGrids(path.string());
    } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": readGrids refuses a good file: " << e.what();
    }
}

/// The bytes of a one-grid file as io::File writes it, and where its pieces are.
struct Layout
{
    std::string bytes;
    size_t tree = 0;   ///< start of the topology (the buffer count)
    size_t blocks = 0; ///< the block position (the leaves' buffers)
    size_t end = 0;
    size_t blockField = 0; ///< where the descriptor stores the block position
};

/// @p transformBytes: the size of the transform's map data (UniformScaleMap: 120).
Layout layoutOf(const fs::path& path, const std::string& treeType, size_t transformBytes = 120)
{
    Layout l;
    l.bytes = readText(path);
    const auto summary = checkVdbHeader(path.string());
    l.tree = summary.firstTreeOffset + transformBytes;
    const size_t type = l.bytes.find(treeType);
    EXPECT_NE(type, std::string::npos);
    l.blockField = type + treeType.size() + 4 + 8; // after the empty instance parent and the grid position
    int64_t v = 0;
    std::memcpy(&v, l.bytes.data() + l.blockField, 8);
    l.blocks = size_t(v);
    std::memcpy(&v, l.bytes.data() + l.blockField + 8, 8);
    l.end = size_t(v);
    return l;
}

/// Position of the chunk size after the compression byte at @p meta of a node with
/// @p numValues values of @p valueBytes bytes.
size_t chunkAfterMeta(const std::string& bytes, size_t meta, size_t valueBytes, size_t numValues)
{
    const int m = bytes[meta];
    size_t pos = meta + 1;
    if (m == 2 || m == 4 || m == 5) pos += valueBytes * (m == 5 ? 2 : 1);
    if (m == 3 || m == 4 || m == 5) pos += numValues / 8;
    return pos;
}

int64_t int64At(const std::string& bytes, size_t pos)
{
    int64_t v = 0;
    std::memcpy(&v, bytes.data() + pos, 8);
    return v;
}

std::string expectRefused(const fs::path& path, const std::string& bytes, const std::string& what,
                          const std::string& fragment)
{
    const std::string msg = readCorrupt(path, bytes, true, what);
    EXPECT_NE(msg.find(fragment), std::string::npos) << what << ": " << msg;
    return msg;
}

fs::path fuzzDataDir() { return fs::path(LEVELFORGE_SOURCE_DIR) / "tests" / "data" / "fuzz"; }

} // namespace

TEST(VdbIO, PreScanAcceptsEveryLayoutOpenVdbWrites)
{
    const fs::path dir = scratchDir("vdbio_prescan_layouts");
    for (bool half : {false, true}) {
        for (Codec codec : {Codec::None, Codec::Zip, Codec::Blosc}) {
            if (codec == Codec::Blosc && !openvdb::io::Archive::hasBloscCompression()) continue;
            for (bool mask : {false, true}) {
                const std::string what = std::string(half ? "half " : "") +
                                         (codec == Codec::None ? "raw" : codec == Codec::Zip ? "zip" : "blosc") +
                                         (mask ? " + active mask" : "");
                const fs::path path = dir / "all.vdb";
                const openvdb::GridPtrVec grids = everyGridType(half);
                writeWithOpenVdb(path, grids, compressionFlags(codec, mask));
                expectAccepted(path, what);
                const auto summary = checkVdbHeader(path.string());
                EXPECT_EQ(summary.gridCount, int32_t(grids.size())) << what;
                EXPECT_GT(summary.leafCount, 10 * grids.size()) << what;
                EXPECT_GE(summary.rootTileCount, 2 * grids.size()) << what;
                // The values come back (half floats within their precision).
                const auto back = levelforge::readGrids(path.string());
                ASSERT_EQ(back->size(), grids.size());
                for (const auto& g : grids) {
                    const auto it = std::find_if(back->begin(), back->end(),
                                                 [&](const auto& b) { return b->getName() == g->getName(); });
                    ASSERT_NE(it, back->end()) << what << ": " << g->getName();
                    EXPECT_EQ((*it)->activeVoxelCount(), g->activeVoxelCount()) << what << ": " << g->getName();
                }
            }
        }
    }
}

TEST(VdbIO, PreScanAcceptsInstancesStreamsFrustumsAndOurWriter)
{
    const fs::path dir = scratchDir("vdbio_prescan_special");
    // Two grids sharing one tree: the second is written as an instance (no tree, no block position).
    {
        auto a = makeGrid("a");
        auto b = a->copy(); // shares the tree
        b->setName("b");
        writeWithOpenVdb(dir / "instance.vdb", {a, b}, compressionFlags(Codec::Zip, true));
        expectAccepted(dir / "instance.vdb", "instanced grids");
        EXPECT_NE(readText(dir / "instance.vdb").find("a"), std::string::npos);
    }
    // A file written by io::Stream: no grid offsets, grids follow their descriptors.
    {
        std::ofstream out(dir / "stream.vdb", std::ios::binary);
        openvdb::io::Stream(out).write(everyGridType(false));
    }
    {
        const auto summary = checkVdbHeader((dir / "stream.vdb").string());
        EXPECT_FALSE(summary.hasGridOffsets);
        EXPECT_GT(summary.leafCount, 50u);
        expectAccepted(dir / "stream.vdb", "a stream-written file");
    }
    // A frustum transform and a scale-translate one.
    {
        auto f = makeGrid("frustum");
        f->setTransform(openvdb::math::Transform::createFrustumTransform(
            openvdb::BBoxd(openvdb::Vec3d(0), openvdb::Vec3d(10)), 0.5, 2.0, 0.1));
        auto t = makeGrid("translated");
        t->transform().postTranslate(openvdb::Vec3d(1, 2, 3));
        t->transform().postScale(openvdb::Vec3d(1, 2, 3));
        writeWithOpenVdb(dir / "maps.vdb", {f, t}, compressionFlags(Codec::Zip, true));
        expectAccepted(dir / "maps.vdb", "frustum and scale-translate maps");
    }
    // An empty grid, and the project's own writer (Blosc, active mask, level-set metadata).
    {
        auto empty = openvdb::FloatGrid::create(1.0f);
        empty->setName("empty");
        auto grid = makeGrid();
        levelforge::stampLevelSetMetadata(*grid, 3.0, 3.0, "unit-test", "test-method");
        levelforge::writeGridsAtomic((dir / "ours.vdb").string(), openvdb::GridPtrVec{grid, empty});
        expectAccepted(dir / "ours.vdb", "writeGridsAtomic");
    }
}

TEST(VdbIO, PreScanAcceptsTheSavedSeedsAndSharedData)
{
    int scanned = 0;
    for (const auto& entry : fs::recursive_directory_iterator(fuzzDataDir())) {
        const std::string name = entry.path().filename().string();
        if (entry.path().extension() != ".vdb" || name.rfind("seed-", 0) != 0) continue;
        expectAccepted(entry.path(), name);
        ++scanned;
    }
    EXPECT_GE(scanned, 8);
    const std::string shared = levelforge_test::sharedDataDir();
    if (shared.empty()) GTEST_SKIP() << "../shared/data not present: only the saved seeds were scanned";
    int inShared = 0;
    for (const auto& entry : fs::recursive_directory_iterator(shared)) {
        if (!entry.is_regular_file() || entry.path().extension() != ".vdb") continue;
        expectAccepted(entry.path(), entry.path().string());
        ++inShared;
    }
    if (inShared == 0) GTEST_SKIP() << "no .vdb file in " << shared << ": only the saved seeds were scanned";
}

TEST(VdbIO, PreScanRefusesCorruptRootsAndMasks)
{
    const fs::path dir = scratchDir("vdbio_prescan_root");
    const fs::path good = dir / "good.vdb";
    // One leaf at the origin, one root tile (tiles come before children).
    auto grid = makeGrid();
    grid->tree().addTile(3, openvdb::Coord(8192, 0, 0), 1.0f, true);
    writeWithOpenVdb(good, {grid}, compressionFlags(Codec::Zip, true));
    const Layout l = layoutOf(good, "Tree_float_5_4_3");
    const fs::path bad = dir / "bad.vdb";
    ASSERT_EQ(l.bytes.compare(l.tree, 4, std::string("\x01\0\0\0", 4)), 0) << "buffer count expected at " << l.tree;
    uint32_t tiles = 0, children = 0;
    std::memcpy(&tiles, l.bytes.data() + l.tree + 8, 4);
    std::memcpy(&children, l.bytes.data() + l.tree + 12, 4);
    ASSERT_EQ(tiles, 1u);
    ASSERT_GE(children, 1u);
    const size_t tile0 = l.tree + 16;
    const size_t child0 = tile0 + 17;
    {
        std::string b = l.bytes;
        putField(b, l.tree, int32_t(63));
        expectRefused(bad, b, "buffer count", "buffers, not 1");
    }
    {
        std::string b = l.bytes;
        putField(b, l.tree + 12, uint32_t(0x7fffffff));
        expectRefused(bad, b, "root child count", "children (at least");
    }
    {
        std::string b = l.bytes;
        putField(b, l.tree + 8, uint32_t(0x10000000));
        expectRefused(bad, b, "root tile count", "tiles and");
    }
    {
        std::string b = l.bytes;
        b[tile0 + 16] = 2;
        expectRefused(bad, b, "root tile active byte", "has the active flag 2, not 0 or 1");
    }
    {
        std::string b = l.bytes;
        putField(b, tile0, int32_t(8193));
        expectRefused(bad, b, "unaligned root tile", "is not at a multiple of 4096");
    }
    {
        std::string b = l.bytes;
        putField(b, child0, int32_t(8192)); // the tile's key
        putField(b, child0 + 4, int32_t(0));
        putField(b, child0 + 8, int32_t(0));
        expectRefused(bad, b, "child at a tile's key", "is also a root tile");
    }
    {
        std::string b = l.bytes;
        putField(b, child0 + 4, int32_t(-38));
        expectRefused(bad, b, "unaligned root child", "is not at a multiple of 4096");
    }
    const size_t childMask = child0 + 12, valueMask = childMask + 4096;
    {
        // Every entry of the top internal node a child: 32,768 nodes announced, the file ends.
        std::string b = l.bytes;
        std::memset(&b[childMask], 0xff, 4096);
        const auto start = std::chrono::steady_clock::now();
        readCorrupt(bad, b, true, "all child bits");
        EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
    }
    {
        std::string b = l.bytes;
        std::memset(&b[valueMask], 0xff, 4096);
        expectRefused(bad, b, "child and active bits", "both as a child and as an active tile");
    }
    {
        std::string b = l.bytes;
        b[valueMask + 4096] = 9;
        expectRefused(bad, b, "compression byte", "is 9, not one of 0 to 6");
    }
    {
        // The topology must end where the descriptor puts the buffers.
        std::string b = l.bytes;
        putField(b, l.blockField, int64_t(l.blocks + 1));
        readCorrupt(bad, b, true, "block position");
    }
    {
        std::string b = l.bytes;
        const size_t flags = l.bytes.find("Tree_float_5_4_3") + 16 + 4 + 24; // the grid's first field
        putField(b, flags, uint32_t(0xee));
        expectRefused(bad, b, "grid compression flags", "not a combination of zip");
    }
    {
        std::string b = l.bytes;
        const size_t map = b.find("UniformScaleMap");
        ASSERT_NE(map, std::string::npos);
        b[map] = 'X';
        expectRefused(bad, b, "transform type", "not a map type OpenVDB knows");
    }
}

TEST(VdbIO, PreScanRefusesCorruptChunks)
{
    const fs::path dir = scratchDir("vdbio_prescan_chunks");
    const fs::path bad = dir / "bad.vdb";
    for (Codec codec : {Codec::Zip, Codec::Blosc}) {
        if (codec == Codec::Blosc && !openvdb::io::Archive::hasBloscCompression()) continue;
        const std::string kind = codec == Codec::Zip ? "zip" : "Blosc";
        const fs::path good = dir / ("good-" + kind + ".vdb");
        // One leaf at the origin; the top internal node holds active tiles, so that its chunk
        // has values (4096 bytes of them once decompressed).
        auto grid = openvdb::FloatGrid::create(0.3f);
        grid->setName("surface");
        grid->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
        for (int i = 0; i < 512; ++i) grid->tree().setValue(openvdb::Coord(i >> 6, (i >> 3) & 7, i & 7), 0.01f * float(i % 50));
        for (int i = 1; i < 1024; i += 1) {
            grid->tree().addTile(2, openvdb::Coord((i % 32) * 128, ((i / 32) % 32) * 128, 0), float(i), true);
        }
        writeWithOpenVdb(good, {grid}, compressionFlags(codec, true));
        const Layout l = layoutOf(good, "Tree_float_5_4_3");
        expectAccepted(good, kind);
        const size_t top = l.tree + 16 + 12;                // the top internal node's child mask
        const size_t chunk = chunkAfterMeta(l.bytes, top + 8192, 4, 32768);
        const int64_t size = int64At(l.bytes, chunk);
        ASSERT_GT(size, 0) << kind << ": expected a compressed chunk at " << chunk;
        {
            std::string b = l.bytes;
            putField(b, chunk, int64_t(1) << 40);
            expectRefused(bad, b, kind + " chunk size 2^40", "declares a " + kind + " chunk of 1,099,511,627,776 bytes, more than the");
        }
        {
            // A negative size means "stored": OpenVDB 10 reads that many bytes into the node's buffer.
            std::string b = l.bytes;
            putField(b, chunk, int64_t(-1000000));
            expectRefused(bad, b, kind + " negative chunk size", "declares a stored (uncompressed) " + kind +
                                                                   " chunk of 1,000,000 bytes, its values take");
        }
        {
            // At most the values' bytes, but more than the topology holds after it.
            const int64_t past = int64_t(l.blocks - (chunk + 8)) + 1;
            ASSERT_LE(past, 4092) << kind;
            std::string b = l.bytes;
            putField(b, chunk, past);
            expectRefused(bad, b, kind + " chunk past the topology", "bytes left in the topology");
        }
        {
            // Compressed bytes that do not decompress (inside readTopology: an exception there leaks).
            std::string b = l.bytes;
            for (int64_t i = codec == Codec::Blosc ? 16 : 2; i < size; ++i) b[chunk + 8 + size_t(i)] = 0;
            if (codec == Codec::Zip) {
                expectRefused(bad, b, "zip chunk of zeros", "does not decompress");
            } else {
                readCorrupt(bad, b, false, "Blosc chunk of zeros");
            }
        }
        if (codec == Codec::Blosc) {
            std::string b = l.bytes;
            putField(b, chunk + 8 + 12, uint32_t(size + 1000)); // the header's compressed size
            expectRefused(bad, b, "Blosc header", "compressed bytes, the buffer holds");
        }
        {
            // The leaf's chunk in the buffers: mask (64 bytes), compression byte, ..., size.
            const size_t leafChunk = chunkAfterMeta(l.bytes, l.blocks + 64, 4, 512);
            std::string b = l.bytes;
            putField(b, leafChunk, int64_t(1) << 40);
            expectRefused(bad, b, kind + " leaf chunk size", "leaf node at (0, 0, 0) declares a " + kind + " chunk");
            b = l.bytes;
            putField(b, leafChunk, int64_t(-4096));
            expectRefused(bad, b, kind + " leaf stored chunk", "declares a stored (uncompressed) " + kind + " chunk of 4,096 bytes");
            b = l.bytes;
            b[l.blocks + 3] ^= 0x10;
            expectRefused(bad, b, "leaf mask in the buffers", "differs from the one in its topology");
        }
    }
}

TEST(VdbIO, PreScanRefusesBadBoolsHalfFlagsAndLeafOrigins)
{
    const fs::path dir = scratchDir("vdbio_prescan_bool");
    const fs::path bad = dir / "bad.vdb";
    for (bool mask : {false, true}) {
        const fs::path good = dir / "good.vdb";
        openvdb::GridBase::Ptr grid;
        if (mask) {
            auto g = openvdb::MaskGrid::create(false);
            g->tree().setValueOn(openvdb::Coord(1, 2, 3));
            grid = g;
        } else {
            auto g = openvdb::BoolGrid::create(false);
            g->tree().setValue(openvdb::Coord(1, 2, 3), true);
            grid = g;
        }
        grid->setName("flags");
        grid->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
        writeWithOpenVdb(good, {grid}, compressionFlags(Codec::None, false));
        const std::string type = mask ? "Tree_mask_5_4_3" : "Tree_bool_5_4_3";
        const Layout l = layoutOf(good, type);
        {
            std::string b = l.bytes;
            b[l.tree + 4] = 2; // the background
            expectRefused(bad, b, type + " background", "for a bool value");
        }
        {
            // The top internal node's values: raw bools (no compression), after the masks and the
            // compression byte (6: all values).
            const size_t meta = l.tree + 4 + 1 + 8 + 12 + 8192;
            ASSERT_EQ(int(l.bytes[meta]), 6) << type;
            std::string b = l.bytes;
            b[meta + 1 + 100] = 7;
            expectRefused(bad, b, type + " internal value", "holds the byte 7 for a bool value");
        }
        {
            // The leaf's origin in its buffer (after its 64-byte mask).
            std::string b = l.bytes;
            putField(b, l.blocks + 64, int32_t(8));
            expectRefused(bad, b, type + " leaf origin", "gives its origin as (8, 0, 0)");
        }
    }
    {
        // A half-float grid whose half flag is cleared: its chunks no longer have the sizes of
        // full floats.
        auto grid = makeGrid();
        grid->setSaveFloatAsHalf(true);
        const fs::path good = dir / "half.vdb";
        writeWithOpenVdb(good, {grid}, compressionFlags(Codec::None, true));
        expectAccepted(good, "half floats");
        std::string b = readText(good);
        const size_t flag = b.find("is_saved_as_half_float");
        ASSERT_NE(flag, std::string::npos);
        const size_t value = flag + 22 + 4 + 4 + 4; // name, type length, "bool", value size
        ASSERT_EQ(int(b[value]), 1);
        b[value] = 0;
        readCorrupt(bad, b, true, "half flag cleared");
        b[value] = 3;
        expectRefused(bad, b, "half flag 3", "is 3, not 0 or 1");
    }
}

TEST(VdbIO, PreScanRefusesFormatVersion221)
{
    const fs::path dir = scratchDir("vdbio_prescan_version");
    const std::string good = goodVdbBytes(dir);
    std::string b = good;
    putField(b, 8, uint32_t(221));
    expectRefused(dir / "old.vdb", b, "version 221", "is not supported");
}

TEST(VdbIO, PreScanOfCorruptStreamFiles)
{
    const fs::path dir = scratchDir("vdbio_prescan_stream");
    {
        std::ofstream out(dir / "stream.vdb", std::ios::binary);
        openvdb::io::Stream(out).write(openvdb::GridPtrVec{makeGrid("a"), makeGrid("b")});
    }
    const std::string good = readText(dir / "stream.vdb");
    // Truncations and flipped bytes, evenly spread: a typed error or a good read, never a crash.
    for (size_t n = 0; n < good.size(); n += good.size() / 150 + 1) {
        readCorrupt(dir / "cut.vdb", good.substr(0, n), true, "cut stream");
    }
    for (size_t i = 0; i < good.size(); i += good.size() / 500 + 1) {
        std::string b = good;
        b[i] = char(b[i] ^ 0xA5);
        readCorrupt(dir / "flip.vdb", b, false, "stream byte " + std::to_string(i));
    }
}

TEST(VdbIO, PreScanOfFlippedTreeBytes)
{
    // Every byte of a small multi-type file flipped in turn (zip, active mask): a typed error or a
    // good read, never another exception (readCorrupt checks).
    const fs::path dir = scratchDir("vdbio_prescan_flip_tree");
    auto f = openvdb::FloatGrid::create(0.5f);
    f->setName("f");
    auto bg = openvdb::BoolGrid::create(false);
    bg->setName("b");
    for (int i = 0; i < 40; ++i) {
        f->tree().setValue(openvdb::Coord(i, 2 * i, 3 * i), float(i));
        bg->tree().setValue(openvdb::Coord(3 * i, 2 * i, i), i % 3 == 0);
    }
    f->tree().addTile(1, openvdb::Coord(128, 0, 0), 2.0f, true);
    f->tree().addTile(2, openvdb::Coord(0, 1024, 0), -2.0f, true);
    bg->tree().addTile(2, openvdb::Coord(0, 1024, 0), true, true);
    writeWithOpenVdb(dir / "good.vdb", {f, bg}, compressionFlags(Codec::Zip, true));
    const std::string good = readText(dir / "good.vdb");
    int refused = 0, tried = 0;
    for (size_t i = 0; i < good.size(); i += good.size() / 1500 + 1, ++tried) {
        std::string b = good;
        b[i] = char(b[i] ^ 0xFF);
        if (!readCorrupt(dir / "flip.vdb", b, false, "byte " + std::to_string(i)).empty()) ++refused;
    }
    EXPECT_GT(refused, tried / 10);
}
