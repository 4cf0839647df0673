// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The atomic file writer (see AtomicFile.h).
#include "detail/AtomicFile.h"

#include <levelforge/core/Exceptions.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

namespace fs = std::filesystem;

namespace levelforge::detail {

namespace {

/// Flushes a file's (or a directory's) data to disk; returns errno or 0.
int syncFile(const std::string& file, bool directory = false)
{
    const int fd = ::open(file.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
    if (fd < 0) return errno;
    int err = 0;
    if (::fsync(fd) != 0) err = errno;
    ::close(fd);
    return err;
}

} // namespace

fs::path parentDirectory(const std::string& path)
{
    fs::path parent = fs::path(path).parent_path();
    return parent.empty() ? fs::path(".") : parent;
}

AtomicFile::AtomicFile(const std::string& path, std::string errorPrefix)
    : mPath(path), mPrefix(std::move(errorPrefix))
{
    const fs::path dir = parentDirectory(path);
    std::random_device rd;
    std::mt19937_64 rng((uint64_t(rd()) << 32) ^ uint64_t(rd()) ^
                        uint64_t(std::chrono::steady_clock::now().time_since_epoch().count()));
    const std::string base = fs::path(path).filename().string();
    for (int attempt = 0; attempt < 100; ++attempt) {
        char suffix[48];
        std::snprintf(suffix, sizeof(suffix), ".%ld-%08llx.tmp", long(::getpid()),
                      static_cast<unsigned long long>(rng() & 0xffffffffull));
        const std::string tmp = (dir / ("." + base + suffix)).string();
        const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            mTemp = tmp;
            mFd = fd;
            return;
        }
        if (errno != EEXIST) {
            throw IoError(mPrefix + ": cannot create a file in '" + dir.string() + "': " +
                          std::strerror(errno));
        }
    }
    throw IoError(mPrefix + ": no free temporary file name in '" + dir.string() + "'");
}

AtomicFile::~AtomicFile()
{
    closeDescriptor();
    if (!mDone) {
        std::error_code ec;
        fs::remove(mTemp, ec);
    }
}

int AtomicFile::releaseDescriptor()
{
    const int fd = mFd;
    mFd = -1;
    return fd;
}

void AtomicFile::closeDescriptor()
{
    if (mFd >= 0) ::close(mFd);
    mFd = -1;
}

void AtomicFile::fail(const std::string& cause)
{
    closeDescriptor();
    if (!mDone) {
        std::error_code ec;
        fs::remove(mTemp, ec);
        mDone = true;
    }
    throw IoError(mPrefix + ": " + cause);
}

void AtomicFile::sync()
{
    if (const int err = syncFile(mTemp)) fail(std::strerror(err));
}

void AtomicFile::commit()
{
    closeDescriptor();
    if (std::rename(mTemp.c_str(), mPath.c_str()) != 0) fail(std::strerror(errno));
    mDone = true;
    syncFile(parentDirectory(mPath).string(), /*directory=*/true); // best effort
}

} // namespace levelforge::detail
