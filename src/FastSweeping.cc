// levelforge — fast sweeping expansion of a level set on sparse VDB topology (see the header).
#include <levelforge/FastSweeping.h>
#include <levelforge/VectorExpansion.h>

#include <levelforge/Exceptions.h>
#include <levelforge/MeshValidation.h>
#include <levelforge/Progress.h>

#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/Morphology.h>
#include <openvdb/tools/Prune.h>
#include <openvdb/tools/SignedFloodFill.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <vector>

namespace levelforge {

namespace fast_sweeping_internal {

namespace {
/// Largest Σ max(|x_i| - a, 0) over lattice points x with |x| < radius: the face steps needed
/// after `a` cube steps (the lattice Minkowski sum of the cube and the octahedron contains x
/// iff that sum is <= b).
int faceStepsNeeded(double radius, int a)
{
    const int n = int(std::floor(radius));
    const double r2 = radius * radius;
    int b = 0;
    for (int x = 0; x <= n; ++x) {
        for (int y = 0; y <= n; ++y) {
            const double rest = r2 - double(x) * x - double(y) * y;
            if (rest <= 0) break;
            int z = int(std::floor(std::sqrt(rest)));
            while (z > 0 && double(x) * x + double(y) * y + double(z) * z >= r2) --z;
            if (double(x) * x + double(y) * y + double(z) * z >= r2) continue;
            b = std::max(b, std::max(x - a, 0) + std::max(y - a, 0) + std::max(z - a, 0));
        }
    }
    return b;
}
} // namespace

void dilationPattern(double radius, int& cubeSteps, int& faceSteps)
{
    cubeSteps = faceSteps = 0;
    if (!(radius > 0)) return;
    const int n = int(std::ceil(radius));
    int bestA = n, bestB = 0;
    // a + b is minimal (= ceil(radius) or so) from about 0.41 R on; search a small window.
    const int lo = std::max(0, int(std::floor(0.33 * radius)) - 1);
    for (int a = lo; a <= n; ++a) {
        const int b = faceStepsNeeded(radius, a);
        if (a + b < bestA + bestB) { bestA = a; bestB = b; }
        if (a > int(0.5 * radius) + 2) break;
    }
    cubeSteps = bestA;
    faceSteps = bestB;
}

} // namespace fast_sweeping_internal

namespace {

using FloatTree = openvdb::FloatTree;
using LeafT = FloatTree::LeafNodeType;
using MaskT = LeafT::NodeMaskType;
using openvdb::Coord;
using Clock = std::chrono::steady_clock;

constexpr float kBig = 1e30f; // "not yet reached" / "not part of the domain"

double seconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string num(double v)
{
    std::ostringstream os;
    os << v;
    return os.str();
}

double readBandMeta(const openvdb::FloatGrid& g, const char* key, double fallback)
{
    if (auto m = g.getMetadata<openvdb::FloatMetadata>(key)) return m->value();
    if (auto m = g.getMetadata<openvdb::DoubleMetadata>(key)) return m->value();
    return fallback;
}

void checkWidth(double v, const char* name, bool allowZero = false)
{
    if (!std::isfinite(v) || v < 0 || (!allowZero && v == 0)) {
        throw InvalidArgumentError(std::string("expandLevelSet: ") + name + " must be finite and " +
                                   (allowZero ? ">= 0" : "> 0") + ", got " + num(v));
    }
}

/// One voxel update: Godunov upwind solution of |∇φ| = 1 from the neighbour magnitudes
/// (world units; h = voxel size). Double precision: float rounding lets values creep down
/// by an ulp per round and delays convergence.
inline float godunov(double a0, double a1, double a2, double h)
{
    if (a0 > a1) std::swap(a0, a1);
    if (a1 > a2) std::swap(a1, a2);
    if (a0 > a1) std::swap(a0, a1);
    double u = a0 + h;
    if (u <= a1) return float(u);
    const double d01 = a0 - a1;
    u = 0.5 * (a0 + a1 + std::sqrt(std::max(2.0 * h * h - d01 * d01, 0.0)));
    if (u <= a2) return float(u);
    const double s = a0 + a1 + a2;
    const double q = a0 * a0 + a1 * a1 + a2 * a2 - h * h;
    return float((s + std::sqrt(std::max(s * s - 3.0 * q, 0.0))) / 3.0);
}

/// The sweeper: leaves of the expanded tree, their face neighbours, frozen/updatable masks and
/// the hyperplane buckets of the four sweep diagonals.
class Sweeper
{
public:
    Sweeper(FloatTree& tree, const FloatTree& frozen, float h, float tol,
            openvdb::util::NullInterrupter* interrupter)
        : mH(h), mTol(tol), mInterrupter(interrupter)
    {
        tree.getNodes(mLeaves);
        const size_t n = mLeaves.size();
        std::map<Coord, int32_t> index; // deterministic, only used during setup
        for (size_t i = 0; i < n; ++i) index.emplace(mLeaves[i]->origin(), int32_t(i));
        mNb.assign(n * 6, -1);
        mUpdatable.resize(n);
        mHasWork.assign(n, 0);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                LeafT& leaf = *mLeaves[i];
                const Coord o = leaf.origin();
                for (int k = 0; k < 3; ++k) {
                    for (int s = 0; s < 2; ++s) {
                        Coord c = o;
                        c[k] += s ? 8 : -8;
                        auto it = index.find(c);
                        mNb[i * 6 + k * 2 + s] = it == index.end() ? -1 : it->second;
                    }
                }
                MaskT upd = leaf.getValueMask();
                if (const LeafT* f = frozen.probeConstLeaf(o)) {
                    upd -= f->getValueMask();
                } else if (frozen.isValueOn(o)) {
                    upd.setOff(); // an active tile of the input covers this leaf
                }
                mUpdatable[i] = upd;
                mHasWork[i] = upd.isOff() ? 0 : 1;
                // Working values: inactive voxels are "not in the domain", new voxels not reached.
                float* v = leaf.buffer().data();
                for (int j = 0; j < 512; ++j) {
                    if (!leaf.isValueOn(j) || upd.isOn(j)) v[j] = std::copysign(kBig, v[j]);
                }
            }
        });
        // Buckets along the 4 diagonals (sx = +1; the opposite orderings run them backwards).
        for (int d = 0; d < 4; ++d) {
            const int sy = (d & 1) ? -1 : 1, sz = (d & 2) ? -1 : 1;
            std::vector<std::pair<int64_t, int32_t>> keys(n);
            for (size_t i = 0; i < n; ++i) {
                const Coord o = mLeaves[i]->origin();
                keys[i] = {int64_t(o.x() >> 3) + sy * int64_t(o.y() >> 3) + sz * int64_t(o.z() >> 3),
                           int32_t(i)};
            }
            std::sort(keys.begin(), keys.end());
            auto& buckets = mBuckets[d];
            for (size_t i = 0; i < n;) {
                size_t j = i;
                std::vector<int32_t> b;
                while (j < n && keys[j].first == keys[i].first) b.push_back(keys[j++].second);
                buckets.push_back(std::move(b));
                i = j;
            }
        }
        mLastChange.assign(n, -1);
        mLastProcessed.assign(n, -1);
        mSelfChanged.assign(n, 1);
    }

    uint64_t candidateVoxels() const
    {
        uint64_t c = 0;
        for (const LeafT* l : mLeaves) c += l->onVoxelCount();
        return c;
    }

    /// Runs rounds of 8 sweeps until converged or maxIterations; returns rounds done.
    void run(int maxIterations, ExpandLevelSetStats& stats)
    {
        static const int kOrder[8][3] = {{1, 1, 1},   {-1, -1, -1}, {1, 1, -1},  {-1, -1, 1},
                                         {1, -1, 1},  {-1, 1, -1},  {1, -1, -1}, {-1, 1, 1}};
        int64_t sweep = 0;
        int64_t step = 0; // bucket steps, in schedule order (for the skip test)
        int round = 0;
        double lastRoundMax = 0.0;
        bool converged = false;
        std::atomic<uint64_t> leafUpdates{0};
        while (round < maxIterations) {
            double roundMax = 0.0;
            bool anyChangeAboveTol = false;
            for (int o = 0; o < 8; ++o, ++sweep) {
                const int sx = kOrder[o][0], sy = kOrder[o][1], sz = kOrder[o][2];
                // diagonal index: normalise so that sx = +1
                const int ny = sy * sx, nz = sz * sx;
                const int d = (ny < 0 ? 1 : 0) | (nz < 0 ? 2 : 0);
                const auto& buckets = mBuckets[d];
                const size_t nb = buckets.size();
                for (size_t bi = 0; bi < nb; ++bi, ++step) {
                    const auto& bucket = buckets[sx > 0 ? bi : nb - 1 - bi];
                    const double m = tbb::parallel_reduce(
                        tbb::blocked_range<size_t>(0, bucket.size(), 4), 0.0,
                        [&](const tbb::blocked_range<size_t>& r, double acc) {
                            uint64_t done = 0;
                            for (size_t k = r.begin(); k != r.end(); ++k) {
                                const int32_t li = bucket[k];
                                if (!needsSweep(li)) continue;
                                acc = std::max(acc, sweepLeaf(li, sx, sy, sz, step));
                                ++done;
                            }
                            leafUpdates += done;
                            return acc;
                        },
                        [](double a, double b) { return std::max(a, b); });
                    roundMax = std::max(roundMax, m);
                    if ((bi & 15) == 0) {
                        progress_internal::check(mInterrupter,
                            std::min(99, int(100.0 * (round * 8 + o + double(bi) / nb) /
                                             (8.0 * std::max(3, round + 1)))));
                    }
                }
            }
            ++round;
            anyChangeAboveTol = roundMax > mTol;
            lastRoundMax = roundMax;
            if (!anyChangeAboveTol) {
                converged = true;
                break;
            }
        }
        stats.iterations = round;
        stats.maxChange = (lastRoundMax >= kBig * 0.5 ? std::numeric_limits<double>::infinity()
                                                       : lastRoundMax / mH);
        stats.converged = converged;
        stats.leafUpdates = leafUpdates;
    }

private:
    /// A leaf whose last sweep changed nothing (by more than the tolerance) satisfies
    /// φ <= Godunov(neighbours) at every voxel — a property of the values, not of the ordering —
    /// so it is a fixed point of every ordering until a face neighbour changes.
    bool needsSweep(int32_t li) const
    {
        if (!mHasWork[li]) return false;
        if (mSelfChanged[li]) return true;
        const int64_t since = mLastProcessed[li];
        for (int k = 0; k < 6; ++k) {
            const int32_t n = mNb[li * 6 + k];
            if (n >= 0 && mLastChange[n] > since) return true;
        }
        return false;
    }

    /// Gauss–Seidel sweep of one leaf in ordering (sx, sy, sz) on a padded 10^3 copy; returns the
    /// largest change (world units; kBig when a voxel was reached for the first time).
    double sweepLeaf(int32_t li, int sx, int sy, int sz, int64_t step)
    {
        LeafT& leaf = *mLeaves[li];
        float* v = leaf.buffer().data();
        float P[10 * 10 * 10];
        std::fill(P, P + 1000, kBig); // edges and corners of the pad are never read
        auto pid = [](int x, int y, int z) { return (x + 1) * 100 + (y + 1) * 10 + (z + 1); };
        for (int x = 0; x < 8; ++x)
            for (int y = 0; y < 8; ++y)
                for (int z = 0; z < 8; ++z) P[pid(x, y, z)] = v[(x << 6) | (y << 3) | z];
        // halo: face neighbours (missing leaves: "not in the domain", signed like the inside)
        static const int kLeafStride[3] = {64, 8, 1}, kPadStride[3] = {100, 10, 1};
        for (int k = 0; k < 3; ++k) {
            const int ka = (k + 1) % 3, kb = (k + 2) % 3;
            for (int s = 0; s < 2; ++s) {
                const int32_t n = mNb[li * 6 + k * 2 + s];
                const float* nv = n >= 0 ? mLeaves[n]->buffer().data() : nullptr;
                const int innerOff = (s ? 7 : 0) * kLeafStride[k];
                const int outerOff = (s ? 0 : 7) * kLeafStride[k];
                const int padOff = (s ? 9 : 0) * kPadStride[k];
                for (int i = 0; i < 8; ++i) {
                    for (int j = 0; j < 8; ++j) {
                        const int base = i * kLeafStride[ka] + j * kLeafStride[kb];
                        const int pad = (i + 1) * kPadStride[ka] + (j + 1) * kPadStride[kb] + padOff;
                        P[pad] = nv ? nv[base + outerOff] : std::copysign(kBig, v[base + innerOff]);
                    }
                }
            }
        }
        const MaskT& upd = mUpdatable[li];
        const float h = mH;
        double maxChange = 0.0;
        bool changedAboveTol = false;
        // Fast path (nearly every leaf): all updatable voxels on one side of the surface; work on
        // magnitudes relative to that side (the same numbers the general path computes).
        float side = 0.0f;
        bool uniform = true;
        for (auto it = upd.beginOn(); it; ++it) {
            const float s = v[it.pos()] < 0 ? -1.0f : 1.0f;
            if (side == 0.0f) side = s;
            else if (s != side) { uniform = false; break; }
        }
        auto mag = [](float w, float sgn) {
            float r = w * sgn;
            if (r < 0) r = (r > -kBig * 0.5f) ? 0.0f : kBig; // across the surface
            return r;
        };
        auto record = [&](float m, float un) {
            const double ch = m >= kBig * 0.5f ? double(kBig) : double(m - un);
            maxChange = std::max(maxChange, ch);
            if (ch > mTol) changedAboveTol = true;
        };
        if (uniform) {
            for (int i = 0; i < 1000; ++i) P[i] = mag(P[i], side);
        }
        for (int xi = 0; xi < 8; ++xi) {
            const int x = sx > 0 ? xi : 7 - xi;
            for (int yi = 0; yi < 8; ++yi) {
                const int y = sy > 0 ? yi : 7 - yi;
                for (int zi = 0; zi < 8; ++zi) {
                    const int z = sz > 0 ? zi : 7 - zi;
                    if (!upd.isOn((x << 6) | (y << 3) | z)) continue;
                    const int p = pid(x, y, z);
                    if (uniform) {
                        const float m = P[p];
                        const float ax = std::min(P[p - 100], P[p + 100]);
                        const float ay = std::min(P[p - 10], P[p + 10]);
                        const float az = std::min(P[p - 1], P[p + 1]);
                        if (std::min(ax, std::min(ay, az)) >= kBig * 0.5f) continue;
                        const float un = godunov(ax, ay, az, h);
                        if (un < m) {
                            P[p] = un;
                            record(m, un);
                        }
                        continue;
                    }
                    const float u = P[p];
                    const float sgn = u < 0 ? -1.0f : 1.0f;
                    const float m = u * sgn;
                    const float ax = std::min(mag(P[p - 100], sgn), mag(P[p + 100], sgn));
                    const float ay = std::min(mag(P[p - 10], sgn), mag(P[p + 10], sgn));
                    const float az = std::min(mag(P[p - 1], sgn), mag(P[p + 1], sgn));
                    if (std::min(ax, std::min(ay, az)) >= kBig * 0.5f) continue;
                    const float un = godunov(ax, ay, az, h);
                    if (un < m) {
                        P[p] = un * sgn;
                        record(m, un);
                    }
                }
            }
        }
        if (maxChange > 0) {
            const float back = uniform ? side : 1.0f;
            for (auto it = upd.beginOn(); it; ++it) {
                const openvdb::Index j = it.pos();
                v[j] = back * P[pid(int(j >> 6), int((j >> 3) & 7), int(j & 7))];
            }
        }
        if (changedAboveTol) mLastChange[li] = step;
        mLastProcessed[li] = step;
        mSelfChanged[li] = changedAboveTol ? 1 : 0;
        return maxChange;
    }

    std::vector<LeafT*> mLeaves;
    std::vector<int32_t> mNb;
    std::vector<MaskT> mUpdatable;
    std::vector<char> mHasWork;
    std::vector<int64_t> mLastChange;    ///< last bucket step that changed the leaf (> tol)
    std::vector<int64_t> mLastProcessed; ///< last bucket step that swept the leaf
    std::vector<char> mSelfChanged;      ///< the leaf's last sweep changed it (> tol)
    std::vector<std::vector<int32_t>> mBuckets[4];
    float mH;
    float mTol;
    openvdb::util::NullInterrupter* mInterrupter;
};

} // namespace

openvdb::FloatGrid::Ptr expandLevelSet(const openvdb::FloatGrid& input,
                                       const ExpandLevelSetOptions& opt,
                                       ExpandLevelSetStats* statsOut)
{
    using fast_sweeping_internal::dilationPattern;
    ExpandLevelSetStats stats;
    auto t0 = Clock::now();

    // ---- validate
    if (input.tree().activeVoxelCount() == 0) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' has no active voxels (an empty level set)");
    }
    if (!input.hasUniformVoxels()) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' has non-uniform voxels; a level set needs cubic voxels");
    }
    if (input.getGridClass() != openvdb::GRID_LEVEL_SET &&
        input.getGridClass() != openvdb::GRID_UNKNOWN) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' is not a level set (class " +
                                   openvdb::GridBase::gridClassToString(input.getGridClass()) + ")");
    }
    const double h = input.voxelSize()[0];
    const float inBackground = input.background();
    if (!(inBackground > 0) || !std::isfinite(inBackground)) {
        throw InvalidArgumentError("expandLevelSet: the input grid '" + input.getName() +
                                   "' has background " + num(inBackground) +
                                   "; a level set needs a positive background");
    }
    const double toVoxels = opt.units == WidthUnits::World ? 1.0 / h : 1.0;
    checkWidth(opt.exteriorWidth, "exteriorWidth");
    if (!opt.fillInterior) checkWidth(opt.interiorWidth, "interiorWidth");
    checkWidth(opt.coverageMargin, "coverageMargin", true);
    checkWidth(opt.coverageMarginPerVoxel, "coverageMarginPerVoxel", true);
    checkWidth(opt.inputExteriorWidth, "inputExteriorWidth", true);
    checkWidth(opt.inputInteriorWidth, "inputInteriorWidth", true);
    if (opt.domain == ExpansionDomain::BoundingBox) checkWidth(opt.boundingBoxMargin, "boundingBoxMargin", true);
    if (!(opt.tolerance > 0) || !std::isfinite(opt.tolerance)) {
        throw InvalidArgumentError("expandLevelSet: tolerance must be finite and > 0, got " +
                                   num(opt.tolerance));
    }
    if (opt.maxIterations < 1) {
        throw InvalidArgumentError("expandLevelSet: maxIterations must be >= 1, got " +
                                   std::to_string(opt.maxIterations));
    }
    const double wExt = opt.exteriorWidth * toVoxels;
    const double wInt = opt.fillInterior ? 0.0 : opt.interiorWidth * toVoxels;
    const double bboxMargin = opt.boundingBoxMargin * toVoxels;
    constexpr double kMaxWidth = 100000.0;
    for (double w : {wExt, wInt, bboxMargin}) {
        if (w > kMaxWidth) {
            throw ResourceLimitError("expandLevelSet: a width of " + num(w) +
                                     " voxels is beyond what fits in memory (limit " +
                                     num(kMaxWidth) + " voxels)");
        }
    }
    double w0Ext = opt.inputExteriorWidth > 0 ? opt.inputExteriorWidth
                   : readBandMeta(input, "levelforge:exterior_band_voxels", inBackground / h);
    double w0Int = opt.inputInteriorWidth > 0 ? opt.inputInteriorWidth
                   : readBandMeta(input, "levelforge:interior_band_voxels", inBackground / h);
    w0Ext = std::max(0.0, w0Ext);
    w0Int = std::max(0.0, w0Int);
    stats.voxelSize = h;
    stats.inputExteriorWidth = w0Ext;
    stats.inputInteriorWidth = w0Int;
    stats.frozenVoxels = input.tree().activeVoxelCount();

    // ---- resource estimate before any allocation: a shell of the input's surface area
    const double area = double(stats.frozenVoxels) / std::max(1.0, w0Ext + w0Int);
    const bool vectorMethod = opt.method == ExpansionMethod::Vector;
    const double perVoxel = vectorMethod ? 0.0 : opt.coverageMarginPerVoxel;
    const double keepExt = wExt + opt.coverageMargin + perVoxel * std::max(0.0, wExt - w0Ext);
    const double keepInt = wInt + opt.coverageMargin + perVoxel * std::max(0.0, wInt - w0Int);
    stats.method = opt.method;
    const openvdb::CoordBBox inBox = input.evalActiveVoxelBoundingBox();
    double lowerEstimate = 0;
    if (opt.domain == ExpansionDomain::BoundingBox) {
        const double e = 2 * std::ceil(bboxMargin);
        lowerEstimate = (inBox.dim().x() + e) * (inBox.dim().y() + e) * (inBox.dim().z() + e);
    } else {
        lowerEstimate = area * (std::max(0.0, keepExt - w0Ext) + (opt.fillInterior ? 0.0 : std::max(0.0, keepInt - w0Int)));
        lowerEstimate += double(stats.frozenVoxels);
        // the ball of radius wExt around a surface point, less the object, is in the band
        const double r = wExt - 1.0;
        if (r > 0) {
            lowerEstimate = std::max(lowerEstimate,
                                     4.0 / 3.0 * M_PI * r * r * r - double(inBox.volume()));
        }
    }
    if (opt.maxVoxels && lowerEstimate > double(opt.maxVoxels)) {
        throw ResourceLimitError("expandLevelSet: the expanded band would hold about " +
                                 num(lowerEstimate) + " voxels, more than the limit of " +
                                 std::to_string(opt.maxVoxels) + " (reduce the widths)");
    }
    if (opt.interrupter) opt.interrupter->start("fast sweeping");
    progress_internal::check(opt.interrupter, 0);

    // ---- topology: flood-filled copy of the input, dilated Euclidean-completely
    FloatTree::Ptr tree(new FloatTree(input.tree()));
    openvdb::tools::signedFloodFill(*tree);
    openvdb::MaskTree::Ptr interior;
    if (opt.fillInterior) {
        openvdb::FloatGrid::Ptr tmp = openvdb::FloatGrid::create(tree);
        auto boolMask = openvdb::tools::sdfInteriorMask(*tmp, 0.0f);
        interior.reset(new openvdb::MaskTree(boolMask->tree(), false, openvdb::TopologyCopy()));
    }
    openvdb::MaskTree band(input.tree(), false, openvdb::TopologyCopy());
    band.voxelizeActiveTiles();
    if (opt.domain == ExpansionDomain::BoundingBox) {
        openvdb::CoordBBox box = inBox;
        box.expand(int(std::ceil(bboxMargin)));
        openvdb::MaskTree boxMask(false);
        boxMask.sparseFill(box, true, true);
        tree->topologyUnion(boxMask);
    } else {
        // (the candidates only need to hold every voxel with d < w; the margin is trimmed from)
        const double rExt = std::max(0.0, wExt - w0Ext + std::sqrt(3.0));
        const double rInt = opt.fillInterior ? 0.0 : std::max(0.0, wInt - w0Int + std::sqrt(3.0));
        const double rSmall = std::min(rExt, rInt), rLarge = std::max(rExt, rInt);
        auto dilated = [&](double r) {
            openvdb::MaskTree::Ptr m(new openvdb::MaskTree(band));
            int a = 0, b = 0;
            dilationPattern(r, a, b);
            if (r == rLarge) { stats.dilationCubeSteps = a; stats.dilationFaceSteps = b; }
            if (a > 0) openvdb::tools::dilateActiveValues(*m, a, openvdb::tools::NN_FACE_EDGE_VERTEX,
                                                         openvdb::tools::IGNORE_TILES);
            progress_internal::check(opt.interrupter, 0);
            if (b > 0) openvdb::tools::dilateActiveValues(*m, b, openvdb::tools::NN_FACE,
                                                         openvdb::tools::IGNORE_TILES);
            progress_internal::check(opt.interrupter, 0);
            return m;
        };
        openvdb::MaskTree::Ptr large = dilated(rLarge);
        if (opt.maxVoxels && large->activeVoxelCount() > opt.maxVoxels) {
            throw ResourceLimitError("expandLevelSet: the dilated band holds " +
                                     std::to_string(large->activeVoxelCount()) +
                                     " voxels, more than the limit of " +
                                     std::to_string(opt.maxVoxels) + " (reduce the widths)");
        }
        tree->topologyUnion(*large);
        if (rSmall < rLarge) {
            // Keep the larger dilation only on the side that asked for it.
            openvdb::MaskTree::Ptr small = dilated(rSmall);
            const bool dropNegative = rInt < rExt; // interior is the small side
            openvdb::tree::LeafManager<FloatTree> lm(*tree);
            lm.foreach([&](LeafT& leaf, size_t) {
                const openvdb::MaskTree::LeafNodeType* sl = small->probeConstLeaf(leaf.origin());
                const openvdb::MaskTree::LeafNodeType* bl = band.probeConstLeaf(leaf.origin());
                for (auto it = leaf.beginValueOn(); it; ++it) {
                    const openvdb::Index j = it.pos();
                    if ((sl && sl->isValueOn(j)) || (bl && bl->isValueOn(j))) continue;
                    const bool neg = *it < 0;
                    if (neg == dropNegative) leaf.setValueOff(j);
                }
            });
        }
    }
    if (interior) tree->topologyUnion(*interior);
    tree->voxelizeActiveTiles();
    stats.secondsTopology = seconds(t0);
    if (opt.maxVoxels && tree->activeVoxelCount() > opt.maxVoxels) {
        throw ResourceLimitError("expandLevelSet: the expanded grid holds " +
                                 std::to_string(tree->activeVoxelCount()) +
                                 " voxels, more than the limit of " + std::to_string(opt.maxVoxels));
    }
    progress_internal::check(opt.interrupter, 0);

    // ---- sweeps
    auto t1 = Clock::now();
    if (vectorMethod) {
        vector_expansion_internal::PropagationStats ps;
        stats.candidateVoxels = tree->activeVoxelCount();
        vector_expansion_internal::ShellVectors shell;
        shell.points = opt.closestPoints;
        if (opt.closestPoints && opt.closestTriangles && opt.mesh) {
            requireUsableMesh(*opt.mesh); // indices in range, finite points, not empty
            shell.triangles = opt.closestTriangles;
            shell.mesh = opt.mesh;
        }
        vector_expansion_internal::propagateClosestVectors(*tree, input.tree(), shell, input.transform(),
                                                           kBig, opt.interrupter, &ps);
        stats.refinedVoxels = ps.refinedVoxels;
        stats.walkSteps = ps.walkSteps;
        stats.refineEvaluations = ps.refineEvaluations;
        stats.refineRounds = ps.refineRounds;
        stats.secondsVectorSetup = ps.secondsSetup;
        stats.secondsVectorPasses = ps.secondsPasses;
        stats.secondsVectorFinish = ps.secondsFinish;
        stats.iterations = 1;
        stats.converged = true;
        stats.estimatedVectors = ps.estimatedVectors;
        stats.unreachedVoxels = ps.unreachedVoxels;
    } else {
        Sweeper sweeper(*tree, input.tree(), float(h), float(opt.tolerance * h), opt.interrupter);
        stats.candidateVoxels = sweeper.candidateVoxels();
        sweeper.run(opt.maxIterations, stats);
    }
    stats.secondsSweep = seconds(t1);

    // ---- finish: keep |φ| < width + margin, background, prune
    auto t2 = Clock::now();
    const bool box = opt.domain == ExpansionDomain::BoundingBox;
    const float keepExtW = float(keepExt * h), keepIntW = float(keepInt * h);
    float background = 0;
    {
        openvdb::tree::LeafManager<FloatTree> lm(*tree);
        // trim, and find the largest kept magnitude (for the box / fill modes)
        std::vector<float> leafMax(lm.leafCount(), 0.0f);
        lm.foreach([&](LeafT& leaf, size_t idx) {
            float mx = 0;
            for (auto it = leaf.beginValueOn(); it; ++it) {
                const float v = *it;
                const float a = std::abs(v);
                bool keep = a < kBig * 0.5f;
                if (keep && !box) keep = v < 0 ? (opt.fillInterior || a < keepIntW) : a < keepExtW;
                if (keep) mx = std::max(mx, a);
                else leaf.setValueOff(it.pos());
            }
            leafMax[idx] = mx;
        });
        float mx = 0;
        for (float m : leafMax) mx = std::max(mx, m);
        background = box || opt.fillInterior ? std::max({mx, keepExtW, float(h)})
                                             : std::max(keepExtW, keepIntW);
        if (opt.fillInterior && !box) background = std::max(background, keepExtW);
        // values just above the kept width must not exceed the background
        background = std::nextafter(background, std::numeric_limits<float>::max());
    }
    openvdb::tools::changeLevelSetBackground(*tree, background);
    openvdb::tools::pruneLevelSet(*tree);
    openvdb::FloatGrid::Ptr out = openvdb::FloatGrid::create(tree);
    out->setTransform(input.transform().copy());
    for (auto it = input.beginMeta(); it != input.endMeta(); ++it) {
        out->insertMeta(it->first, *it->second);
    }
    // The band is now complete (every voxel with |d| < width is active) to the target widths.
    const double bgVoxels = background / h;
    if (input.getMetadata<openvdb::FloatMetadata>("levelforge:exterior_band_voxels")) {
        out->insertMeta("levelforge:exterior_band_voxels",
                        openvdb::FloatMetadata(float(box ? bgVoxels : wExt)));
    }
    if (input.getMetadata<openvdb::FloatMetadata>("levelforge:interior_band_voxels")) {
        out->insertMeta("levelforge:interior_band_voxels",
                        openvdb::FloatMetadata(float(box || opt.fillInterior ? bgVoxels : wInt)));
    }
    out->setName(input.getName());
    out->setGridClass(openvdb::GRID_LEVEL_SET);
    stats.activeVoxels = out->activeVoxelCount();
    stats.secondsFinish = seconds(t2);
    if (opt.interrupter) { opt.interrupter->wasInterrupted(100); opt.interrupter->end(); }
    if (statsOut) *statsOut = stats;
    return out;
}

} // namespace levelforge
