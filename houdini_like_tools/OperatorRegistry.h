// SPDX-License-Identifier: Apache-2.0
// levelforge — the operator registry and the command-line front end generated from it.
//
// Operators register themselves (LEVELFORGE_REGISTER_OPERATOR in Operator.h) when the program
// starts. runCli() builds a CLI11 application from the declarations: one subcommand per
// operator, one positional per input/output, one `--option` per parameter, with help text,
// type/range checks and error messages all derived from the declaration.
#pragma once

#include "Operator.h"

#include <iosfwd>
#include <string>
#include <vector>

namespace levelforge::ops {

class OperatorRegistry
{
public:
    /// The registry the CLI uses; operators add themselves to it at start-up.
    static OperatorRegistry& global();

    /// Checks the declaration (std::logic_error if inconsistent or the name is taken) and adds it.
    void add(OperatorSpec spec);
    /// nullptr if no operator has this name.
    const OperatorSpec* find(const std::string& name) const;
    /// All operators, sorted by name.
    std::vector<const OperatorSpec*> list() const;

    /// Generated `levelforge --help` text: usage and the list of operators.
    std::string helpText(const std::string& program = "levelforge") const;

private:
    std::vector<OperatorSpec> mOps;
};

/// Exit statuses of the CLI.
enum ExitCode : int { kExitOk = 0, kExitFailure = 1, kExitUsage = 2, kExitInterrupted = 130 };

/// Runs the command line `argv` (argv[0] is the program name) against `registry`: parses it,
/// cooks the chosen operator and reports. Help goes to `out`; every failure becomes exactly
/// one line "levelforge: error: <message>" on `err`. Returns kExitOk, kExitUsage (bad command
/// line: unknown operator or option, missing or out-of-range value) or kExitFailure (the
/// operator failed: unreadable mesh, write error, ...) or kExitInterrupted (Ctrl-C, see
/// Interrupt.h). Never throws, never exits.
int runCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err,
           const OperatorRegistry& registry = OperatorRegistry::global());

/// The same, taking the arguments after the program name.
int runCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
           const OperatorRegistry& registry = OperatorRegistry::global());

} // namespace levelforge::ops
