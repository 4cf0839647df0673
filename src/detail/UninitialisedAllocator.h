// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief An allocator whose vectors leave trivially constructible elements uninitialised, for
///        large buffers written in parallel right after they are allocated.
#pragma once

#include <memory>
#include <new>
#include <utility>

namespace levelforge::detail {

/// An allocator that leaves trivially constructible elements uninitialised where a vector would
/// value-initialise them: a buffer written in parallel right after it is allocated then has its
/// pages first touched there, on every thread, instead of zeroed on one (the hierarchy's
/// clusters, 196 MB for the 2.7 M marching-cubes triangles of a 181 × 217 × 181 volume; the
/// expansion's triangle corners, as many again).
template <class T>
struct UninitialisedAllocator : std::allocator<T>
{
    template <class U>
    struct rebind { using other = UninitialisedAllocator<U>; };
    UninitialisedAllocator() = default;
    template <class U>
    UninitialisedAllocator(const UninitialisedAllocator<U>&) noexcept {}
    template <class U>
    void construct(U* p) noexcept { ::new (static_cast<void*>(p)) U; }
    template <class U, class... A>
    void construct(U* p, A&&... a) { ::new (static_cast<void*>(p)) U(std::forward<A>(a)...); }
};

} // namespace levelforge::detail
