// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief PageBuffer: an uninitialised, cache-line (or huge-page) aligned buffer for large
///        intermediates.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace levelforge::detail {

/// An uninitialised buffer for an intermediate, cache-line aligned (so lanes' column ranges of a
/// row never share a line when rows are multiples of 64 bytes). From 4 MB on it is 2 MB-aligned
/// and advised for transparent huge pages where Linux offers them, so that its first touch
/// faults in 2 MB pages instead of 4 kB ones. Throws std::bad_alloc.
template<class T>
class PageBuffer
{
public:
    explicit PageBuffer(size_t n)
    {
        constexpr size_t kHuge = size_t(2) << 20;
        const size_t bytes = std::max<size_t>(1, n * sizeof(T));
        const size_t align = bytes >= 2 * kHuge ? kHuge : 64;
        const size_t rounded = (bytes + align - 1) / align * align;
        mData = static_cast<T*>(std::aligned_alloc(align, rounded));
        if (!mData) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (align == kHuge) madvise(mData, rounded, MADV_HUGEPAGE); // advice: failing changes only speed
#endif
    }
    ~PageBuffer() { std::free(mData); }
    PageBuffer(const PageBuffer&) = delete;
    PageBuffer& operator=(const PageBuffer&) = delete;
    T* get() const { return mData; }

private:
    T* mData = nullptr;
};

} // namespace levelforge::detail
