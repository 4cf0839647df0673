// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one lower envelope of parabolas of the library: the 1-D step of its separable
///        exact Euclidean distance transforms (Felzenszwalb & Huttenlocher, "Distance
///        Transforms of Sampled Functions", Theory of Computing 8, 2012).
///
/// The parabolas (t - x_i)² + f_i are added in increasing order of their apex x_i; the envelope
/// keeps, for each of its segments, the parabola lowest there and the breakpoint where that
/// segment starts, bracketed by two sentinels as in the paper (z[0] = -∞ before every
/// breakpoint, z[k+1] = +∞ after every query). Then it is evaluated at increasing abscissas.
///
/// The geometry and the arithmetic come from the caller, so each user keeps its own numbers:
///  - volume/ExactDistanceTransform.cc: sites at integer indices with a spacing weight,
///    breakpoints in double by the paper's formula, samples of +∞ left out;
///  - adf/AdfLatticeEdt.cc: sites at doubled integer coordinates, breakpoints as exact rationals
///    compared in 128-bit integers.
#pragma once

#include <cstddef>
#include <vector>

namespace levelforge::detail {

/// @brief Lower envelope of parabolas with values of type @p Value and breakpoints of type
///        @p Break (a number, or e.g. an exact rational).
template<typename Value, typename Break>
class LowerEnvelope
{
public:
    /// @param[in] lowest   a breakpoint before every breakpoint (the paper's -∞): notAfter(s,
    ///                     lowest) must be false for every s the breakpoint callback returns
    /// @param[in] highest  a breakpoint after every query (+∞): before(highest, t) must be false
    LowerEnvelope(Break lowest, Break highest) : mLowest(lowest), mHighest(highest) {}

    /// @brief Empties the envelope and makes room for @p n parabolas.
    void reset(size_t n)
    {
        mSite.resize(n);
        mValue.resize(n);
        mBreak.resize(n + 1);
        mK = -1;
    }

    /// @brief True until the first add() after reset().
    bool empty() const { return mK < 0; }

    /// @brief Adds the parabola of site @p site with value @p f; sites come in increasing
    ///        order of their apex.
    /// @param[in] site        the caller's index of the site (handed back to the callbacks)
    /// @param[in] f           its value (the parabola's height at its apex)
    /// @param[in] breakpoint  breakpoint(a, fa) -> Break: where the new parabola starts to lie
    ///                        below the parabola of envelope site a (value fa)
    /// @param[in] notAfter    notAfter(s, z) -> bool: s <= z
    template<typename BreakFn, typename NotAfterFn>
    void add(int site, Value f, BreakFn&& breakpoint, NotAfterFn&& notAfter)
    {
        int k = mK;
        if (k < 0) {
            mK = 0;
            mSite[0] = site;
            mValue[0] = f;
            mBreak[0] = mLowest;
            mBreak[1] = mHighest;
            return;
        }
        Break s = breakpoint(mSite[size_t(k)], mValue[size_t(k)]);
        while (notAfter(s, mBreak[size_t(k)])) {
            --k;
            s = breakpoint(mSite[size_t(k)], mValue[size_t(k)]);
        }
        ++k;
        mSite[size_t(k)] = site;
        mValue[size_t(k)] = f;
        mBreak[size_t(k)] = s;
        mBreak[size_t(k) + 1] = mHighest;
        mK = k;
    }

    /// @brief Evaluates the envelope at @p nq increasing abscissas (at least one add() first).
    /// @param[in] nq        number of queries
    /// @param[in] position  position(j): the abscissa t of query j
    /// @param[in] before    before(z, t) -> bool: breakpoint z lies before t (z < t)
    /// @param[in] emit      emit(j, t, site, value): the parabola (site, value) is lowest at t
    template<typename PositionFn, typename BeforeFn, typename EmitFn>
    void evaluate(int nq, PositionFn&& position, BeforeFn&& before, EmitFn&& emit) const
    {
        int c = 0;
        for (int j = 0; j < nq; ++j) {
            const auto t = position(j);
            while (before(mBreak[size_t(c) + 1], t)) ++c;
            emit(j, t, mSite[size_t(c)], mValue[size_t(c)]);
        }
    }

private:
    Break mLowest, mHighest;
    std::vector<int> mSite;
    std::vector<Value> mValue;
    std::vector<Break> mBreak;
    int mK = -1;
};

} // namespace levelforge::detail
