// SPDX-License-Identifier: Apache-2.0
// Force-included into every translation unit of the ThreadSanitizer build (CMakeLists.txt,
// LEVELFORGE_SANITIZE=thread). Debian's libopenvdb is built with explicit template
// instantiation: its headers declare `extern template` for the tools on the standard trees
// (dilateActiveValues, prune, signedFloodFill, ...), so those run as uninstrumented code inside
// libopenvdb.so, and TSan cannot see the joins of their TBB loops (it reported a tree built in a
// worker and freed by the caller as a race). Without the macro, every template is instantiated in
// our own, instrumented objects.
#pragma once
#include <openvdb/version.h>
#undef OPENVDB_USE_EXPLICIT_INSTANTIATION
