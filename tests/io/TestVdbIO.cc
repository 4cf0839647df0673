// SPDX-License-Identifier: Apache-2.0
// Tests for VdbIO.h: atomic writes, reading with clear errors, level-set metadata.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>

#include "detail/MessageText.h"
#include "io/VdbHeaderCheck.h"

#include <openvdb/openvdb.h>

#include <algorithm>
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
