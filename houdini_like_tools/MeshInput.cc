// SPDX-License-Identifier: Apache-2.0
#include "MeshInput.h"

#include <levelforge/reference/MeshShapes.h>

namespace levelforge::ops {

TriangleMesh readMeshInput(const std::string& name, MeshReadInfo* info)
{
    if (isBuiltinMeshName(name)) return makeBuiltinMesh(name); // source set by the generator
    if (info) return readMesh(name, *info);
    return readMesh(name);
}

} // namespace levelforge::ops
