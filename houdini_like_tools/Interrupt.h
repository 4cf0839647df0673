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
//
// Async-signal safety: the handler uses only a lock-free std::atomic counter, a volatile
// sig_atomic_t flag, the lock-free atomics of detail's fixed-size table of live temporary
// paths, unlink(), write() and _exit(); it allocates nothing and takes no lock. errno is
// preserved when it returns. SIGINT and SIGTERM are blocked while it runs (no nesting on one
// thread), and SA_RESTART keeps system calls of the computing threads from failing with EINTR.
// A signal that was ignored when the process started (nohup, background jobs) stays ignored.
#pragma once

#include <levelforge/core/Progress.h>

namespace levelforge::ops {

/// Installs the SIGINT / SIGTERM handlers (main() calls it; library code never does).
void installInterruptHandlers();

/// True once SIGINT or SIGTERM has been received.
bool interruptRequested();

/// @brief While alive, SIGINT / SIGTERM end the process at once (status 130): wrap the reading of
///        inputs, which has no side effects and polls no interrupter. Throws InterruptedError
///        when a signal has already arrived. Not nestable across threads (one reader at a time).
class ReadingScope
{
public:
    ReadingScope();
    ~ReadingScope();
    ReadingScope(const ReadingScope&) = delete;
    ReadingScope& operator=(const ReadingScope&) = delete;
};

/// StderrProgress that also reports a pending Ctrl-C as an interruption.
class CliProgress : public StderrProgress
{
public:
    using StderrProgress::StderrProgress;
    bool wasInterrupted(int percent = -1) override;
};

} // namespace levelforge::ops
