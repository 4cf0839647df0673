// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target stl_ascii: readMesh() on STL files read as ASCII (the .stla extension); checks what MeshIO.h promises
///        of every mesh it returns (indices in range, finite coordinates, three distinct corners).
#include "FuzzCommon.h"

LF_FUZZ_TARGET(stl_ascii)
{
    return levelforge::fuzz::fuzzMeshFile(data, size, ".stla");
}
