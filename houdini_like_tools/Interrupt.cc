// SPDX-License-Identifier: Apache-2.0
// levelforge — Ctrl-C for the command line (see Interrupt.h).
#include "Interrupt.h"

#include <csignal>

namespace levelforge::ops {
namespace {

volatile std::sig_atomic_t gInterrupted = 0;

extern "C" void onInterruptSignal(int)
{
    gInterrupted = 1;
}

} // namespace

void installInterruptHandlers()
{
    struct sigaction action {};
    action.sa_handler = onInterruptSignal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND; // a second signal gets the default action: exit at once
    for (int sig : {SIGINT, SIGTERM}) {
        // A signal ignored by whoever started us (nohup, background jobs of a script) stays
        // ignored, as with any well-behaved Unix tool.
        struct sigaction previous {};
        if (sigaction(sig, nullptr, &previous) == 0 && previous.sa_handler == SIG_IGN) continue;
        sigaction(sig, &action, nullptr);
    }
}

bool interruptRequested() { return gInterrupted != 0; }

bool CliProgress::wasInterrupted(int percent)
{
    const bool stop = interruptRequested();
    if (!stop) StderrProgress::wasInterrupted(percent);
    return stop;
}

} // namespace levelforge::ops
