// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target off: readMesh() on OFF files; checks what MeshIO.h promises
///        of every mesh it returns (indices in range, finite coordinates, three distinct corners).
#include "FuzzCommon.h"

LF_FUZZ_TARGET(off)
{
    return levelforge::fuzz::fuzzMeshFile(data, size, ".off");
}
