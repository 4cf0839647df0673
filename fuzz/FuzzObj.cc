// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target obj: readMesh() on OBJ (Wavefront) files; checks what MeshIO.h promises
///        of every mesh it returns (indices in range, finite coordinates, three distinct corners).
#include "FuzzCommon.h"

LF_FUZZ_TARGET(obj)
{
    return levelforge::fuzz::fuzzMeshFile(data, size, ".obj");
}
