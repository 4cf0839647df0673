// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target stl: readMesh() on STL files, ASCII or binary by OpenMesh's size rule; checks what MeshIO.h promises
///        of every mesh it returns (indices in range, finite coordinates, three distinct corners).
#include "FuzzCommon.h"

LF_FUZZ_TARGET(stl)
{
    return levelforge::fuzz::fuzzMeshFile(data, size, ".stl");
}
