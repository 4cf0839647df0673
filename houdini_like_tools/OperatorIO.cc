// SPDX-License-Identifier: Apache-2.0
// levelforge operators — files, built-in shapes and in-memory pipeline slots (see OperatorIO.h).
#include "OperatorIO.h"

#include "Interrupt.h"

#include <levelforge/io/VdbIO.h>
#include <levelforge/reference/MeshShapes.h>

namespace levelforge::ops {
namespace {

MemoryStore& requireMemory(const OperatorArgs& args, const std::string& name)
{
    if (!args.memory()) {
        throw UsageError("'" + name + "' names a grid kept in memory between the steps of a pipeline; "
                         "such names are only valid in the files of 'levelforge run'");
    }
    return *args.memory();
}

} // namespace

bool isMemoryName(const std::string& name) { return !name.empty() && name[0] == '@'; }

void MemoryStore::putGrids(const std::string& name, const openvdb::GridPtrVec& grids, const openvdb::MetaMap&)
{
    const std::lock_guard<std::mutex> lock(mMutex);
    mMeshes.erase(name);
    mGrids[name] = grids;
}

void MemoryStore::putMesh(const std::string& name, const TriangleMesh& mesh)
{
    const std::lock_guard<std::mutex> lock(mMutex);
    mGrids.erase(name);
    mMeshes[name] = mesh;
}

openvdb::GridPtrVecPtr MemoryStore::grids(const std::string& name) const
{
    openvdb::GridPtrVec stored;
    {
        const std::lock_guard<std::mutex> lock(mMutex);
        auto it = mGrids.find(name);
        if (it == mGrids.end()) {
            if (mMeshes.count(name)) throw UsageError("'" + name + "' holds a mesh, not grids");
            throw UsageError("no grids in '" + name + "': no earlier step writes it");
        }
        stored = it->second;
    }
    auto copies = std::make_shared<openvdb::GridPtrVec>();
    copies->reserve(stored.size());
    for (const openvdb::GridBase::Ptr& g : stored) copies->push_back(g->deepCopyGrid());
    return copies;
}

TriangleMesh MemoryStore::mesh(const std::string& name) const
{
    const std::lock_guard<std::mutex> lock(mMutex);
    auto it = mMeshes.find(name);
    if (it == mMeshes.end()) {
        if (mGrids.count(name)) throw UsageError("'" + name + "' holds grids, not a mesh");
        throw UsageError("no mesh in '" + name + "': no earlier step writes it");
    }
    return it->second;
}

bool MemoryStore::hasGrids(const std::string& name) const
{
    const std::lock_guard<std::mutex> lock(mMutex);
    return mGrids.count(name) != 0;
}

bool MemoryStore::hasMesh(const std::string& name) const
{
    const std::lock_guard<std::mutex> lock(mMutex);
    return mMeshes.count(name) != 0;
}

void MemoryStore::clear()
{
    const std::lock_guard<std::mutex> lock(mMutex);
    mGrids.clear();
    mMeshes.clear();
}

openvdb::GridPtrVecPtr readGridsInput(const OperatorArgs& args, const std::string& path)
{
    if (isMemoryName(path)) return requireMemory(args, path).grids(path);
    const ReadingScope reading; // SIGINT / SIGTERM end the process at once while reading
    return readGrids(path);
}

void writeGridsOutput(const OperatorArgs& args, const std::string& path, const openvdb::GridPtrVec& grids,
                      const openvdb::MetaMap& fileMeta)
{
    if (isMemoryName(path)) {
        requireMemory(args, path).putGrids(path, grids, fileMeta);
        return;
    }
    writeGridsAtomic(path, grids, fileMeta);
}

void writeGridsReplacing(const OperatorArgs& args, const std::string& path, const openvdb::GridPtrVec& grids,
                         const openvdb::GridBase::Ptr& replaced, const openvdb::GridBase::Ptr& by)
{
    openvdb::GridPtrVec result;
    for (const openvdb::GridBase::Ptr& g : grids) result.push_back(g == replaced ? by : g);
    openvdb::MetaMap fileMeta;
    fileMeta.insertMeta("creator", openvdb::StringMetadata(generatorString()));
    writeGridsOutput(args, path, result, fileMeta);
}

void checkOutputTarget(const OperatorArgs& args, const std::string& path)
{
    if (isMemoryName(path)) {
        requireMemory(args, path);
        return;
    }
    checkOutputPath(path);
}

TriangleMesh readMeshInput(const OperatorArgs& args, const std::string& name, MeshReadInfo* info)
{
    if (isMemoryName(name)) return requireMemory(args, name).mesh(name);
    if (isBuiltinMeshName(name)) return makeBuiltinMesh(name); // source set by the generator
    const ReadingScope reading;
    if (info) return readMesh(name, *info);
    return readMesh(name);
}

TriangleMesh readMeshInput(const OperatorArgs& args, const std::string& name, const MeshReadOptions& options,
                           MeshReadInfo& info)
{
    if (isMemoryName(name) || isBuiltinMeshName(name)) return readMeshInput(args, name, nullptr);
    const ReadingScope reading;
    return readMesh(name, options, info);
}

void writeMeshOutput(const OperatorArgs& args, const TriangleMesh& mesh, const std::string& path)
{
    if (isMemoryName(path)) {
        requireMemory(args, path).putMesh(path, mesh);
        return;
    }
    writeMesh(mesh, path);
}

} // namespace levelforge::ops
