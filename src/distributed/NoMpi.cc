// SPDX-License-Identifier: Apache-2.0
// Built instead of MpiDistributedMeshToSdf.cc when levelforge is built without MPI: the
// distributed entry points say how to get it (distributed/DistributedMeshToSdf.h).
#include <levelforge/core/Exceptions.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>

namespace levelforge {
namespace {

[[noreturn]] void noMpi()
{
    throw InvalidArgumentError("--distributed needs MPI, and this levelforge was built without it: install OpenMPI "
                               "(apt-get install libopenmpi-dev openmpi-bin, or scripts/setup), rebuild with "
                               "-DLEVELFORGE_MPI=ON and run under mpirun (docs/distributed.md)");
}

} // namespace

bool mpiAvailable() { return false; }
int distributedRank() { noMpi(); }
int distributedSize() { noMpi(); }
void runOnAllRanks(const std::function<void()>&) { noMpi(); }
openvdb::FloatGrid::Ptr distributedMeshToSdf(const TriangleMesh&, const MeshToSdfOptions&, int, DistributedStats*)
{
    noMpi();
}
std::string distributedMeshToSdfPieces(const TriangleMesh&, const MeshToSdfOptions&, const std::string&, int,
                                       DistributedStats*)
{
    noMpi();
}

} // namespace levelforge
