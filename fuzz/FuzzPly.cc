// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target ply: readMesh() on PLY files (ASCII, binary little and big endian); checks what MeshIO.h promises
///        of every mesh it returns (indices in range, finite coordinates, three distinct corners).
#include "FuzzCommon.h"

LF_FUZZ_TARGET(ply)
{
    return levelforge::fuzz::fuzzMeshFile(data, size, ".ply");
}
