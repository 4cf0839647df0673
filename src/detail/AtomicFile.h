// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one atomic file writer of the library: the data goes to a temporary sibling of
///        the target, which is flushed to disk and then rename()d over the target, so a reader
///        never sees a half-written file and a failed write leaves nothing behind.
///
/// The temporary file is `DIR/.NAME.PID-XXXXXXXX.tmp` (hidden, ends in .tmp, unique: created
/// with O_EXCL under a random suffix), created with mode 0666 & ~umask like any file the user
/// creates. Every IoError starts with the error prefix the writer passes (e.g.
/// "cannot write 'out.vdb'"), so messages name the file.
#pragma once

#include <filesystem>
#include <string>

namespace levelforge::detail {

/// Directory that will hold @p path ("." for a bare file name).
std::filesystem::path parentDirectory(const std::string& path);

/// A temporary file next to a target path, renamed over the target by commit(). Until then
/// (a failure, an exception, no commit()), the destructor removes it: the target is never
/// touched.
class AtomicFile
{
public:
    /// Creates an empty, uniquely named temporary file next to @p path and keeps it open for
    /// writing (descriptor()). Checks nothing else about the location (see the callers).
    /// @param[in] path         the file to write
    /// @param[in] errorPrefix  start of every IoError message, e.g. "cannot write 'out.vdb'"
    /// @throws IoError "<prefix>: cannot create a file in 'DIR': <errno text>", or "<prefix>: no
    ///         free temporary file name in 'DIR'".
    AtomicFile(const std::string& path, std::string errorPrefix);
    /// Closes the descriptor if still owned; removes the temporary file unless committed.
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// The target path.
    const std::string& path() const { return mPath; }
    /// The temporary file's path.
    const std::string& tempPath() const { return mTemp; }
    /// The temporary file's write descriptor (O_WRONLY | O_CLOEXEC), or -1 once released or closed.
    int descriptor() const { return mFd; }
    /// Hands the descriptor over to the caller (fdopen, gzdopen, ...), which then closes it.
    int releaseDescriptor();
    /// Closes the descriptor (for writers that reopen the temporary file by name).
    void closeDescriptor();

    /// Removes the temporary file and throws IoError "<prefix>: <cause>".
    [[noreturn]] void fail(const std::string& cause);
    /// Flushes the temporary file's data to disk (fsync); calls fail(<errno text>) on error.
    void sync();
    /// Renames the temporary file over the target (calls fail(<errno text>) on error), then
    /// flushes the directory entry (best effort).
    void commit();

private:
    std::string mPath, mTemp, mPrefix;
    int mFd = -1;
    bool mDone = false; ///< committed, or the temporary file already removed
};

} // namespace levelforge::detail
