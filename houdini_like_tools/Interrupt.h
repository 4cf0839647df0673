// SPDX-License-Identifier: Apache-2.0
// levelforge — Ctrl-C for the command line.
//
// The first SIGINT or SIGTERM asks the running operator to stop: CliProgress::wasInterrupted()
// returns true at the next progress check, the algorithm throws InterruptedError and discards
// its partial result, nothing is written, and the CLI exits with status 130. A second signal
// ends the process at once (the default action is restored after the first).
#pragma once

#include <levelforge/core/Progress.h>

namespace levelforge::ops {

/// Installs the SIGINT / SIGTERM handlers (main() calls it; library code never does).
void installInterruptHandlers();

/// True once SIGINT or SIGTERM has been received.
bool interruptRequested();

/// StderrProgress that also reports a pending Ctrl-C as an interruption.
class CliProgress : public StderrProgress
{
public:
    using StderrProgress::StderrProgress;
    bool wasInterrupted(int percent = -1) override;
};

} // namespace levelforge::ops
