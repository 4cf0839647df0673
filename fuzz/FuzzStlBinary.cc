// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target stl_binary: readMesh() on STL files read as binary (the .stlb extension); checks what MeshIO.h promises
///        of every mesh it returns (indices in range, finite coordinates, three distinct corners).
#include "FuzzCommon.h"

LF_FUZZ_TARGET(stl_binary)
{
    return levelforge::fuzz::fuzzMeshFile(data, size, ".stlb");
}
