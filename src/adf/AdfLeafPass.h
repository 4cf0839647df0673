// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Private to src/adf/: which build of the ADF builder's per-leaf sample pass runs
///        (AdfLeafPass.cc), for the tests.
#pragma once

namespace levelforge {
namespace adf_internal {

/// Whether the builder's per-leaf sample pass runs its AVX2 build on this CPU (x86-64 with
/// AVX2). It is the same code in VEX encoding (no FMA, nothing contracted), so every value is
/// bit-identical to the baseline build's; only the speed differs.
bool avx2LeafPassAvailable();

/// Testing hook: false forces the baseline build of the leaf pass (process-wide; not for use
/// while a build runs on another thread).
void setAvx2LeafPassEnabled(bool enabled);

} // namespace adf_internal
} // namespace levelforge
