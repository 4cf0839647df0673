// SPDX-License-Identifier: Apache-2.0
// levelforge — command-line entry point. Everything (operators, options, help, errors) comes
// from the operator registry; see OperatorRegistry.h.
#include "Interrupt.h"
#include "OperatorRegistry.h"

#include <iostream>

int main(int argc, char** argv)
{
    levelforge::ops::installInterruptHandlers();
    return levelforge::ops::runCli(argc, argv, std::cout, std::cerr);
}
