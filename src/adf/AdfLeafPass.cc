// SPDX-License-Identifier: Apache-2.0
// The per-leaf sample pass of the ADF mesh builder (type-1 and type-2 samples, Yin et al. 2011
// §5.2, §6), compiled twice: for the baseline and for AVX2, chosen at run time.
#include "adf/AdfLeafPass.h"
#include "adf/AdfLeafSearch.h"
#include "adf/AdfMeshProvider.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>

namespace levelforge {
namespace adf_internal {

namespace {
std::atomic<bool> gAvx2LeafPass{true}; // testing hook (setAvx2LeafPassEnabled)
} // namespace

LF_HOT void MeshProvider::leafSamplesImpl(FloatLeaf& leaf, const uint8_t* isFree, float* out)
{
    MeshScratch& s = mScratch.local();
    const Coord o = leaf.origin();
    gather(o, s, true);
    std::unique_ptr<FloatLeaf> t1; // the type-1 samples of this leaf, if any
    for (int off = 0; off < 512; ++off) {
        if (!isFree[off]) continue;
        const int x = off >> 6, y = (off >> 3) & 7, z = off & 7;
        const Coord local(x + kGather, y + kGather, z + kGather);
        bool type1 = false;
        for (int d = 0; d < 8 && !type1; ++d) {
            const Coord c = local - Coord((d >> 2) & 1, (d >> 1) & 1, d & 1);
            type1 = s.cellSlot[size_t((c.x() * kRegion + c.y()) * kRegion + c.z())] >= 0;
        }
        const Vec3d q(o.x() + x, o.y() + y, o.z() + z);
        const Nearest nb = nearest(q, local, mLattice, s);
        if (nb.tri == kNone) {
            // nothing within the region (refinement leaves far from the surface): type-3 rule.
            // The flood-fill tree is not there yet: signs are fixed in afterLeaves().
            out[off] = float(std::sqrt(mBvh.nearest2(q, s.hint)) * mH);
            mDeferredSign.local().push_back(&out[off]);
            ++s.type3;
            continue;
        }
        double cert = 0;
        const double v = certified(nb, q, s, cert);
        out[off] = float(v);
        if (type1) {
            ++s.type1;
            if (!t1) t1 = std::make_unique<FloatLeaf>(o, 0.0f, false);
            t1->setValueOn(openvdb::Index(off), float(v));
        } else {
            ++s.type2;
            s.type2MaxBound = std::max(s.type2MaxBound, cert);
        }
    }
    if (t1) mType1Leaves.local().push_back(std::move(t1));
}


void MeshProvider::leafSamplesBase(FloatLeaf& leaf, const uint8_t* isFree, float* out) { leafSamplesImpl(leaf, isFree, out); }

#if defined(LF_ADF_AVX2)
__attribute__((target("avx2"))) void MeshProvider::leafSamplesAvx2(FloatLeaf& leaf, const uint8_t* isFree, float* out)
{
    leafSamplesImpl(leaf, isFree, out);
}
#endif

void MeshProvider::leafSamples(size_t, FloatLeaf& leaf, const uint8_t* isFree, float* out)
{
#if defined(LF_ADF_AVX2)
    if (avx2LeafPassAvailable() && gAvx2LeafPass.load(std::memory_order_relaxed)) return leafSamplesAvx2(leaf, isFree, out);
#endif
    leafSamplesBase(leaf, isFree, out);
}

bool avx2LeafPassAvailable()
{
#if defined(LF_ADF_AVX2)
    static const bool has = __builtin_cpu_supports("avx2");
    return has;
#else
    return false;
#endif
}

void setAvx2LeafPassEnabled(bool enabled) { gAvx2LeafPass.store(enabled, std::memory_order_relaxed); }

} // namespace adf_internal
} // namespace levelforge
