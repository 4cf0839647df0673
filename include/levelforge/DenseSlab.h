// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Forwarding header, kept for one release (0.2): this header moved to
///        <levelforge/scan/DenseSlab.h>. Include that instead; this one will be removed in 0.3.
#pragma once
#if !defined(LEVELFORGE_NO_MOVED_HEADER_WARNINGS)
#pragma message("<levelforge/DenseSlab.h> moved to <levelforge/scan/DenseSlab.h>; this forwarding header goes away in levelforge 0.3")
#endif
#include <levelforge/scan/DenseSlab.h>
