// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Typed exceptions.
///
/// Library code never exits: every failure is reported by throwing one of these types, each
/// with a message a user can act on (which file, which element, which value). The CLI turns
/// them into one line on stderr and a non-zero exit code.
#pragma once

#include <stdexcept>
#include <string>

namespace levelforge {

/// @brief Base of every exception levelforge throws.
class Error : public std::runtime_error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message: what failed, and where (file, element, value)
    explicit Error(const std::string& msg) : std::runtime_error(msg) {}
};

/// @brief A parameter is out of its valid range (voxel size <= 0, NaN band width, ...).
class InvalidArgumentError : public Error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message: what failed, and where (file, element, value)
    explicit InvalidArgumentError(const std::string& msg) : Error(msg) {}
};

/// @brief A mesh is unusable: unreadable file, no triangles, NaN/Inf coordinates, bad index.
///
/// The message names the file and the element (vertex or face number, 0-based unless said).
class InvalidMeshError : public Error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message: what failed, and where (file, element, value)
    explicit InvalidMeshError(const std::string& msg) : Error(msg) {}
};

/// @brief Reading or writing a file failed (missing, permission, disk full, not a .vdb, ...).
class IoError : public Error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message: what failed, and where (file, element, value)
    explicit IoError(const std::string& msg) : Error(msg) {}
};

/// @brief The requested grid would not fit in memory (or exceeds a configured voxel limit).
class ResourceLimitError : public Error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message: what failed, and where (file, element, value)
    explicit ResourceLimitError(const std::string& msg) : Error(msg) {}
};

/// @brief The caller's interrupter asked to stop; partial results were discarded.
class InterruptedError : public Error
{
public:
    /// @brief Constructs the exception.
    /// @param[in] msg  the message; "interrupted" by default, or which stage was interrupted
    explicit InterruptedError(const std::string& msg = "interrupted") : Error(msg) {}
};

} // namespace levelforge
