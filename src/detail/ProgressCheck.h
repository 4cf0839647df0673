// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The one interrupter poll of the library's stages (implemented in core/Progress.cc).
#pragma once

#include <openvdb/util/NullInterrupter.h>

namespace levelforge::progress_internal {

/// Calls interrupter->wasInterrupted(percent) if an interrupter is set; throws InterruptedError
/// when it asks to stop.
void check(openvdb::util::NullInterrupter* interrupter, int percent = -1);

} // namespace levelforge::progress_internal
