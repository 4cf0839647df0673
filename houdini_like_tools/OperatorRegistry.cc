// SPDX-License-Identifier: Apache-2.0
// levelforge — operator registry and the generated command line (see OperatorRegistry.h).
#include "OperatorRegistry.h"

#include "FrameRunner.h"

#include "detail/MessageText.h"

#include <levelforge/io/VdbIO.h> // generatorString()

#include <CLI/CLI.hpp>

#include <algorithm>
#include <iostream>
#include <map>
#include <memory>
#include <new>
#include <sstream>
#include <stdexcept>

namespace levelforge::ops {

namespace registry_internal {

/// Error messages are printed on one line.
std::string oneLine(std::string msg)
{
    for (char& c : msg) {
        if (c == '\n' || c == '\r') c = ' ';
    }
    while (!msg.empty() && msg.back() == ' ') msg.pop_back();
    return msg.empty() ? std::string("unknown error") : msg;
}

std::string operatorList(const OperatorRegistry& registry)
{
    std::string s;
    for (const OperatorSpec* op : registry.list()) s += (s.empty() ? "" : ", ") + op->name();
    return s;
}

/// Values collected by CLI11 for one operator, before they are checked against the declaration.
struct Collected
{
    std::map<std::string, std::string> ports;
    std::map<std::string, std::string> texts;
    std::map<std::string, std::vector<std::string>> lists; // repeatable parameters
    std::map<std::string, int64_t> flags;
    std::map<std::string, CLI::Option*> options;
    // the common options (FrameRunner.h)
    std::string frames, reportJson;
    int jobs = 1;
    int taskIndex = 0, taskCount = 1;
    int64_t stopOnError = 0;
    CLI::Option* taskIndexOption = nullptr;
    CLI::Option* taskCountOption = nullptr;
    std::vector<std::string> plugins;
    CLI::Option* framesOption = nullptr;
};

int report(std::ostream& err, const std::string& message, int code)
{
    err << "levelforge: error: " << oneLine(message) << std::endl;
    return code;
}

} // namespace registry_internal

using namespace registry_internal;

OperatorRegistry& OperatorRegistry::global()
{
    static OperatorRegistry registry;
    return registry;
}

void OperatorRegistry::add(OperatorSpec spec)
{
    spec.checkDeclaration();
    if (find(spec.name())) {
        throw std::logic_error("operator '" + spec.name() + "' is registered twice");
    }
    mOps.push_back(std::move(spec));
}

const OperatorSpec* OperatorRegistry::find(const std::string& name) const
{
    for (const OperatorSpec& op : mOps) {
        if (op.name() == name) return &op;
    }
    return nullptr;
}

std::vector<const OperatorSpec*> OperatorRegistry::list() const
{
    std::vector<const OperatorSpec*> ops;
    for (const OperatorSpec& op : mOps) ops.push_back(&op);
    std::sort(ops.begin(), ops.end(),
              [](const OperatorSpec* a, const OperatorSpec* b) { return a->name() < b->name(); });
    return ops;
}

std::string OperatorRegistry::helpText(const std::string& program) const
{
    std::ostringstream os;
    os << generatorString()
       << " - triangle meshes to exact signed distance fields in OpenVDB level sets\n\n"
       << "Usage: " << program << " <operator> <inputs...> <outputs...> [options]\n"
       << "       " << program << " <operator> --help\n\n"
       << "Operators:\n";
    size_t width = 0;
    for (const OperatorSpec* op : list()) width = std::max(width, op->name().size());
    for (const OperatorSpec* op : list()) {
        os << "  " << op->name() << std::string(width + 3 - op->name().size(), ' ') << op->help()
           << "\n";
    }
    os << "\nOptions:\n"
       << "  -h, --help" << std::string(width > 7 ? width - 7 : 1, ' ')
       << "Print this help (or an operator's help) and exit.\n"
       << "  --version" << std::string(width > 6 ? width - 6 : 1, ' ')
       << "Print the version and exit.\n\n"
       << "Errors are reported as one line \"levelforge: error: <message>\" on stderr;\n"
       << "the exit status is 2 for usage errors and 1 when an operator fails.\n";
    return os.str();
}

int runCli(int argc, const char* const* argv, std::ostream& out, std::ostream& err,
           const OperatorRegistry& registry)
{
    std::vector<std::string> args;
    for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
    return runCli(args, out, err, registry);
}

int runCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err,
           const OperatorRegistry& registry)
{
    const std::string program = "levelforge";
    try {
        // The operator comes first; give a precise message for an unknown one.
        if (args.empty()) {
            return report(err, "no operator given (one of: " + operatorList(registry) +
                                   "); see '" + program + " --help'", kExitUsage);
        }
        if (!args[0].empty() && args[0][0] != '-' && !registry.find(args[0])) {
            return report(err, "unknown operator '" + args[0] + "' (one of: " +
                                   operatorList(registry) + "); see '" + program + " --help'",
                          kExitUsage);
        }

        CLI::App app(generatorString(), program);
        app.set_version_flag("--version", generatorString());
        app.formatter_fn([&registry, program](const CLI::App*, std::string, CLI::AppFormatMode) {
            return registry.helpText(program);
        });
        app.require_subcommand(0, 1);
        std::vector<std::string> appPlugins; // loaded by main() before the parse (Plugins.h)
        app.add_option("--plugin", appPlugins, "Load operators from a plugin library")
            ->expected(1)
            ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);

        std::map<std::string, Collected> collected;
        for (const OperatorSpec* spec : registry.list()) {
            CLI::App* sub = app.add_subcommand(spec->name(), spec->help());
            sub->formatter_fn([spec, program](const CLI::App*, std::string, CLI::AppFormatMode) {
                return spec->helpText(program);
            });
            Collected& c = collected[spec->name()];
            for (const auto* ports : {&spec->inputs(), &spec->outputs()}) {
                for (const Port& port : *ports) {
                    c.options[port.name] = sub->add_option(port.name, c.ports[port.name], port.help);
                }
            }
            c.framesOption = sub->add_option("--frames", c.frames, "Frame Range");
            sub->add_option("--jobs", c.jobs, "Jobs")->check(CLI::Range(1, 1024));
            sub->add_flag("--stop-on-error", c.stopOnError, "Stop On Error");
            sub->add_option("--report-json", c.reportJson, "Report File");
            c.taskIndexOption = sub->add_option("--task-index", c.taskIndex, "Task Index")->check(CLI::NonNegativeNumber);
            c.taskCountOption = sub->add_option("--task-count", c.taskCount, "Task Count")->check(CLI::PositiveNumber);
            sub->add_option("--plugin", c.plugins, "Plugin")->expected(1)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
            for (const Param& p : spec->params()) {
                if (p.type == ParamType::Bool) {
                    c.options[p.name] = sub->add_flag(p.option(), c.flags[p.name], p.help);
                } else if (p.repeatable) {
                    c.options[p.name] = sub->add_option(p.option(), c.lists[p.name], p.help)
                                            ->type_name(p.metavar())
                                            ->expected(1)
                                            ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
                } else {
                    c.options[p.name] = sub->add_option(p.option(), c.texts[p.name], p.help)
                                            ->type_name(p.metavar());
                }
            }
        }

        std::vector<std::string> reversed(args.rbegin(), args.rend());
        try {
            app.parse(reversed);
        } catch (const CLI::CallForHelp&) {
            out << app.help();
            return kExitOk;
        } catch (const CLI::CallForAllHelp&) {
            out << app.help("", CLI::AppFormatMode::All);
            return kExitOk;
        } catch (const CLI::CallForVersion&) {
            out << generatorString() << "\n";
            return kExitOk;
        } catch (const CLI::ParseError& e) {
            std::string hint = " (see '" + program + " --help')";
            const auto subs = app.get_subcommands();
            if (!subs.empty()) hint = " (see '" + program + " " + subs[0]->get_name() + " --help')";
            return report(err, e.what() + hint, kExitUsage);
        }

        const auto subs = app.get_subcommands();
        if (subs.empty()) {
            return report(err, "no operator given (one of: " + operatorList(registry) +
                                   "); see '" + program + " --help'", kExitUsage);
        }
        const OperatorSpec& spec = *registry.find(subs[0]->get_name());
        const Collected& c = collected.at(spec.name());

        OperatorArgs opArgs(spec, out, err);
        try {
            for (const auto* ports : {&spec.inputs(), &spec.outputs()}) {
                for (const Port& port : *ports) {
                    if (c.options.at(port.name)->count() > 0) {
                        opArgs.setPort(port.name, c.ports.at(port.name));
                    }
                }
            }
            for (const Param& p : spec.params()) {
                if (c.options.at(p.name)->count() == 0) continue;
                if (p.type == ParamType::Bool) {
                    opArgs.setFlag(p.name, c.flags.at(p.name) > 0);
                } else if (p.repeatable) {
                    std::string joined;
                    for (const std::string& v : c.lists.at(p.name)) joined += (joined.empty() ? "" : ",") + v;
                    opArgs.set(p.name, joined);
                } else {
                    opArgs.set(p.name, c.texts.at(p.name));
                }
            }
            opArgs.checkComplete();
        } catch (const UsageError& e) {
            return report(err, std::string(e.what()) + " (see '" + program + " " + spec.name() +
                                   " --help')", kExitUsage);
        }

        CommonOptions common;
        common.jobs = c.jobs;
        common.stopOnError = c.stopOnError > 0;
        common.reportJson = c.reportJson;
        if (c.taskIndexOption->count() > 0) common.taskIndex = c.taskIndex;
        if (c.taskCountOption->count() > 0) common.taskCount = c.taskCount;
        try {
            if (c.framesOption->count() > 0) common.frames = parseFrameRange(c.frames);
        } catch (const UsageError& e) {
            return report(err, std::string(e.what()) + " (see '" + program + " " + spec.name() + " --help')",
                          kExitUsage);
        }
        if (spec.precheckFunction()) {
            // once, before any frame: a bad pipeline is one error, not one per frame
            OperatorArgs first = common.frames ? opArgs.forFrame(common.frames->first) : opArgs;
            spec.precheckFunction()(first);
        }
        return cookWithCommonOptions(opArgs, common, out, err);
    } catch (const UsageError& e) {
        return report(err, e.what(), kExitUsage);
    } catch (const InterruptedError& e) {
        return report(err, e.what(), kExitInterrupted);
    } catch (const CLI::Error& e) {
        return report(err, e.what(), kExitUsage);
    } catch (const std::bad_alloc&) {
        return report(err, "out of memory", kExitFailure);
    } catch (const std::exception& e) {
        // our own messages are short; a dependency's can be gigabytes (a corrupt file)
        return report(err, message_internal::cutDependencyMessage(e.what(), 2000), kExitFailure);
    } catch (...) {
        return report(err, "unknown failure", kExitFailure);
    }
}

} // namespace levelforge::ops
