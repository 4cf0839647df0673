// SPDX-License-Identifier: Apache-2.0
// One conversion on the ranks of MPI_COMM_WORLD (distributed/DistributedMeshToSdf.h): MPI set-up,
// the collective error agreement, the decomposition broadcast from rank 0, and the gather of the
// parts to rank 0. Built only with MPI (LEVELFORGE_MPI; NoMpi.cc otherwise). Every MPI call is
// made by the thread that called in (MPI_THREAD_FUNNELED); TBB's workers never call MPI.
#include "detail/Timer.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/distributed/DistributedMeshToSdf.h>
#include <levelforge/io/VdbIO.h>

#include <mpi.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <climits>
#include <cstdlib>
#include <memory>
#include <new>
#include <vector>

namespace levelforge {
namespace {

void finalizeAtExit()
{
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) MPI_Finalize();
}

void ensureMpi()
{
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (initialized) return;
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
        throw Error("MPI could not be initialized (run under mpirun; see docs/distributed.md)");
    std::atexit(finalizeAtExit);
}

int worldRank()
{
    ensureMpi();
    int r = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &r);
    return r;
}

int worldSize()
{
    ensureMpi();
    int n = 1;
    MPI_Comm_size(MPI_COMM_WORLD, &n);
    return n;
}

enum Kind : int { kOk = 0, kArgument, kMesh, kIo, kLimit, kInterrupted, kError, kMemory, kOther };

[[noreturn]] void throwKind(int kind, const std::string& msg)
{
    switch (kind) {
    case kArgument: throw InvalidArgumentError(msg);
    case kMesh: throw InvalidMeshError(msg);
    case kIo: throw IoError(msg);
    case kLimit: throw ResourceLimitError(msg);
    case kInterrupted: throw InterruptedError(msg);
    case kMemory: throw std::bad_alloc();
    default: throw Error(msg);
    }
}

constexpr size_t kChunk = size_t(256) << 20; // bytes per message (MPI counts are int)
constexpr size_t kLeavesPerPiece = 8192;      // about 17 MiB of leaves a piece
constexpr uint64_t kFailed = ~uint64_t(0);    // a piece header: the sender failed

/// Test aid (tests/distributed/TestCliDistributedMerge.cc): LEVELFORGE_DISTRIBUTED_INJECT=piece:R
/// fails rank R right after it wrote its piece, =manifest fails rank 0's manifest write after
/// every piece was written; the clean-up after a late failure is tested with them.
bool injected(const std::string& what)
{
    const char* v = std::getenv("LEVELFORGE_DISTRIBUTED_INJECT");
    return v && what == v;
}

double peakMiB()
{
    struct rusage ru {};
    getrusage(RUSAGE_SELF, &ru);
    return double(ru.ru_maxrss) / 1024.0; // Linux: KiB
}

} // namespace

bool mpiAvailable() { return true; }
int distributedRank() { return worldRank(); }
int distributedSize() { return worldSize(); }

void runOnAllRanks(const std::function<void()>& step)
{
    const int rank = worldRank(), size = worldSize();
    int kind = kOk;
    std::string msg;
    try {
        step();
    } catch (const InterruptedError& e) {
        kind = kInterrupted, msg = e.what();
    } catch (const InvalidMeshError& e) {
        kind = kMesh, msg = e.what();
    } catch (const IoError& e) {
        kind = kIo, msg = e.what();
    } catch (const ResourceLimitError& e) {
        kind = kLimit, msg = e.what();
    } catch (const InvalidArgumentError& e) {
        kind = kArgument, msg = e.what();
    } catch (const Error& e) {
        kind = kError, msg = e.what();
    } catch (const std::bad_alloc&) {
        kind = kMemory, msg = "out of memory";
    } catch (const std::exception& e) {
        kind = kOther, msg = e.what();
    } catch (...) {
        kind = kOther, msg = "unknown failure";
    }
    if (msg.size() > 2000) msg = msg.substr(0, 2000) + " ...";
    // the lowest failing rank tells everyone what happened
    const int mine = kind == kOk ? size : rank;
    int failed = size;
    MPI_Allreduce(&mine, &failed, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    if (failed == size) return;
    int head[2] = {kind, int(msg.size())};
    MPI_Bcast(head, 2, MPI_INT, failed, MPI_COMM_WORLD);
    msg.resize(size_t(head[1]));
    MPI_Bcast(msg.data(), head[1], MPI_CHAR, failed, MPI_COMM_WORLD);
    if (size > 1) msg = "rank " + std::to_string(failed) + " of " + std::to_string(size) + ": " + msg;
    throwKind(head[0], msg);
}

namespace {

/// What one rank computed: the shared decomposition, its bricks and its part.
struct RankWork
{
    BrickDecomposition d;
    std::vector<openvdb::CoordBBox> boxes;
    openvdb::FloatGrid::Ptr part;
    SignMode sign = SignMode::Pseudonormal;
    double partSeconds = 0.0, partPeak = 0.0;
    uint64_t partActive = 0, partTriangles = 0;
};

/// The decomposition (rank 0 decides, every rank gets the same list) and this rank's part.
RankWork computeRankPart(const TriangleMesh& mesh, const MeshToSdfOptions& o, int brickLog2, DistributedStats& st,
                         detail::Clock::time_point t0)
{
    const int rank = st.rank, size = st.ranks;
    RankWork w;
    BrickDecomposition& d = w.d;
    runOnAllRanks([&] {
        w.sign = checkDistributable(mesh, o);
        if (rank != 0) return;
        const double h = resolveVoxelSize(mesh, o);
        const float ext = static_cast<float>(o.widthInVoxels(o.exteriorWidth, h));
        const float in = static_cast<float>(o.widthInVoxels(o.interiorWidth, h));
        const double limit = w.sign == SignMode::Unsigned ? double(ext) : double(std::max(ext, in));
        d = decomposeIntoBricks(mesh, h, limit, size, brickLog2);
    });
    {
        uint64_t n = d.origins.size();
        MPI_Bcast(&n, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
        std::vector<int> packed(4 * n);
        if (rank == 0)
            for (size_t i = 0; i < n; ++i) {
                for (int k = 0; k < 3; ++k) packed[4 * i + k] = d.origins[i][k];
                packed[4 * i + 3] = d.owner[i];
            }
        d.weights.resize(n);
        MPI_Bcast(packed.data(), int(packed.size()), MPI_INT, 0, MPI_COMM_WORLD);
        MPI_Bcast(d.weights.data(), int(n), MPI_DOUBLE, 0, MPI_COMM_WORLD);
        d.brickLog2 = brickLog2;
        d.ranks = size;
        d.origins.resize(n);
        d.owner.resize(n);
        for (size_t i = 0; i < n; ++i) {
            d.origins[i] = openvdb::Coord(packed[4 * i], packed[4 * i + 1], packed[4 * i + 2]);
            d.owner[i] = packed[4 * i + 3];
        }
    }
    st.bricks = d.origins.size();
    st.secondsDecompose = detail::secondsSince(t0);

    // ---- this rank's bricks
    w.boxes = d.boxesOf(rank);
    runOnAllRanks([&] {
        const auto tp = detail::Clock::now();
        w.part = meshToSdfBricks(mesh, o, w.boxes, &st.sdf);
        w.partSeconds = detail::secondsSince(tp);
        w.partPeak = peakMiB();
    });
    w.partActive = st.sdf.band.activeVoxels;
    w.partTriangles = st.sdf.band.triangles;
    return w;
}

/// The per-rank numbers to rank 0 (collective).
void gatherRankRows(DistributedStats& st, const RankWork& w, uint64_t bytes)
{
    const int rank = st.rank, size = st.ranks;
    constexpr int kRow = 8;
    double mine[kRow] = {double(w.boxes.size()), double(w.partTriangles), double(w.partActive), double(bytes),
                         w.d.loadOf(rank), w.partSeconds, peakMiB(), w.partPeak};
    std::vector<double> every(size_t(kRow * size), 0.0);
    MPI_Gather(mine, kRow, MPI_DOUBLE, every.data(), kRow, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    const int rows = rank == 0 ? size : 1;
    for (int r = 0; r < rows; ++r) {
        const double* v = rank == 0 ? &every[size_t(kRow * r)] : mine;
        st.rankBricks.push_back(uint64_t(v[0]));
        st.rankTriangles.push_back(uint64_t(v[1]));
        st.rankActiveVoxels.push_back(uint64_t(v[2]));
        st.rankBytes.push_back(uint64_t(v[3]));
        st.rankEstimate.push_back(v[4]);
        st.rankSeconds.push_back(v[5]);
        st.rankPeakMiB.push_back(v[6]);
        st.rankPartPeakMiB.push_back(v[7]);
    }
}

} // namespace

openvdb::FloatGrid::Ptr distributedMeshToSdf(const TriangleMesh& mesh, const MeshToSdfOptions& o, int brickLog2,
                                             DistributedStats* statsOut)
{
    const auto t0 = detail::Clock::now();
    const int rank = worldRank(), size = worldSize();
    DistributedStats st;
    st.rank = rank;
    st.ranks = size;
    st.brickLog2 = brickLog2;
    RankWork w = computeRankPart(mesh, o, brickLog2, st, t0);
    openvdb::FloatGrid::Ptr& part = w.part; // rank 0 keeps its own part as a grid

    // ---- the gather, rank by rank, in pieces of kLeavesPerPiece leaves: a rank never holds more
    //      than one piece's bytes besides its leaves (which it frees as they go), rank 0 merges
    //      each piece as it comes. Per piece: its size (tag 6; 0: no more, kFailed: the rank
    //      failed, its message follows on tag 8), then its bytes (tag 7, at most kChunk a message).
    const auto tg = detail::Clock::now();
    uint64_t myBytes = 0;
    std::vector<openvdb::FloatGrid::Ptr> parts;
    std::string gatherError;
    if (rank == 0) {
        parts.push_back(part);
        part.reset();
        std::string buffer;
        for (int r = 1; r < size; ++r) {
            for (;;) {
                uint64_t head = 0;
                MPI_Recv(&head, 1, MPI_UINT64_T, r, 6, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                if (head == 0) break;
                if (head == kFailed) {
                    MPI_Status status;
                    MPI_Probe(r, 8, MPI_COMM_WORLD, &status);
                    int n = 0;
                    MPI_Get_count(&status, MPI_CHAR, &n);
                    std::string msg(size_t(n), '\0');
                    MPI_Recv(msg.data(), n, MPI_CHAR, r, 8, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                    if (gatherError.empty()) gatherError = "rank " + std::to_string(r) + ": " + msg;
                    break;
                }
                bool keep = true;
                try {
                    buffer.assign(size_t(head), '\0');
                } catch (const std::bad_alloc&) {
                    keep = false;
                    if (gatherError.empty()) gatherError = "out of memory receiving rank " + std::to_string(r) + "'s part";
                }
                std::string sink;
                for (uint64_t off = 0; off < head; off += kChunk) {
                    const int n = int(std::min<uint64_t>(kChunk, head - off));
                    if (!keep) sink.assign(size_t(n), '\0'); // drained, so that rank r is not left waiting
                    MPI_Recv(keep ? buffer.data() + off : sink.data(), n, MPI_BYTE, r, 7, MPI_COMM_WORLD,
                             MPI_STATUS_IGNORE);
                }
                if (!keep) continue;
                try {
                    parts.push_back(deserializeGrid(buffer));
                } catch (const std::exception& e) {
                    if (gatherError.empty()) gatherError = "rank " + std::to_string(r) + "'s part: " + e.what();
                }
            }
        }
        std::string().swap(buffer);
    } else {
        using FloatLeaf = openvdb::FloatTree::LeafNodeType;
        std::vector<FloatLeaf*> stolen;
        if (part) part->tree().stealNodes(stolen);
        std::vector<std::unique_ptr<FloatLeaf>> leaves(stolen.begin(), stolen.end());
        size_t next = 0;
        do {
            std::string bytes, failure;
            try {
                if (!part) throw Error("no part");
                auto piece = openvdb::gridPtrCast<openvdb::FloatGrid>(part->copyGridWithNewTree());
                for (size_t n = 0; next < leaves.size() && n < kLeavesPerPiece; ++next, ++n) {
                    piece->tree().addLeaf(leaves[next].get());
                    (void)leaves[next].release();
                }
                bytes = serializeGrid(*piece);
            } catch (const std::bad_alloc&) {
                failure = "out of memory serializing its part";
            } catch (const std::exception& e) {
                failure = std::string("serializing its part: ") + e.what();
            }
            uint64_t head = failure.empty() ? uint64_t(bytes.size()) : kFailed;
            MPI_Send(&head, 1, MPI_UINT64_T, 0, 6, MPI_COMM_WORLD);
            if (!failure.empty()) {
                MPI_Send(failure.data(), int(failure.size()), MPI_CHAR, 0, 8, MPI_COMM_WORLD);
                break;
            }
            for (uint64_t off = 0; off < head; off += kChunk) {
                const int n = int(std::min<uint64_t>(kChunk, head - off));
                MPI_Send(bytes.data() + off, n, MPI_BYTE, 0, 7, MPI_COMM_WORLD);
            }
            myBytes += head;
            if (next == leaves.size()) {
                const uint64_t done = 0;
                MPI_Send(&done, 1, MPI_UINT64_T, 0, 6, MPI_COMM_WORLD);
            }
        } while (next < leaves.size());
        part.reset();
    }
    const uint64_t mySize = myBytes;
    st.secondsGather = detail::secondsSince(tg);

    // ---- rank 0 merges and finishes
    openvdb::FloatGrid::Ptr grid;
    const auto tf = detail::Clock::now();
    runOnAllRanks([&] {
        if (rank != 0) return;
        if (!gatherError.empty()) throw IoError(gatherError);
        MeshToSdfStats fin;
        grid = finishBrickUnion(mesh, o, parts, &fin);
        st.sdf.sign = fin.sign;
        st.sdf.filledVoxels = fin.filledVoxels;
        st.sdf.voxelSize = fin.voxelSize;
        st.sdf.exteriorBandVoxels = fin.exteriorBandVoxels;
        st.sdf.interiorBandVoxels = fin.interiorBandVoxels;
        st.sdf.method = fin.method;
    });
    st.secondsFinish = detail::secondsSince(tf);

    // ---- per-rank numbers to rank 0
    gatherRankRows(st, w, mySize);
    st.seconds = detail::secondsSince(t0);
    st.sdf.seconds = st.seconds;
    if (statsOut) *statsOut = st;
    return grid;
}

std::string distributedMeshToSdfPieces(const TriangleMesh& mesh, const MeshToSdfOptions& o, const std::string& output,
                                       int brickLog2, DistributedStats* statsOut)
{
    const auto t0 = detail::Clock::now();
    const int rank = worldRank(), size = worldSize();
    DistributedStats st;
    st.rank = rank;
    st.ranks = size;
    st.brickLog2 = brickLog2;
    const std::string manifest = manifestFileName(output), mine = pieceFileName(output, rank);
    // fail fast: every rank its piece's place, rank 0 the manifest's
    runOnAllRanks([&] {
        if (output.empty()) throw InvalidArgumentError("per-rank output: no output path");
        checkOutputPath(mine);
        if (rank == 0) checkOutputPath(manifest);
    });
    // the run's id, from rank 0: every piece carries it, so the merge refuses a stale piece
    char id[33] = {};
    if (rank == 0) {
        const std::string made = newPieceRunId();
        std::snprintf(id, sizeof(id), "%s", made.c_str());
    }
    MPI_Bcast(id, 33, MPI_CHAR, 0, MPI_COMM_WORLD);

    RankWork w = computeRankPart(mesh, o, brickLog2, st, t0);
    BrickFinish finish;
    const float background = w.part ? w.part->background() : 0.0f;
    const openvdb::math::Transform::Ptr transform = w.part ? w.part->transform().copy() : nullptr;

    // ---- every rank writes its piece (atomically); rank 0 first removes an earlier manifest,
    //      whose pieces are being replaced
    const auto tw = detail::Clock::now();
    BrickPiece piece;
    bool written = false;
    auto removeMine = [&] {
        if (!written) return;
        std::remove(mine.c_str());
        written = false;
    };
    try {
        runOnAllRanks([&] {
            if (rank == 0) {
                finish = brickFinishFor(mesh, o);
                std::error_code ec;
                if (std::filesystem::is_regular_file(manifest, ec) && std::remove(manifest.c_str()) != 0)
                    throw IoError("cannot replace the manifest '" + manifest + "': " + std::strerror(errno));
            }
            if (!w.part) throw Error("no part");
            piece = writeBrickPiece(mine, *w.part, id, rank, size);
            written = true;
            if (injected("piece:" + std::to_string(rank))) throw IoError("cannot write '" + mine + "': injected failure");
            w.part.reset(); // this rank's leaves are on disk
        });
        // ---- the pieces' counts to rank 0, which writes the manifest
        uint64_t row[3] = {piece.leaves, piece.activeVoxels, piece.bytes};
        std::vector<uint64_t> rows(size_t(3 * size), 0);
        MPI_Gather(row, 3, MPI_UINT64_T, rows.data(), 3, MPI_UINT64_T, 0, MPI_COMM_WORLD);
        runOnAllRanks([&] {
            if (rank != 0) return;
            BrickManifest m;
            m.id = id;
            m.generator = generatorString();
            m.output = std::filesystem::path(output).filename().string();
            m.ranks = size;
            m.brickLog2 = brickLog2;
            m.background = background;
            m.transform = transform;
            m.finish = finish;
            for (int r = 0; r < size; ++r) {
                BrickPiece p;
                p.rank = r;
                p.file = std::filesystem::path(pieceFileName(output, r)).filename().string();
                for (const openvdb::CoordBBox& b : w.d.boxesOf(r)) p.bricks.push_back(b.min());
                p.leaves = rows[size_t(3 * r)];
                p.activeVoxels = rows[size_t(3 * r + 1)];
                p.bytes = rows[size_t(3 * r + 2)];
                m.pieces.push_back(std::move(p));
            }
            if (injected("manifest")) throw IoError("cannot write '" + manifest + "': injected failure");
            writeBrickManifest(manifest, m);
        });
    } catch (...) {
        removeMine(); // every rank gets here together (runOnAllRanks): no piece is left
        throw;
    }
    st.secondsGather = detail::secondsSince(tw);
    st.sdf.sign = finish.sign;
    st.sdf.voxelSize = finish.voxelSize;
    st.sdf.exteriorBandVoxels = finish.exteriorBandVoxels;
    st.sdf.interiorBandVoxels = finish.interiorBandVoxels;
    gatherRankRows(st, w, piece.bytes);
    st.seconds = detail::secondsSince(t0);
    if (statsOut) *statsOut = st;
    return manifest;
}

} // namespace levelforge
