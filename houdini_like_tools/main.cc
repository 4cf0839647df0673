// SPDX-License-Identifier: Apache-2.0
// levelforge — command-line entry point. Everything (operators, options, help, errors) comes
// from the operator registry; see OperatorRegistry.h.
#include "Interrupt.h"
#include "OperatorRegistry.h"
#include "Plugins.h"

#include <iostream>
#include <string>
#include <vector>

#ifdef LEVELFORGE_WITH_JEMALLOC
// jemalloc's options, read at its first allocation (the environment's MALLOC_CONF comes after and
// overrides them): transparent huge pages for its mappings, which a conversion first-touches by
// the hundreds of MB (houdini_like_tools/CMakeLists.txt).
extern "C" {
extern const char* malloc_conf;
const char* malloc_conf = "thp:always,metadata_thp:auto";
}
#endif

int main(int argc, char** argv)
{
    levelforge::ops::installInterruptHandlers();
    std::vector<std::string> args(argv + 1, argv + argc);
    if (const int rc = levelforge::ops::loadPlugins(args, std::cerr)) return rc;
    return levelforge::ops::runCli(argc, argv, std::cout, std::cerr);
}
