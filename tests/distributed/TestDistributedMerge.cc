// SPDX-License-Identifier: Apache-2.0
// One file per rank, in one process: K "ranks" each write their part with writeBrickPiece(), a
// manifest lists them (writeBrickManifest()), and mergeBrickPieces() must give meshToSdf()'s grid
// bit for bit (values, active states, tiles, metadata) for K = 1..4, with empty ranks, the
// interior fill, unequal widths and the unsigned sign. Then every kind of bad manifest or piece is
// refused with one IoError naming the file and the problem.
#include "TestUtil.h"
#include "distributed/GridIdentity.h"
#include "distributed/PieceWriter.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/pipeline/MeshToSdf.h>
#include <levelforge/reference/MeshShapes.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

namespace fs = std::filesystem;
using namespace levelforge;
using levelforge_test::gridDifference;

namespace {

MeshToSdfOptions knotOptions()
{
    MeshToSdfOptions o;
    o.voxelCount = 96;
    return o;
}

std::string readAll(const fs::path& p)
{
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void writeAll(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

/// mergeBrickPieces() must throw IoError mentioning every one of @p mentions.
void expectRefused(const std::string& manifest, const std::vector<std::string>& mentions, const std::string& what)
{
    try {
        mergeBrickPieces(manifest);
        ADD_FAILURE() << what << ": merged";
    } catch (const IoError& e) {
        for (const std::string& m : mentions)
            EXPECT_NE(std::string(e.what()).find(m), std::string::npos) << what << ": " << e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": not an IoError: " << e.what();
    }
}

} // namespace

TEST(DistributedMerge, PieceAndManifestNames)
{
    EXPECT_EQ(pieceFileName("out.vdb", 3), "out.rank0003.vdb");
    EXPECT_EQ(pieceFileName("/a/b/statue.vdb", 12345), "/a/b/statue.rank12345.vdb");
    EXPECT_EQ(pieceFileName("dir/noext", 0), "dir/noext.rank0000.vdb");
    EXPECT_EQ(manifestFileName("dir/out.vdb"), "dir/out.vdb.manifest.json");
    EXPECT_EQ(newPieceRunId().size(), 32u);
    EXPECT_NE(newPieceRunId(), newPieceRunId());
}

TEST(DistributedMerge, PiecesMergedEqualSingleProcessOnOneToFourRanks)
{
    const TriangleMesh knot = makeTorusKnot();
    const MeshToSdfOptions o = knotOptions();
    const openvdb::FloatGrid::Ptr single = meshToSdf(knot, o);
    ASSERT_GT(single->activeVoxelCount(), 10000u);
    for (int brickLog2 : {4, 7})
        for (int ranks = 1; ranks <= 4; ++ranks) {
            const fs::path dir = levelforge_test::scratchDir("merge_knot_" + std::to_string(brickLog2) + "_" +
                                                             std::to_string(ranks));
            const std::string manifest = levelforge_test::writePieces(knot, o, ranks, brickLog2, dir);
            MergeStats st;
            const openvdb::FloatGrid::Ptr merged = mergeBrickPieces(manifest, {}, &st);
            EXPECT_EQ(gridDifference(*single, *merged), "") << ranks << " ranks, bricks of 2^" << brickLog2;
            EXPECT_EQ(st.pieces, ranks);
            EXPECT_EQ(st.leaves, single->tree().leafCount());
            // and through files, as `levelforge merge` and mesh-to-sdf write them (the writer adds
            // the file_* statistics to both)
            writeGridsAtomic((dir / "merged.vdb").string(), {merged});
            writeGridsAtomic((dir / "single.vdb").string(), {single->deepCopy()});
            const auto a = readGrids((dir / "single.vdb").string()), b = readGrids((dir / "merged.vdb").string());
            ASSERT_EQ(b->size(), 1u);
            EXPECT_EQ(gridDifference(*openvdb::gridPtrCast<openvdb::FloatGrid>(a->front()),
                                     *openvdb::gridPtrCast<openvdb::FloatGrid>(b->front())),
                      "");
        }
}

TEST(DistributedMerge, FillUnequalWidthsUnsignedAndEmptyRanks)
{
    const TriangleMesh knot = makeTorusKnot();
    MeshToSdfOptions f = knotOptions();
    f.fillInterior = true;
    f.exteriorWidth = 4.0;
    f.interiorWidth = 1.5;
    f.gridName = "filled";
    const openvdb::FloatGrid::Ptr filled = meshToSdf(knot, f);
    EXPECT_EQ(gridDifference(*filled, *mergeBrickPieces(levelforge_test::writePieces(knot, f, 3, 4,
                                                                    levelforge_test::scratchDir("merge_fill")))),
              "")
        << "fill interior, 4 / 1.5 voxels";
    MeshToSdfOptions u = knotOptions();
    u.sign = SignMode::Unsigned;
    EXPECT_EQ(gridDifference(*meshToSdf(knot, u),
                             *mergeBrickPieces(levelforge_test::writePieces(knot, u, 2, 5, levelforge_test::scratchDir("merge_unsigned")))),
              "")
        << "unsigned";
    // a sphere inside one brick: two of three ranks write empty pieces
    const TriangleMesh ball = makeIcosphere(Vec3d(0.5, 0.5, 0.5), 0.3, 3);
    MeshToSdfOptions b;
    b.voxelSize = 0.01;
    b.fillInterior = true;
    const fs::path dir = levelforge_test::scratchDir("merge_one_brick");
    const std::string manifest = levelforge_test::writePieces(ball, b, 3, 7, dir);
    const BrickManifest m = readBrickManifest(manifest);
    int empty = 0;
    for (const BrickPiece& p : m.pieces) empty += p.leaves == 0 ? 1 : 0;
    EXPECT_EQ(empty, 2);
    EXPECT_EQ(gridDifference(*meshToSdf(ball, b), *mergeBrickPieces(manifest)), "") << "two empty ranks";
}

TEST(DistributedMerge, ManifestReadsBackAsWritten)
{
    const TriangleMesh knot = makeTorusKnot();
    MeshToSdfOptions o = knotOptions();
    o.exteriorWidth = 2.5;
    o.source = "a \"quoted\" source\nwith a new line";
    const fs::path dir = levelforge_test::scratchDir("merge_manifest");
    const BrickManifest m = readBrickManifest(levelforge_test::writePieces(knot, o, 3, 5, dir, "0123456789abcdef0123456789abcdef"));
    const BrickFinish f = brickFinishFor(knot, o);
    EXPECT_EQ(m.id, "0123456789abcdef0123456789abcdef");
    EXPECT_EQ(m.ranks, 3);
    EXPECT_EQ(m.brickLog2, 5);
    EXPECT_EQ(m.output, "out.vdb");
    EXPECT_EQ(m.finish.voxelSize, f.voxelSize);
    EXPECT_EQ(m.finish.exteriorBandVoxels, f.exteriorBandVoxels);
    EXPECT_EQ(m.finish.interiorBandVoxels, f.interiorBandVoxels);
    EXPECT_EQ(m.finish.source, o.source);
    EXPECT_EQ(m.finish.sign, SignMode::Pseudonormal);
    EXPECT_EQ(m.finish.gridName, "surface");
    EXPECT_EQ(m.transform->voxelSize()[0], f.voxelSize);
    ASSERT_EQ(m.pieces.size(), 3u);
    uint64_t leaves = 0;
    for (int r = 0; r < 3; ++r) {
        EXPECT_EQ(m.pieces[size_t(r)].rank, r);
        EXPECT_EQ(m.pieces[size_t(r)].file, "out.rank000" + std::to_string(r) + ".vdb");
        EXPECT_EQ(m.pieces[size_t(r)].bytes, fs::file_size(dir / m.pieces[size_t(r)].file));
        EXPECT_FALSE(m.pieces[size_t(r)].bricks.empty());
        leaves += m.pieces[size_t(r)].leaves;
    }
    EXPECT_EQ(leaves, meshToSdf(knot, o)->tree().leafCount());
}

TEST(DistributedMerge, BadManifestsAndPiecesAreRefusedNamingTheFile)
{
    const TriangleMesh knot = makeTorusKnot();
    const MeshToSdfOptions o = knotOptions();
    const fs::path dir = levelforge_test::scratchDir("merge_bad");
    const std::string manifest = levelforge_test::writePieces(knot, o, 3, 4, dir);
    const std::string good = readAll(manifest);
    const fs::path bad = dir / "bad.json";
    auto edited = [&](const std::string& from, const std::string& to) {
        std::string t = good;
        const size_t at = t.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        if (at != std::string::npos) t.replace(at, from.size(), to);
        writeAll(bad, t);
        return bad.string();
    };
    ASSERT_NO_THROW(mergeBrickPieces(manifest));

    expectRefused((dir / "none.json").string(), {"none.json", "no such file"}, "missing manifest");
    writeAll(bad, good.substr(0, good.size() / 2));
    expectRefused(bad.string(), {"bad.json", "not valid JSON"}, "cut-short manifest");
    writeAll(bad, "{\"format\": \"something else\"}");
    expectRefused(bad.string(), {"bad.json", "not a manifest of levelforge pieces"}, "another JSON file");
    expectRefused(edited("\"ranks\": 3", "\"ranks\": 4"), {"bad.json", "'ranks' is 4 but 3 pieces"}, "wrong count");
    expectRefused(edited("\"voxel_size\":", "\"voxel_sizes\":"), {"bad.json", "grid.voxel_size", "missing"},
                  "missing field");
    expectRefused(edited("\"sign\":\"pseudonormal\"", "\"sign\":\"winding\""), {"bad.json", "grid.sign"}, "sign");
    // a transform other than the pieces': the first matrix entry (the voxel size) changed
    {
        const BrickManifest m = readBrickManifest(manifest);
        BrickManifest other = m;
        other.transform = openvdb::math::Transform::createLinearTransform(m.finish.voxelSize * 1.5);
        writeBrickManifest(bad.string(), other);
        expectRefused(bad.string(), {"out.rank0000.vdb", "transform"}, "mismatched transform");
        other = m;
        other.pieces[1].leaves += 1;
        writeBrickManifest(bad.string(), other);
        expectRefused(bad.string(), {"out.rank0001.vdb", "leaves"}, "wrong leaf count");
        other = m;
        std::swap(other.pieces[1].bricks, other.pieces[2].bricks);
        writeBrickManifest(bad.string(), other);
        expectRefused(bad.string(), {"out.rank0001.vdb", "outside its rank's bricks"}, "wrong bricks");
        other = m;
        other.background = -other.background;
        writeBrickManifest(bad.string(), other);
        expectRefused(bad.string(), {"out.rank0000.vdb", "background"}, "wrong background");
    }
    // a piece of another run in place of rank 1's
    const fs::path otherDir = levelforge_test::scratchDir("merge_bad_other_run");
    levelforge_test::writePieces(knot, o, 3, 4, otherDir);
    fs::copy_file(dir / "out.rank0001.vdb", dir / "keep.vdb", fs::copy_options::overwrite_existing);
    fs::copy_file(otherDir / "out.rank0001.vdb", dir / "out.rank0001.vdb", fs::copy_options::overwrite_existing);
    expectRefused(manifest, {"out.rank0001.vdb", "not a piece of this manifest"}, "a piece of another run");
    // rank 2's piece where rank 1's should be (same run, same size check bypassed by its own bytes)
    fs::copy_file(dir / "keep.vdb", dir / "out.rank0001.vdb", fs::copy_options::overwrite_existing);
    fs::copy_file(dir / "out.rank0002.vdb", dir / "keep2.vdb", fs::copy_options::overwrite_existing);
    {
        BrickManifest m = readBrickManifest(manifest);
        std::swap(m.pieces[1].file, m.pieces[2].file);
        std::swap(m.pieces[1].bytes, m.pieces[2].bytes);
        writeBrickManifest(bad.string(), m);
        expectRefused(bad.string(), {"out.rank0002.vdb", "rank 2 of 3's piece"}, "swapped pieces");
    }
    // a piece that is not a VDB file at all, one cut short, one missing
    writeAll(dir / "out.rank0002.vdb", std::string(size_t(fs::file_size(dir / "keep2.vdb")), 'x'));
    expectRefused(manifest, {"out.rank0002.vdb"}, "not a VDB file");
    fs::remove(dir / "out.rank0002.vdb");
    expectRefused(manifest, {"out.rank0002.vdb", "no such file"}, "missing piece");
    fs::copy_file(dir / "keep2.vdb", dir / "out.rank0002.vdb");
    EXPECT_NO_THROW(mergeBrickPieces(manifest)) << "whole again";
}
