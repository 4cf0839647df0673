// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Forwarding header, kept for one release (0.2): the vector expansion is used through
///        <levelforge/expand/ExpandLevelSet.h> (expandLevelSet() with ExpansionMethod::Vector);
///        its propagation step is private (src/expand/VectorExpansion.h). This header goes away
///        in 0.3.
#pragma once
#if !defined(LEVELFORGE_NO_MOVED_HEADER_WARNINGS)
#pragma message("<levelforge/VectorExpansion.h> moved: use <levelforge/expand/ExpandLevelSet.h>; this forwarding header goes away in levelforge 0.3")
#endif
#include <levelforge/expand/ExpandLevelSet.h>
