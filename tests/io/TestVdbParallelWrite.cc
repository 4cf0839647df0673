// SPDX-License-Identifier: Apache-2.0
// writeGridsAtomic() compresses the leaf buffers of FloatGrids on all threads (src/io/VdbIO.cc,
// ParallelBufferFloatGrid): the file must be OpenVDB's own, byte for byte, apart from the random
// UUID of the header — for level sets of many leaves, with several grids, a shared (instanced)
// tree, a half-float grid, other value types and an empty grid.
#include "TestUtil.h"
#include "io/VdbHeaderCheck.h"

#include <levelforge/io/VdbIO.h>
#include <levelforge/mesh/MeshToLevelSet.h>
#include <levelforge/reference/MeshShapes.h>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

using namespace levelforge;
using levelforge_test::scratchDir;

namespace {

std::vector<char> readBytes(const std::filesystem::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::vector<char>(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// The header's UUID: 36 characters after magic (8), format version (4), library version (8) and
/// the grid-offsets flag (1).
constexpr size_t kUuidBegin = 21, kUuidEnd = 57;

/// parallelFloatGrids: how many of the grids the parallel path must write (float, not half).
void expectOpenVdbBytes(const openvdb::GridPtrVec& grids, const std::string& name, uint64_t parallelFloatGrids)
{
    const auto dir = scratchDir("vdb-parallel-write");
    const auto ours = dir / (name + "-levelforge.vdb"), theirs = dir / (name + "-openvdb.vdb");
    openvdb::MetaMap meta;
    meta.insertMeta("generator", openvdb::StringMetadata(generatorString()));
    const uint64_t before = vdbio_internal::parallelBufferGridsWritten();
    writeGridsAtomic(ours.string(), grids, meta);
    EXPECT_EQ(vdbio_internal::parallelBufferGridsWritten() - before, parallelFloatGrids) << name;
    {
        openvdb::io::File file(theirs.string());
        file.setCompression(openvdb::io::COMPRESS_ACTIVE_MASK |
                            (openvdb::io::Archive::hasBloscCompression() ? openvdb::io::COMPRESS_BLOSC
                                                                         : openvdb::io::COMPRESS_ZIP));
        file.write(grids, meta);
        file.close();
    }
    const std::vector<char> a = readBytes(ours), b = readBytes(theirs);
    ASSERT_EQ(a.size(), b.size()) << name;
    ASSERT_GT(a.size(), kUuidEnd) << name;
    size_t differences = 0;
    for (size_t i = 0; i < a.size(); ++i)
        if (a[i] != b[i] && (i < kUuidBegin || i >= kUuidEnd)) ++differences;
    EXPECT_EQ(differences, 0u) << name << ": bytes differ outside the UUID";
}

} // namespace

TEST(VdbParallelWrite, TheBytesOfOpenVdbsOwnWriter)
{
    openvdb::initialize();
    MeshToLevelSetOptions opt;
    opt.voxelCount = 400; // ~11,000 leaves: many blocks of 64 leaves, more than the pipeline holds at once
    const auto knot = meshToLevelSetWithClosestPoints(makeTorusKnot(), opt);
    ASSERT_GT(knot.levelSet->tree().leafCount(), 64u * 64u);
    expectOpenVdbBytes({knot.levelSet}, "level set", 1);

    // several grids: the level set, its closest points and triangles (other value types), a
    // second name for the same tree (written as an instance), a half-float copy, an empty grid
    auto instance = openvdb::FloatGrid::create(knot.levelSet->treePtr());
    instance->setName("same tree");
    instance->setTransform(knot.levelSet->transform().copy());
    auto half = knot.levelSet->deepCopy();
    half->setName("half");
    half->setSaveFloatAsHalf(true);
    auto empty = openvdb::FloatGrid::create(2.0f);
    empty->setName("empty");
    // the level set and the empty grid in parallel; the instance shares the level set's tree
    // (OpenVDB writes it as an instance: no buffers), the half-float grid goes through OpenVDB
    expectOpenVdbBytes({knot.levelSet, knot.closestPoints, knot.closestTriangles, instance, half, empty}, "several grids", 2);
}
