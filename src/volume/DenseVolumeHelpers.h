// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to the dense volume transforms: a new volume with the geometry of another,
///        and the equal-dims check of the functions that combine two volumes.
#pragma once

#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/Exceptions.h>

#include <sstream>

namespace levelforge::volume_internal {

/// A volume of value type Out with the dims, spacing and origin of @p v, every value @p fill
/// (value-initialised by default).
template<typename Out, typename In>
DenseVolume<Out> like(const DenseVolume<In>& v, Out fill = Out())
{
    DenseVolume<Out> o;
    o.dims = v.dims;
    o.spacing = v.spacing;
    o.origin = v.origin;
    o.data.assign(v.data.size(), fill);
    return o;
}

/// Throws InvalidArgumentError, naming `what`, unless @p a and @p b have equal dims.
template<typename A, typename B>
void requireSameDims(const DenseVolume<A>& a, const DenseVolume<B>& b, const char* what)
{
    if (a.dims != b.dims) {
        std::ostringstream ss;
        ss << what << ": volume dims differ (" << a.dims.x() << " x " << a.dims.y() << " x " << a.dims.z()
           << " vs " << b.dims.x() << " x " << b.dims.y() << " x " << b.dims.z() << ")";
        throw InvalidArgumentError(ss.str());
    }
}

} // namespace levelforge::volume_internal
