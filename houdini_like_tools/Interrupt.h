// SPDX-License-Identifier: Apache-2.0
// levelforge — Ctrl-C (SIGINT) and SIGTERM for the command line.
//
// The first SIGINT or SIGTERM asks the running operator to stop:
//  - while it computes, CliProgress::wasInterrupted() returns true at the next progress check,
//    the algorithm throws InterruptedError and discards its partial result, nothing is
//    written, and the CLI prints "levelforge: error: interrupted" and exits with status 130;
//  - the handler also calls detail::abortWrites(): an output file whose writing starts later,
//    or whose rename has not begun yet, is not written (its AtomicFile removes the temporary
//    file and throws InterruptedError; same message, same status);
//  - while an output is being written (an AtomicFile holds a live temporary file, e.g. during
//    OpenVDB's one blocking io::File::write call, which cannot be interrupted), the handler
//    itself unlinks every live temporary file (detail::removeLiveTemporaryFiles()), writes
//    "levelforge: error: interrupted while writing; the partial output was removed" to stderr
//    and ends the process with _exit(130). The target file is left as it was before.
//  - while an input is being read (a ReadingScope is alive: the readers poll no interrupter, and
//    a 60 MB mesh takes a few tenths of a second), the handler writes "levelforge: error:
//    interrupted" and ends the process with _exit(130) at once: reading has no side effects.
// A second signal ends the process at once the same way (temporary files removed, one error
// line, status 130), whatever it is doing.
// Whenever the handler ends the process, it also removes the paths registered with an
// ExitCleanupPath (the staging directories of `levelforge run` and the files staged in them):
// first every registered file, then every registered (by then empty) directory.
//
// Async-signal safety: the handler uses only a lock-free std::atomic counter, a volatile
// sig_atomic_t flag, the lock-free atomics of detail's fixed-size table of live temporary
// paths, unlink(), write() and _exit(); it allocates nothing and takes no lock. errno is
// preserved when it returns. SIGINT and SIGTERM are blocked while it runs (no nesting on one
// thread), and SA_RESTART keeps system calls of the computing threads from failing with EINTR.
// A signal that was ignored when the process started (nohup, background jobs) stays ignored.
#pragma once

#include <levelforge/core/Progress.h>

#include <atomic>
#include <chrono>
#include <string>

namespace levelforge::ops {

/// Installs the SIGINT / SIGTERM handlers (main() calls it; library code never does).
void installInterruptHandlers();

/// True once SIGINT or SIGTERM has been received.
bool interruptRequested();

/// @brief While alive, SIGINT / SIGTERM end the process at once (status 130): wrap the reading of
///        inputs, which has no side effects and polls no interrupter. Throws InterruptedError
///        when a signal has already arrived. Scopes may be alive on several threads at once
///        (frames read in parallel): the process ends while any is alive.
class ReadingScope
{
public:
    ReadingScope();
    ~ReadingScope();
    ReadingScope(const ReadingScope&) = delete;
    ReadingScope& operator=(const ReadingScope&) = delete;
};

/// @brief While alive, a signal handler that ends the process (see the file comment) removes
///        @p path: unlink() for a file, rmdir() for a directory (files are removed first, so a
///        directory whose files are all registered goes too). Async-signal-safe on the handler's
///        side (a fixed table of kExitCleanupSlots paths, lock-free atomics); a path that finds
///        no free slot, or is longer than kExitCleanupPathMax - 1 bytes, is not covered.
///        Relative paths are made absolute. Thread-safe.
class ExitCleanupPath
{
public:
    static constexpr int kExitCleanupSlots = 128;
    static constexpr int kExitCleanupPathMax = 4096;
    explicit ExitCleanupPath(const std::string& path);
    ~ExitCleanupPath();
    ExitCleanupPath(const ExitCleanupPath&) = delete;
    ExitCleanupPath& operator=(const ExitCleanupPath&) = delete;
    /// False when the table was full or the path too long.
    bool covered() const { return mSlot >= 0; }

private:
    int mSlot = -1;
};

/// @brief The operators' progress reporter; also reports a pending Ctrl-C as an interruption.
///
/// How it prints (stderr), chosen when it is made:
///  - on a terminal (stderr is a TTY and TERM is not "dumb"): one updating bar per stage,
///    "levelforge: <stage> [########------------]  40%  ETA 3 s", redrawn at most 10 times a
///    second, ended by "levelforge: <stage> done (N.NN s)";
///  - otherwise: plain lines "levelforge: <stage> 40%" every `minStep` percent, then the
///    "done" line (what a log file or a farm scheduler wants);
///  - nothing when disabled (--quiet) or inside a SilentProgressScope (frames cooked in
///    parallel report per frame instead).
/// Stages that end within half a second print nothing. LEVELFORGE_PROGRESS=bar|plain|none
/// overrides the choice (bar: even when not a terminal). The stage name is prefixed by the
/// ProgressPrefixScope of the thread that made the reporter ("frame 12 (3/240) step 2/3 reshape: ").
class CliProgress : public openvdb::util::NullInterrupter
{
public:
    explicit CliProgress(int minStep = 10, bool enabled = true);
    void start(const char* name = nullptr) override;
    void end() override;
    /// Prints progress (safe to call from TBB worker threads); true once Ctrl-C was pressed.
    bool wasInterrupted(int percent = -1) override;

private:
    void draw(int percent, bool final);

    enum class Mode { None, Plain, Bar };
    Mode mMode;
    int mStep;
    std::string mPrefix, mName;
    std::atomic<int> mLast{-1};          ///< last printed percent (plain) or drawn percent (bar)
    std::atomic<long long> mLastDrawNs{0};
    std::atomic<bool> mDrawing{false};
    std::chrono::steady_clock::time_point mStart;
};

/// While alive, CliProgress reporters made on this thread prefix their stage names with @p prefix.
class ProgressPrefixScope
{
public:
    explicit ProgressPrefixScope(std::string prefix);
    ~ProgressPrefixScope();
    ProgressPrefixScope(const ProgressPrefixScope&) = delete;
    ProgressPrefixScope& operator=(const ProgressPrefixScope&) = delete;
    /// The prefix in effect on this thread.
    static const std::string& current();

private:
    std::string mSaved;
};

/// While alive, CliProgress reporters made on this thread print nothing.
class SilentProgressScope
{
public:
    SilentProgressScope();
    ~SilentProgressScope();
    SilentProgressScope(const SilentProgressScope&) = delete;
    SilentProgressScope& operator=(const SilentProgressScope&) = delete;
    static bool active();

private:
    bool mSaved;
};

} // namespace levelforge::ops
