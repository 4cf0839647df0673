// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The mesh input of the operators: a mesh file (io/MeshIO.h) or a built-in shape name
///        ("builtin:torus-knot", "builtin:sphere", "builtin:box"; reference/MeshShapes.h).
#pragma once

#include <levelforge/io/MeshIO.h>

#include <string>

namespace levelforge::ops {

/// @brief Reads the mesh file @p name, or builds the built-in shape it names.
/// @param[in]  name  a path, or "builtin:<shape>"
/// @param[out] info  optional: what readMesh() found besides the mesh (untouched for built-ins)
/// @return the mesh; `source` is the path or the shape's description
/// @throws the errors of readMesh() and makeBuiltinMesh()
TriangleMesh readMeshInput(const std::string& name, MeshReadInfo* info = nullptr);

} // namespace levelforge::ops
