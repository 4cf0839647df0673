// SPDX-License-Identifier: Apache-2.0
// The union of the parts of a brick decomposition, built part by part, and its finish
// (distributed/DistributedMeshToSdf.h): finishBrickUnion() adds every part at once, the merge of
// per-rank pieces (BrickManifest.cc) one file at a time. One finish for both, so both equal
// meshToSdf() bit for bit.
#pragma once

#include <levelforge/distributed/DistributedMeshToSdf.h>

#include <openvdb/openvdb.h>

#include <string>

namespace levelforge::distributed_internal {

class BrickUnion
{
public:
    explicit BrickUnion(BrickFinish finish) : mFinish(std::move(finish)) {}

    /// Moves the leaves of @p part into the union (the first part's tree becomes the union's
    /// when it holds leaves only, as a part from meshToSdfBricks() does); @p part is left
    /// empty. @p what names the part in errors ("part 2", "'out.rank0002.vdb'").
    /// @throws InvalidArgumentError another background, transform or sign than the first part
    ///         (or a sign other than the finish's), a leaf already in the union
    void add(openvdb::FloatGrid& part, const std::string& what);

    /// Leaves in the union so far.
    uint64_t leafCount() const;

    /// Finishes the union as meshToSdf() does (signed flood fill for the pseudonormal sign,
    /// the interior fill, the grid's name, class and metadata). Call once.
    /// @throws InvalidArgumentError nothing was added
    openvdb::FloatGrid::Ptr finish(MeshToSdfStats* stats = nullptr);

private:
    BrickFinish mFinish;
    openvdb::FloatTree::Ptr mTree;
    openvdb::math::Transform::Ptr mTransform;
    float mBackground = 0.0f;
    std::string mFirst;
};

} // namespace levelforge::distributed_internal
