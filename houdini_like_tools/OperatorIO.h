// SPDX-License-Identifier: Apache-2.0
// levelforge operators — where inputs come from and outputs go: files, built-in shapes, or
// grids and meshes kept in memory between the steps of a pipeline (`levelforge run`).
//
// Every operator reads and writes through these functions, never through levelforge::readGrids
// / writeGridsAtomic / readMesh / writeMesh directly, so that a pipeline step can hand its result
// to the next one without a file round trip:
//
//  - a name that starts with '@' ("@band") is an in-memory slot of the running pipeline
//    (OperatorArgs::memory()); writing it stores the grids (or mesh), reading it gives a deep copy,
//    so a step can never change what another step reads. Outside `levelforge run` an '@' name is
//    a usage error;
//  - any other name is a file: read under a ReadingScope (Ctrl-C ends a read at once), written
//    atomically (temp + rename; on failure the target is left as it was).
#pragma once

#include "Operator.h"

#include <levelforge/io/MeshIO.h>

#include <openvdb/openvdb.h>

#include <map>
#include <mutex>
#include <string>

namespace levelforge::ops {

/// True for the name of an in-memory slot ("@band").
bool isMemoryName(const std::string& name);

/// @brief Grids and meshes kept in memory between the steps of one pipeline run (one per frame).
///        Thread-safe; values are stored as given and handed out as deep copies.
class MemoryStore
{
public:
    /// Stores @p grids (and the file-level metadata a file would have had) under @p name.
    void putGrids(const std::string& name, const openvdb::GridPtrVec& grids, const openvdb::MetaMap& fileMeta);
    void putMesh(const std::string& name, const TriangleMesh& mesh);
    /// Deep copies of the grids stored under @p name.
    /// @throws UsageError nothing was stored under @p name (yet)
    openvdb::GridPtrVecPtr grids(const std::string& name) const;
    /// @throws UsageError no mesh was stored under @p name (yet)
    TriangleMesh mesh(const std::string& name) const;
    bool hasGrids(const std::string& name) const;
    bool hasMesh(const std::string& name) const;
    void clear();

private:
    mutable std::mutex mMutex;
    std::map<std::string, openvdb::GridPtrVec> mGrids;
    std::map<std::string, TriangleMesh> mMeshes;
};

/// @brief The grids of a .vdb file, or of the in-memory slot @p path.
/// @throws IoError the file cannot be read; UsageError an '@' name outside a pipeline or not
///         written by an earlier step; InterruptedError Ctrl-C before the read began
openvdb::GridPtrVecPtr readGridsInput(const OperatorArgs& args, const std::string& path);

/// @brief Writes @p grids to the .vdb file @p path atomically (with @p fileMeta as the file's
///        metadata), or stores them in the in-memory slot @p path.
void writeGridsOutput(const OperatorArgs& args, const std::string& path, const openvdb::GridPtrVec& grids,
                      const openvdb::MetaMap& fileMeta);

/// @brief Writes the grids of an input file with one of them replaced (the operators that change
///        one grid of a file and pass the others through: reshape, smooth, expand, rebuild), with
///        the file metadata every operator writes ("creator": generatorString()).
/// @param[in] grids     the grids read from the input
/// @param[in] replaced  the grid of @p grids that was worked on
/// @param[in] by        its replacement
void writeGridsReplacing(const OperatorArgs& args, const std::string& path, const openvdb::GridPtrVec& grids,
                         const openvdb::GridBase::Ptr& replaced, const openvdb::GridBase::Ptr& by);

/// @brief Fails fast, before any work, when the output @p path cannot be written (see
///        levelforge::checkOutputPath()); nothing to check for an in-memory slot.
void checkOutputTarget(const OperatorArgs& args, const std::string& path);

/// @brief A mesh file, a built-in shape ("builtin:torus-knot", see reference/MeshShapes.h), or the
///        in-memory slot @p name. @p info is filled for files only.
TriangleMesh readMeshInput(const OperatorArgs& args, const std::string& name, MeshReadInfo* info = nullptr);
/// The same with read options (attributes to keep); options are ignored for built-ins and slots.
TriangleMesh readMeshInput(const OperatorArgs& args, const std::string& name, const MeshReadOptions& options,
                           MeshReadInfo& info);

/// @brief Writes @p mesh to @p path (format by extension, see io/MeshIO.h; atomic), or stores it
///        in the in-memory slot @p path.
void writeMeshOutput(const OperatorArgs& args, const TriangleMesh& mesh, const std::string& path);

} // namespace levelforge::ops
