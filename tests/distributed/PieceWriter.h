// SPDX-License-Identifier: Apache-2.0
// Pieces of a distributed conversion written in one process (what distributedMeshToSdfPieces()
// does under MPI), for the merge tests with and without MPI.
#pragma once

#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/VdbIO.h>

#include <algorithm>
#include <filesystem>
#include <string>

namespace levelforge_test {

/// Converts @p mesh in @p ranks parts, writes each as a piece of dir/out.vdb and the manifest
/// (what distributedMeshToSdfPieces() does under MPI); returns the manifest's path.
inline std::string writePieces(const levelforge::TriangleMesh& mesh, const levelforge::MeshToSdfOptions& o, int ranks, int brickLog2,
                        const std::filesystem::path& dir, const std::string& id = levelforge::newPieceRunId())
{
    using namespace levelforge;
    const std::string output = (dir / "out.vdb").string();
    const BrickFinish finish = brickFinishFor(mesh, o);
    const double limit = finish.sign == SignMode::Unsigned
                             ? double(finish.exteriorBandVoxels)
                             : double(std::max(finish.exteriorBandVoxels, finish.interiorBandVoxels));
    const BrickDecomposition d = decomposeIntoBricks(mesh, finish.voxelSize, limit, ranks, brickLog2);
    BrickManifest m;
    m.id = id;
    m.generator = generatorString();
    m.output = "out.vdb";
    m.ranks = ranks;
    m.brickLog2 = brickLog2;
    m.finish = finish;
    for (int r = 0; r < ranks; ++r) {
        const openvdb::FloatGrid::Ptr part = meshToSdfBricks(mesh, o, d.boxesOf(r));
        if (r == 0) {
            m.background = part->background();
            m.transform = part->transform().copy();
        }
        BrickPiece p = writeBrickPiece(pieceFileName(output, r), *part, id, r, ranks);
        for (const openvdb::CoordBBox& b : d.boxesOf(r)) p.bricks.push_back(b.min());
        m.pieces.push_back(p);
    }
    const std::string manifest = manifestFileName(output);
    writeBrickManifest(manifest, m);
    return manifest;
}

} // namespace levelforge_test
