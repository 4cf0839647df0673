// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The atomic file writer (see AtomicFile.h).
#include "detail/AtomicFile.h"

#include <levelforge/core/Exceptions.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <system_error>

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/types.h>
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

// ------------------------------------------------------------ the table of live temporaries
//
// Each slot goes Free -> Filling (its owner copies the path) -> Live -> Free (the owner, on
// commit or removal). A signal handler takes a Live slot for good (Live -> Taken) before it
// reads the path, so the owner can no longer free and refill the slot while the handler
// reads: the owner's Live -> Free exchange fails and the slot stays Taken (the process is
// about to end). Only lock-free atomics and unlink() are used on the handler's side.

enum SlotState : int { kFree = 0, kFilling = 1, kLive = 2, kTaken = 3 };

struct LiveSlot
{
    std::atomic<int> state{kFree};
    char path[kLivePathMax];
};

static_assert(std::atomic<int>::is_always_lock_free, "the live table needs lock-free atomics");
static_assert(std::atomic<bool>::is_always_lock_free, "the abort flag needs a lock-free atomic");

LiveSlot gLiveSlots[kLiveSlots]; // zero-initialised: every slot Free
std::atomic<bool> gWritesAborted{false};

/// Registers @p path as a live temporary file; returns its slot, or -1 (no free slot, path too
/// long: the file is then simply not covered by removeLiveTemporaryFiles()).
int registerLive(const std::string& path) noexcept
{
    if (path.empty() || path.size() >= size_t(kLivePathMax)) return -1;
    for (int i = 0; i < kLiveSlots; ++i) {
        int expected = kFree;
        if (gLiveSlots[i].state.compare_exchange_strong(expected, kFilling)) {
            std::memcpy(gLiveSlots[i].path, path.c_str(), path.size() + 1);
            gLiveSlots[i].state.store(kLive);
            return i;
        }
    }
    return -1;
}

/// Frees @p slot unless a signal handler has taken it.
void unregisterLive(int slot) noexcept
{
    if (slot < 0 || slot >= kLiveSlots) return;
    int expected = kLive;
    gLiveSlots[slot].state.compare_exchange_strong(expected, kFree);
}

/// Absolute form of @p path (the handler must not depend on the working directory), or
/// @p path itself if that fails.
std::string absolutePath(const std::string& path) noexcept
{
    try {
        std::error_code ec;
        const fs::path abs = fs::absolute(path, ec);
        return ec ? path : abs.string();
    } catch (...) {
        return path;
    }
}

/// True if @p rdev is /dev/null's device number.
bool isNullRdev(dev_t rdev)
{
    struct stat null {};
    return ::stat("/dev/null", &null) == 0 && S_ISCHR(null.st_mode) && null.st_rdev == rdev;
}

/// "a directory", "a FIFO (named pipe)", ... for the refusal message.
const char* kindOf(mode_t mode)
{
    if (S_ISDIR(mode)) return "a directory";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
    if (S_ISSOCK(mode)) return "a socket";
    return "a special file";
}

bool isLowerHex(char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); }

} // namespace

fs::path parentDirectory(const std::string& path)
{
    fs::path parent = fs::path(path).parent_path();
    return parent.empty() ? fs::path(".") : parent;
}

// ---------------------------------------------------------------------------- output rule

bool isNullDevice(const std::string& path)
{
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 && S_ISCHR(st.st_mode) && isNullRdev(st.st_rdev);
}

OutputTarget resolveOutputTarget(const std::string& path, const std::string& errorPrefix)
{
    if (path.empty()) throw IoError(errorPrefix + ": empty output path");
    OutputTarget target;
    target.path = path;
    fs::path current(path);
    for (int hops = 0;; ++hops) {
        struct stat st {};
        if (::lstat(current.c_str(), &st) != 0) {
            const int err = errno;
            if (err != ENOENT && err != ENOTDIR) {
                throw IoError(errorPrefix + ": " + std::strerror(err));
            }
            // A new file (possibly the target of a dangling link). A missing or unusable
            // directory is reported when the temporary file is created.
            target.resolved = current.string();
            const std::string name = current.filename().string();
            if (name.empty() || name == "." || name == "..") {
                throw IoError(errorPrefix + ": '" + path + "' names a directory, not a file");
            }
            return target;
        }
        if (S_ISLNK(st.st_mode)) {
            if (hops >= 40) throw IoError(errorPrefix + ": too many levels of symbolic links");
            std::error_code ec;
            const fs::path next = fs::read_symlink(current, ec);
            if (ec) throw IoError(errorPrefix + ": " + ec.message());
            // A relative link is relative to the directory that holds the link.
            current = next.is_absolute() ? next : current.parent_path() / next;
            continue;
        }
        target.resolved = current.string();
        target.exists = true;
        if (S_ISREG(st.st_mode)) return target;
        if (S_ISCHR(st.st_mode) && isNullRdev(st.st_rdev)) {
            target.discard = true;
            return target;
        }
        const std::string what = target.resolved == path
                                     ? "'" + path + "' is "
                                     : "'" + path + "' is a link to '" + target.resolved +
                                           "', which is ";
        throw IoError(errorPrefix + ": " + what + kindOf(st.st_mode) +
                      ", not a regular file; write to a regular file, or to /dev/null to "
                      "discard the output");
    }
}

// ----------------------------------------------------------------------- temporary names

std::string temporaryFileName(const std::string& targetName, long pid, unsigned long long random)
{
    char suffix[48];
    std::snprintf(suffix, sizeof(suffix), ".%ld-%08llx.tmp", pid, random & 0xffffffffull);
    return "." + targetName + suffix;
}

bool parseTemporaryFileName(const std::string& fileName, const std::string& targetName, long& pid)
{
    // "." NAME "." DIGITS "-" 8 lower-case hex ".tmp"
    const std::string head = "." + targetName + ".";
    static const std::string tail = ".tmp";
    if (targetName.empty() || fileName.size() < head.size() + 1 + 1 + 8 + tail.size()) return false;
    if (fileName.compare(0, head.size(), head) != 0) return false;
    if (fileName.compare(fileName.size() - tail.size(), tail.size(), tail) != 0) return false;
    const std::string middle =
        fileName.substr(head.size(), fileName.size() - head.size() - tail.size()); // PID-XXXXXXXX
    const size_t dash = middle.find('-');
    if (dash == std::string::npos || dash == 0 || dash > 10) return false;
    if (middle.size() != dash + 1 + 8) return false;
    long value = 0;
    for (size_t i = 0; i < dash; ++i) {
        if (middle[i] < '0' || middle[i] > '9') return false;
        value = value * 10 + (middle[i] - '0');
    }
    for (size_t i = dash + 1; i < middle.size(); ++i) {
        if (!isLowerHex(middle[i])) return false;
    }
    if (value <= 0) return false;
    pid = value;
    return true;
}

int removeStaleTemporaryFiles(const std::string& resolvedTarget) noexcept
{
    int removed = 0;
    try {
        const std::string name = fs::path(resolvedTarget).filename().string();
        const std::string dir = parentDirectory(resolvedTarget).string();
        DIR* d = ::opendir(dir.c_str());
        if (!d) return 0;
        const long self = long(::getpid());
        while (const dirent* entry = ::readdir(d)) {
            long pid = 0;
            if (!parseTemporaryFileName(entry->d_name, name, pid)) continue;
            if (pid == self || pid > long(std::numeric_limits<pid_t>::max())) continue;
            // Alive (0) or alive under another user (EPERM): keep.
            if (::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;
            struct stat st {};
            if (::fstatat(::dirfd(d), entry->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0) continue;
            if (!S_ISREG(st.st_mode)) continue;
            if (::unlinkat(::dirfd(d), entry->d_name, 0) == 0) ++removed;
        }
        ::closedir(d);
    } catch (...) {
        // best effort
    }
    return removed;
}

// ---------------------------------------------------------------- interruption (signal-safe)

int removeLiveTemporaryFiles() noexcept
{
    int found = 0;
    for (int i = 0; i < kLiveSlots; ++i) {
        int expected = kLive;
        if (gLiveSlots[i].state.compare_exchange_strong(expected, kTaken)) {
            ::unlink(gLiveSlots[i].path);
            ++found;
        }
    }
    return found;
}

void abortWrites() noexcept { gWritesAborted.store(true); }

bool writesAborted() noexcept { return gWritesAborted.load(); }

void clearAbortedWrites() noexcept { gWritesAborted.store(false); }

// ------------------------------------------------------------------------------ AtomicFile

AtomicFile::AtomicFile(const std::string& path, std::string errorPrefix)
    : mPath(path), mPrefix(std::move(errorPrefix))
{
    const OutputTarget target = resolveOutputTarget(path, mPrefix);
    mTarget = target.resolved;

    if (target.discard) {
        // /dev/null: written through, never replaced.
        const int fd = ::open(mTarget.c_str(), O_WRONLY | O_CLOEXEC);
        if (fd < 0) throw IoError(mPrefix + ": " + std::strerror(errno));
        if (writesAborted()) {
            ::close(fd);
            throw InterruptedError("interrupted; '" + mPath + "' was not written");
        }
        mTemp = mTarget;
        mFd = fd;
        mWriteThrough = true;
        return;
    }

    removeStaleTemporaryFiles(mTarget);

    const fs::path dir = parentDirectory(mTarget);
    std::random_device rd;
    std::mt19937_64 rng((uint64_t(rd()) << 32) ^ uint64_t(rd()) ^
                        uint64_t(std::chrono::steady_clock::now().time_since_epoch().count()));
    const std::string base = fs::path(mTarget).filename().string();
    for (int attempt = 0; attempt < 100; ++attempt) {
        const std::string tmp =
            (dir / temporaryFileName(base, long(::getpid()), static_cast<unsigned long long>(rng())))
                .string();
        const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            mTemp = tmp;
            mFd = fd;
            mSlot = registerLive(absolutePath(tmp));
            // After registering: a handler that ran abortWrites() before it could see the slot
            // is seen here (both sides use sequentially consistent atomics).
            if (writesAborted()) {
                closeDescriptor();
                discard();
                throw InterruptedError("interrupted; '" + mPath + "' was not written");
            }
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
    discard();
}

void AtomicFile::discard() noexcept
{
    if (mDone) return;
    if (!mWriteThrough && !mTemp.empty()) ::unlink(mTemp.c_str());
    unregisterLive(mSlot);
    mSlot = -1;
    mDone = true;
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
    discard();
    throw IoError(mPrefix + ": " + cause);
}

void AtomicFile::sync()
{
    if (mWriteThrough) return; // fsync() of a character device fails with EINVAL
    if (const int err = syncFile(mTemp)) fail(std::strerror(err));
}

void AtomicFile::commit()
{
    closeDescriptor();
    if (writesAborted()) {
        discard();
        throw InterruptedError("interrupted; '" + mPath + "' was not written");
    }
    if (mWriteThrough) {
        mDone = true;
        return;
    }
    if (std::rename(mTemp.c_str(), mTarget.c_str()) != 0) fail(std::strerror(errno));
    unregisterLive(mSlot);
    mSlot = -1;
    mDone = true;
    syncFile(parentDirectory(mTarget).string(), /*directory=*/true); // best effort
}

void writeTextAtomic(const std::string& path, const std::string& text)
{
    AtomicFile file(path, "cannot write '" + path + "'");
    const char* p = text.data();
    size_t left = text.size();
    while (left > 0) {
        const ssize_t n = ::write(file.descriptor(), p, left);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) file.fail(std::strerror(errno));
        p += n;
        left -= size_t(n);
    }
    file.sync();
    file.commit();
}

} // namespace levelforge::detail
