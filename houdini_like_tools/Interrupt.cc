// SPDX-License-Identifier: Apache-2.0
// levelforge — Ctrl-C for the command line (see Interrupt.h).
#include "Interrupt.h"

#include "OperatorRegistry.h" // kExitInterrupted

// The library's private atomic writer (its signal-safe table of live temporary files). Included
// by a relative path: levelforge_ops does not have src/ on its include path.
#include "detail/AtomicFile.h"

#include <levelforge/core/Exceptions.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <filesystem>

#include <unistd.h>

namespace levelforge::ops {
namespace {

volatile std::sig_atomic_t gInterrupted = 0;
std::atomic<int> gReading{0}; // ReadingScopes alive (frames read in parallel)
std::atomic<int> gSignalCount{0};
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs lock-free counters");

// The paths of ExitCleanupPath: Free -> Filling -> Live -> Free, and Live -> Taken by the
// handler for good (as detail's table of live temporary files).
enum CleanupState : int { kFree = 0, kFilling = 1, kLive = 2, kTaken = 3 };

struct CleanupSlot
{
    std::atomic<int> state{kFree};
    char path[ExitCleanupPath::kExitCleanupPathMax];
};

CleanupSlot gCleanup[ExitCleanupPath::kExitCleanupSlots]; // zero-initialised: every slot Free

/// Async-signal-safe: removes every registered file, then every registered directory.
void removeCleanupPaths() noexcept
{
    bool taken[ExitCleanupPath::kExitCleanupSlots] = {};
    for (int i = 0; i < ExitCleanupPath::kExitCleanupSlots; ++i) {
        int expected = kLive;
        taken[i] = gCleanup[i].state.compare_exchange_strong(expected, kTaken);
        if (taken[i]) ::unlink(gCleanup[i].path); // fails (EISDIR) for a directory
    }
    for (int i = 0; i < ExitCleanupPath::kExitCleanupSlots; ++i) {
        if (taken[i]) ::rmdir(gCleanup[i].path); // fails (ENOTDIR, ENOENT) for a file
    }
}

/// write() all of a literal to stderr, ignoring errors (async-signal-safe).
template<size_t N>
void writeStderr(const char (&text)[N])
{
    const char* p = text;
    size_t left = N - 1;
    while (left > 0) {
        const ssize_t n = ::write(STDERR_FILENO, p, left);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) return;
        p += n;
        left -= size_t(n);
    }
}

extern "C" void onInterruptSignal(int)
{
    const int savedErrno = errno;
    gInterrupted = 1;
    const int count = gSignalCount.fetch_add(1) + 1;
    // First: no output may appear from now on. Then: a write in progress cannot be stopped
    // gracefully (OpenVDB writes in one blocking call), so remove its temporary file and end.
    detail::abortWrites();
    const int live = detail::removeLiveTemporaryFiles();
    if (live > 0) {
        removeCleanupPaths();
        writeStderr("levelforge: error: interrupted while writing; the partial output was removed\n");
        ::_exit(kExitInterrupted);
    }
    if (count >= 2 || gReading.load() > 0) {
        removeCleanupPaths();
        writeStderr("levelforge: error: interrupted\n");
        ::_exit(kExitInterrupted);
    }
    errno = savedErrno;
}

} // namespace

void installInterruptHandlers()
{
    struct sigaction action {};
    action.sa_handler = onInterruptSignal;
    sigemptyset(&action.sa_mask);
    sigaddset(&action.sa_mask, SIGINT);
    sigaddset(&action.sa_mask, SIGTERM);
    // No SA_RESETHAND: a second signal must still remove the temporary files before the
    // process ends (the handler does, then _exit(130)).
    action.sa_flags = SA_RESTART;
    for (int sig : {SIGINT, SIGTERM}) {
        // A signal ignored by whoever started us (nohup, background jobs of a script) stays
        // ignored, as with any well-behaved Unix tool.
        struct sigaction previous {};
        if (sigaction(sig, nullptr, &previous) == 0 && previous.sa_handler == SIG_IGN) continue;
        sigaction(sig, &action, nullptr);
    }
}

bool interruptRequested() { return gInterrupted != 0; }

ReadingScope::ReadingScope()
{
    gReading.fetch_add(1);
    if (interruptRequested()) {
        gReading.fetch_sub(1);
        throw InterruptedError("interrupted");
    }
}

ReadingScope::~ReadingScope() { gReading.fetch_sub(1); }

ExitCleanupPath::ExitCleanupPath(const std::string& path)
{
    std::string abs = path;
    try {
        std::error_code ec;
        const std::filesystem::path a = std::filesystem::absolute(path, ec);
        if (!ec) abs = a.string();
    } catch (...) {
    }
    if (abs.empty() || abs.size() >= size_t(kExitCleanupPathMax)) return;
    for (int i = 0; i < kExitCleanupSlots; ++i) {
        int expected = kFree;
        if (gCleanup[i].state.compare_exchange_strong(expected, kFilling)) {
            std::memcpy(gCleanup[i].path, abs.c_str(), abs.size() + 1);
            gCleanup[i].state.store(kLive);
            mSlot = i;
            return;
        }
    }
}

ExitCleanupPath::~ExitCleanupPath()
{
    if (mSlot < 0) return;
    int expected = kLive;
    gCleanup[mSlot].state.compare_exchange_strong(expected, kFree); // stays Taken if the handler took it
}

} // namespace levelforge::ops
