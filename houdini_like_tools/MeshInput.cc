// SPDX-License-Identifier: Apache-2.0
#include "MeshInput.h"
#include "Interrupt.h"

#include <levelforge/reference/MeshShapes.h>

namespace levelforge::ops {

TriangleMesh readMeshInput(const std::string& name, MeshReadInfo* info)
{
    if (isBuiltinMeshName(name)) return makeBuiltinMesh(name); // source set by the generator
    const ReadingScope reading; // SIGINT / SIGTERM end the process at once while reading
    if (info) return readMesh(name, *info);
    return readMesh(name);
}

} // namespace levelforge::ops
