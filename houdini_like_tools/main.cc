// SPDX-License-Identifier: Apache-2.0
// levelforge — command-line entry point. Everything (operators, options, help, errors) comes
// from the operator registry; see OperatorRegistry.h.
#include "Interrupt.h"
#include "OperatorRegistry.h"
#include "Plugins.h"

#include <iostream>
#include <string>
#include <vector>

int main(int argc, char** argv)
{
    levelforge::ops::installInterruptHandlers();
    std::vector<std::string> args(argv + 1, argv + argc);
    if (const int rc = levelforge::ops::loadPlugins(args, std::cerr)) return rc;
    return levelforge::ops::runCli(argc, argv, std::cout, std::cerr);
}
