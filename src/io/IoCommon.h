// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Helpers shared by the mesh and the volume readers and writers: host byte order,
///        byte swapping, lower-cased file names and extensions.
#pragma once

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>

namespace levelforge::io_internal {

/// True on a big-endian host (file formats state their own byte order).
constexpr bool kHostBigEndian = (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__);

/// @p v with its bytes in reverse order.
template<typename T>
T byteSwapped(T v)
{
    static_assert(std::is_trivially_copyable<T>::value, "");
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    std::reverse(b, b + sizeof(T));
    std::memcpy(&v, b, sizeof(T));
    return v;
}

/// @p s with ASCII letters in lower case.
inline std::string asciiLower(std::string s)
{
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

/// File name of @p path (no directory), lower case: "Brain.NII.GZ" -> "brain.nii.gz".
inline std::string lowerFileName(const std::string& path)
{
    return asciiLower(std::filesystem::path(path).filename().string());
}

/// Last extension of @p path with its dot, lower case: "a/Box.OBJ" -> ".obj"; "" when none.
inline std::string lowerExtension(const std::string& path)
{
    return asciiLower(std::filesystem::path(path).extension().string());
}

/// True when @p s ends with @p suffix.
inline bool endsWith(const std::string& s, const std::string& suffix)
{
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

} // namespace levelforge::io_internal
