// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one atomic file writer of the library: the data goes to a temporary sibling of
///        the target, which is flushed to disk and then rename()d over the target, so a reader
///        never sees a half-written file and a failed write leaves nothing behind.
///
/// **What may be written (the output rule).** resolveOutputTarget() decides, and the
/// AtomicFile constructor applies it to every write:
/// - a path that does not exist yet, or an existing *regular file*: written atomically
///   (temporary file + rename);
/// - a *symbolic link* is followed (every hop, up to 40, a dangling link included) and the file
///   it points to is written: the temporary file is created next to the link's target and
///   renamed over the target, so the link itself stays a link (like `cp`, `sed -i
///   --follow-symlinks` or an editor that saves through a link). Replacing the link by a
///   regular file would silently break whatever else the link is for;
/// - `/dev/null` (any character device with the same device number as `/dev/null`, reached
///   directly or through a link) is *written through*: opened for writing and written
///   directly, without a temporary file, a rename or an fsync, so "discard the output"
///   works and the device node is never replaced;
/// - anything else that exists and is not a regular file (a directory, another character
///   device such as /dev/full, a block device, a FIFO, a socket) is refused with an IoError
///   that names the path and what it is, e.g. "cannot write '/dev/full': '/dev/full' is a
///   character device, not a regular file; write to a regular file, or to /dev/null to
///   discard the output". Nothing is opened, so a FIFO without a reader never blocks.
///
/// **Temporary file names.** The temporary file is `DIR/.NAME.PID-XXXXXXXX.tmp`: DIR and NAME
/// are the directory and file name of the (link-resolved) target, PID the decimal process id
/// of the writer and XXXXXXXX eight lower-case hexadecimal digits (random; the file is created
/// with O_EXCL, so the name is unique). It is hidden, ends in .tmp and is created with mode
/// 0666 & ~umask like any file the user creates. Every IoError starts with the error prefix
/// the writer passes (e.g. "cannot write 'out.vdb'"), so messages name the file.
///
/// **Stale temporary files.** A process killed outright (SIGKILL, a power cut) cannot remove
/// its temporary file. Before it creates its own, every AtomicFile removes the temporary files
/// *of the same target* left by processes that no longer exist: names that match the pattern
/// above exactly for this NAME in this DIR, that are regular files, and whose PID is not ours
/// and answers kill(PID, 0) with ESRCH. Files of live processes (or of processes of other
/// users: EPERM) are kept. A PID is only meaningful on this machine and in this PID namespace:
/// a temporary file left in a shared directory by a process of another machine or container
/// whose PID is not in use here is removed too (its writer has lost the race anyway: the
/// rename of a vanished temporary file fails with an error naming the target).
///
/// **Interruption.** Every AtomicFile with a temporary file registers the temporary file's
/// absolute path in a fixed-size, process-wide table of live temporary files (kLiveSlots
/// slots of kLivePathMax bytes; a write that finds no free slot or has a longer path still
/// works, it is just not covered). removeLiveTemporaryFiles() unlinks all of them and is
/// async-signal-safe (it uses only lock-free atomics and unlink()), for a signal handler that
/// ends the process right after (the CLI's SIGINT/SIGTERM handler, see
/// houdini_like_tools/Interrupt.h). abortWrites() (also async-signal-safe) marks every write
/// of the process as interrupted: an AtomicFile created afterwards, or committed afterwards,
/// removes its temporary file and throws InterruptedError instead. The check happens right
/// after the temporary file is registered and right before the rename; both use
/// sequentially consistent atomics, so a handler that calls abortWrites() and then
/// removeLiveTemporaryFiles() either removes a temporary file or is seen by its writer: no
/// temporary file survives an interruption, and no output appears after abortWrites()
/// returned (one whose rename had already begun may). The one gap: a process ended by a
/// handler in the instant between creating its temporary file and registering it leaves
/// the file behind; the next write of the same target removes it (stale temporary files).
#pragma once

#include <filesystem>
#include <string>

namespace levelforge::detail {

/// Directory that will hold @p path ("." for a bare file name).
std::filesystem::path parentDirectory(const std::string& path);

/// What an output path names, decided by resolveOutputTarget().
struct OutputTarget
{
    /// The path as given.
    std::string path;
    /// The file that will be replaced: @p path with every symbolic link followed (equal to
    /// path when it is not a link). The temporary file is created in its directory.
    std::string resolved;
    /// True when @p resolved exists (a regular file, or /dev/null).
    bool exists = false;
    /// True when @p resolved is /dev/null: the data is written through, no temporary file.
    bool discard = false;
};

/// Applies the output rule (see the file comment): follows symbolic links and refuses an
/// existing target that is neither a regular file nor /dev/null. Does not check that the
/// directory exists or is writable (creating the temporary file does).
/// @param[in] path         the output path (not empty)
/// @param[in] errorPrefix  start of the IoError message, e.g. "cannot write 'out.vdb'"
/// @throws IoError "<prefix>: '<path>' is a <kind>, not a regular file; write to a regular
///         file, or to /dev/null to discard the output" (kind: directory, character device,
///         block device, FIFO (named pipe), socket), or "<prefix>: too many levels of symbolic
///         links", or "<prefix>: <errno text>" when the path cannot be examined.
OutputTarget resolveOutputTarget(const std::string& path, const std::string& errorPrefix);

/// True if @p path, links followed, is a character device with /dev/null's device number.
bool isNullDevice(const std::string& path);

/// The name of a temporary file of @p targetName ("out.vdb" → ".out.vdb.PID-XXXXXXXX.tmp")
/// written by process @p pid with the random part @p random (only its low 32 bits are used).
std::string temporaryFileName(const std::string& targetName, long pid, unsigned long long random);

/// True if @p fileName is exactly a temporary file name of @p targetName (see
/// temporaryFileName()); stores the PID it names in @p pid.
bool parseTemporaryFileName(const std::string& fileName, const std::string& targetName, long& pid);

/// Removes the stale temporary files of @p resolvedTarget (see the file comment): those in its
/// directory named for its file name by a process that no longer exists. Best effort: never
/// throws. @return how many files it removed.
int removeStaleTemporaryFiles(const std::string& resolvedTarget) noexcept;

/// Capacity of the process-wide table of live temporary files.
constexpr int kLiveSlots = 32;
/// Longest absolute temporary path the table holds, terminating NUL included.
constexpr int kLivePathMax = 4096;

/// Async-signal-safe. Unlinks the temporary file of every AtomicFile of the process that has
/// not been committed or removed yet and marks those table entries as taken for good: call it
/// only when the process ends right after (a signal handler followed by _exit()). The writers'
/// own later clean-up then finds nothing to remove. @return how many live temporary files it
/// found (and unlinked; an unlink that fails because the file was just renamed or removed
/// counts too).
int removeLiveTemporaryFiles() noexcept;

/// Async-signal-safe. Marks every write of the process as interrupted (see the file comment);
/// stays set until clearAbortedWrites().
void abortWrites() noexcept;
/// True after abortWrites(), until clearAbortedWrites().
bool writesAborted() noexcept;
/// Allows writes again (tests; a long-running program that handled an interruption).
void clearAbortedWrites() noexcept;

/// A temporary file next to a target path, renamed over the target by commit(). Until then
/// (a failure, an exception, no commit()), the destructor removes it: the target is never
/// touched. The target follows the output rule of this file: links are followed, /dev/null is
/// written through (writesThrough()), other non-regular files are refused.
class AtomicFile
{
public:
    /// Applies the output rule (resolveOutputTarget()), removes stale temporary files of the
    /// target (removeStaleTemporaryFiles()), creates an empty, uniquely named temporary file
    /// next to the (link-resolved) target, registers it as live, and keeps it open for writing
    /// (descriptor()). For /dev/null, opens /dev/null itself instead.
    /// @param[in] path         the file to write
    /// @param[in] errorPrefix  start of every IoError message, e.g. "cannot write 'out.vdb'"
    /// @throws IoError as resolveOutputTarget(), or "<prefix>: cannot create a file in 'DIR':
    ///         <errno text>", or "<prefix>: no free temporary file name in 'DIR'".
    /// @throws InterruptedError after abortWrites() (nothing is left behind).
    AtomicFile(const std::string& path, std::string errorPrefix);
    /// Closes the descriptor if still owned; removes the temporary file unless committed.
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// The target path, as given.
    const std::string& path() const { return mPath; }
    /// The file that commit() replaces: path() with symbolic links followed.
    const std::string& targetPath() const { return mTarget; }
    /// The path to write: the temporary file's path, or /dev/null's path when writesThrough()
    /// (writers that write by name, such as OpenVDB's io::File, then write straight to it).
    const std::string& tempPath() const { return mTemp; }
    /// True when the target is /dev/null: no temporary file, sync() and commit() only close,
    /// nothing is ever removed or renamed, and reading tempPath() back yields nothing.
    bool writesThrough() const { return mWriteThrough; }
    /// The write descriptor (O_WRONLY | O_CLOEXEC), or -1 once released or closed.
    int descriptor() const { return mFd; }
    /// Hands the descriptor over to the caller (fdopen, gzdopen, ...), which then closes it.
    int releaseDescriptor();
    /// Closes the descriptor (for writers that reopen the temporary file by name).
    void closeDescriptor();

    /// Removes the temporary file and throws IoError "<prefix>: <cause>".
    [[noreturn]] void fail(const std::string& cause);
    /// Flushes the temporary file's data to disk (fsync); calls fail(<errno text>) on error.
    /// Does nothing when writesThrough().
    void sync();
    /// Renames the temporary file over the target (calls fail(<errno text>) on error), then
    /// flushes the directory entry (best effort). When writesThrough(), only closes.
    /// @throws InterruptedError after abortWrites(): the temporary file is removed and the
    ///         target left as it was.
    void commit();

private:
    /// Removes the temporary file (unless written through) and marks this file done.
    void discard() noexcept;

    std::string mPath, mTarget, mTemp, mPrefix;
    int mFd = -1;
    int mSlot = -1;            ///< index in the live table, or -1 when not registered
    bool mWriteThrough = false;
    bool mDone = false;        ///< committed, or the temporary file already removed
};

/// Writes @p text to @p path through an AtomicFile (temp, fsync, rename): the whole text or no
/// file. Throws IoError "cannot write '<path>': <cause>".
void writeTextAtomic(const std::string& path, const std::string& text);

} // namespace levelforge::detail
