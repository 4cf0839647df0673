// SPDX-License-Identifier: Apache-2.0
// levelforge operators — pipeline files and their runs (see Pipeline.h).
#include "Pipeline.h"

#include "FrameRunner.h"
#include "Interrupt.h"
#include "OperatorIO.h"

#include "detail/AtomicFile.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/reference/MeshShapes.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <exception>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>

#include <unistd.h>

namespace fs = std::filesystem;

namespace levelforge::ops {
namespace {

using Json = nlohmann::json;

[[noreturn]] void invalid(const std::string& path, const std::string& what)
{
    throw InvalidArgumentError("pipeline '" + path + "': " + what);
}

const char* jsonType(const Json& j)
{
    return j.type_name();
}

/// The text OperatorArgs::set() parses for a JSON value of a parameter.
std::string paramText(const Param& p, const Json& v, const std::string& where)
{
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number_integer()) return std::to_string(v.get<long long>());
    if (v.is_number_float()) {
        char buf[40];
        std::snprintf(buf, sizeof buf, "%.17g", v.get<double>());
        return buf;
    }
    if (v.is_array() && p.repeatable) {
        std::string joined;
        for (const Json& e : v) {
            if (!e.is_string()) throw UsageError(where + ": every value of " + p.option() + " must be a string");
            joined += (joined.empty() ? "" : ",") + e.get<std::string>();
        }
        return joined;
    }
    throw UsageError(where + ": " + p.option() + " (" + p.label + ") takes " +
                     (p.type == ParamType::Bool ? "true or false" : std::string("a ") + toString(p.type)) +
                     ", not " + jsonType(v));
}

std::vector<std::string> stringList(const Json& step, const char* key, const std::string& path, const std::string& where)
{
    std::vector<std::string> list;
    if (!step.contains(key)) return list;
    const Json& a = step.at(key);
    if (!a.is_array()) invalid(path, where + ": \"" + key + "\" must be a list of names");
    for (const Json& e : a) {
        if (!e.is_string() || e.get<std::string>().empty())
            invalid(path, where + ": every entry of \"" + key + "\" must be a non-empty string");
        list.push_back(e.get<std::string>());
    }
    return list;
}

/// Replaces every occurrence of @p from by @p to in @p text.
std::string replaceAll(std::string text, const std::string& from, const std::string& to)
{
    if (from.empty()) return text;
    for (size_t pos = 0; (pos = text.find(from, pos)) != std::string::npos; pos += to.size())
        text.replace(pos, from.size(), to);
    return text;
}

/// Files of one frame: staged in hidden directories next to their targets, moved into place by
/// commit(), removed otherwise.
class FrameStaging
{
public:
    ~FrameStaging()
    {
        std::error_code ec;
        for (const auto& [dir, staging] : mDirs) fs::remove_all(staging, ec);
        // mCleanup is released after this: a signal that ends the process in between finds
        // only paths that are gone already
    }

    /// The staged path for the target @p path (created directory on first use).
    std::string stage(const std::string& path)
    {
        auto it = mStaged.find(path);
        if (it != mStaged.end()) return it->second;
        const detail::OutputTarget target = detail::resolveOutputTarget(path, "cannot write '" + path + "'");
        const fs::path resolved(target.resolved);
        const fs::path dir = resolved.has_parent_path() ? resolved.parent_path() : fs::path(".");
        std::string& staging = mDirs[dir.string()];
        if (staging.empty()) {
            std::random_device rd;
            for (int attempt = 0; attempt < 16 && staging.empty(); ++attempt) {
                char name[64];
                std::snprintf(name, sizeof name, ".levelforge-run.%ld.%08x", long(::getpid()), unsigned(rd()));
                const fs::path candidate = dir / name;
                std::error_code ec;
                if (fs::create_directory(candidate, ec) && !ec) staging = candidate.string();
            }
            if (staging.empty()) throw IoError("cannot write '" + path + "': cannot create a staging directory in '" + dir.string() + "'");
            // a signal handler that ends the process (Interrupt.h) removes it
            mCleanup.push_back(std::make_unique<ExitCleanupPath>(staging));
        }
        const std::string staged = (fs::path(staging) / resolved.filename()).string();
        for (const auto& [t, s] : mStaged) {
            if (s == staged) throw UsageError("two outputs of the pipeline are the same file '" + path + "'");
        }
        mCleanup.push_back(std::make_unique<ExitCleanupPath>(staged));
        mStaged[path] = staged;
        mTargets.emplace_back(staged, target.resolved);
        return staged;
    }

    /// The staged file of @p path if a step of this frame wrote or will write it.
    const std::string* staged(const std::string& path) const
    {
        auto it = mStaged.find(path);
        return it == mStaged.end() ? nullptr : &it->second;
    }

    /// Staged path -> target, for rewriting what the steps print.
    const std::map<std::string, std::string>& staged() const { return mStaged; }

    /// Moves every staged file over its target.
    void commit()
    {
        for (const auto& [staged, target] : mTargets) {
            std::error_code ec;
            if (!fs::exists(staged, ec)) continue; // a step that chose not to write (no such case today)
            fs::rename(staged, target, ec);
            if (ec) throw IoError("cannot write '" + target + "': " + ec.message());
        }
    }

private:
    std::map<std::string, std::string> mDirs;   ///< target directory -> staging directory
    std::map<std::string, std::string> mStaged; ///< output path as given -> staged path
    std::vector<std::pair<std::string, std::string>> mTargets;
    std::vector<std::unique_ptr<ExitCleanupPath>> mCleanup; ///< staging directories and staged files
};

/// @p text with every staged path shown as the file it becomes.
std::string unstaged(std::string text, const FrameStaging& staging)
{
    for (const auto& [target, staged] : staging.staged()) text = replaceAll(text, staged, target);
    return text;
}

} // namespace

Pipeline loadPipeline(const std::string& path, const OperatorRegistry& registry)
{
    std::string text;
    {
        std::error_code ec;
        if (!fs::is_regular_file(path, ec)) throw IoError("cannot read pipeline '" + path + "': no such file");
        std::ifstream in(path, std::ios::binary);
        if (!in) throw IoError("cannot read pipeline '" + path + "'");
        text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    Json root;
    try {
        root = Json::parse(text);
    } catch (const Json::parse_error& e) {
        // e.byte is the offset of the error: report a line and column
        size_t line = 1, col = 1;
        for (size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
            if (text[i] == '\n') {
                ++line;
                col = 1;
            } else {
                ++col;
            }
        }
        invalid(path, "not valid JSON at line " + std::to_string(line) + ", column " + std::to_string(col));
    }
    if (!root.is_object() || !root.contains("steps")) invalid(path, "expected an object {\"steps\": [...]}");
    for (const auto& [key, value] : root.items()) {
        if (key != "steps" && key != "description") invalid(path, "unknown key \"" + key + "\" (steps, description)");
    }
    const Json& steps = root.at("steps");
    if (!steps.is_array() || steps.empty()) invalid(path, "\"steps\" must be a non-empty list");

    Pipeline p;
    p.path = path;
    std::set<std::string> written; // '@' names written by earlier steps
    for (size_t i = 0; i < steps.size(); ++i) {
        const Json& s = steps[i];
        std::string where = "step " + std::to_string(i + 1);
        if (!s.is_object()) invalid(path, where + ": expected an object with \"op\"");
        for (const auto& [key, value] : s.items()) {
            if (key != "op" && key != "inputs" && key != "outputs" && key != "params" && key != "name")
                invalid(path, where + ": unknown key \"" + key + "\" (op, inputs, outputs, params, name)");
        }
        if (!s.contains("op") || !s.at("op").is_string()) invalid(path, where + ": \"op\" (the operator name) is missing");
        const std::string op = s.at("op").get<std::string>();
        const OperatorSpec* spec = registry.find(op);
        if (!spec) invalid(path, where + ": unknown operator '" + op + "'");
        if (op == "run") invalid(path, where + ": a pipeline cannot run another pipeline");
        const std::string label =
            where + " (" + ((s.contains("name") && s.at("name").is_string()) ? s.at("name").get<std::string>() : op) + ")";
        const std::vector<std::string> inputs = stringList(s, "inputs", path, label);
        const std::vector<std::string> outputs = stringList(s, "outputs", path, label);
        if (inputs.size() != spec->inputs().size() || outputs.size() != spec->outputs().size()) {
            invalid(path, label + ": " + op + " takes " + std::to_string(spec->inputs().size()) + " input(s) and " +
                              std::to_string(spec->outputs().size()) + " output(s), the file gives " +
                              std::to_string(inputs.size()) + " and " + std::to_string(outputs.size()));
        }
        OperatorArgs args(*spec);
        for (size_t k = 0; k < inputs.size(); ++k) {
            if (isMemoryName(inputs[k]) && !written.count(inputs[k]))
                invalid(path, label + ": '" + inputs[k] + "' is read before any step writes it");
            args.setPort(spec->inputs()[k].name, inputs[k]);
        }
        for (size_t k = 0; k < outputs.size(); ++k) args.setPort(spec->outputs()[k].name, outputs[k]);
        if (s.contains("params")) {
            const Json& params = s.at("params");
            if (!params.is_object()) invalid(path, label + ": \"params\" must be an object {\"name\": value}");
            for (const auto& [key, value] : params.items()) {
                const std::string name = key.rfind("--", 0) == 0 ? key.substr(2) : key;
                const Param* prm = spec->findParam(name);
                if (!prm) throw UsageError(label + ": " + op + " has no parameter --" + name + " (see 'levelforge " + op + " --help')");
                try {
                    if (prm->type == ParamType::Bool) {
                        if (!value.is_boolean()) throw UsageError(prm->option() + " (" + prm->label + ") is a switch: give true or false");
                        args.setFlag(name, value.get<bool>());
                    } else {
                        args.set(name, paramText(*prm, value, label));
                    }
                } catch (const UsageError& e) {
                    const std::string msg = e.what();
                    throw UsageError(msg.rfind(label, 0) == 0 ? msg : label + ": " + msg);
                }
            }
        }
        try {
            args.checkComplete();
        } catch (const UsageError& e) {
            throw UsageError(label + ": " + e.what());
        }
        for (const std::string& o : outputs) {
            if (isMemoryName(o)) written.insert(o);
        }
        p.steps.push_back(PipelineStep{label, std::move(args)});
    }
    return p;
}

void runPipeline(const Pipeline& pipeline, OperatorArgs& run, bool quiet)
{
    using Clock = std::chrono::steady_clock;
    const std::optional<int> frame = run.frame();
    const size_t n = pipeline.steps.size();

    // Per frame: the steps with their frame tokens replaced, staged outputs, and the checks that
    // must pass before anything is computed.
    std::vector<OperatorArgs> steps;
    FrameStaging staging;
    MemoryStore memory;
    for (const PipelineStep& step : pipeline.steps) {
        OperatorArgs a = frame ? step.args.forFrame(*frame) : step.args;
        a.setMemory(&memory);
        for (const Port& port : a.spec().inputs()) {
            const std::string& in = a.input(port.name);
            if (isMemoryName(in) || isBuiltinMeshName(in)) continue;
            if (const std::string* s = staging.staged(in)) {
                a.setPort(port.name, *s); // written by an earlier step of this frame
                continue;
            }
            std::error_code ec;
            if (!fs::exists(in, ec) && a.spec().name() != "sample") // sample's inputs are coordinates
                throw IoError(step.label + ": input '" + in + "' does not exist");
        }
        // a text parameter naming a file an earlier step of this frame writes (resample
        // --reference, slice --error-against) reads the staged file too
        for (const Param& prm : a.spec().params()) {
            if (prm.type != ParamType::String || prm.repeatable || !a.isSet(prm.name)) continue;
            if (const std::string* s = staging.staged(a.getString(prm.name))) a.set(prm.name, *s);
        }
        for (const Port& port : a.spec().outputs()) {
            const std::string& out = a.output(port.name);
            if (isMemoryName(out) || detail::isNullDevice(out)) continue;
            try {
                a.setPort(port.name, staging.stage(out));
            } catch (const std::exception& e) {
                throw IoError(step.label + ": " + e.what());
            }
        }
        steps.push_back(std::move(a));
    }

    for (size_t i = 0; i < n; ++i) {
        OperatorArgs& a = steps[i];
        const std::string& label = pipeline.steps[i].label;
        std::ostringstream out;
        a.setStreams(out, run.err());
        const auto t0 = Clock::now();
        std::string error;
        std::exception_ptr failure;
        try {
            const ProgressPrefixScope prefix(ProgressPrefixScope::current() + "step " + std::to_string(i + 1) + "/" +
                                             std::to_string(n) + " " + a.spec().name() + ": ");
            a.cook();
        } catch (const std::exception& e) {
            error = e.what();
            if (error.empty()) error = "unknown failure";
            failure = std::current_exception();
        }
        const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
        // what the step printed, its error and its report, with the staged paths shown as the
        // files they become
        run.out() << unstaged(out.str(), staging);
        error = unstaged(error, staging);
        run.addStepReport(unstaged(cookReportJson(a, seconds, error), staging));
        if (!error.empty()) {
            const std::string msg = label + ": " + error;
            try {
                std::rethrow_exception(failure);
            } catch (const UsageError&) {
                throw UsageError(msg);
            } catch (const InterruptedError&) {
                throw;
            } catch (const IoError&) {
                throw IoError(msg);
            } catch (const InvalidMeshError&) {
                throw InvalidMeshError(msg);
            } catch (...) {
                throw Error(msg);
            }
        }
        if (!quiet) {
            char secs[32];
            std::snprintf(secs, sizeof secs, "%.2f s", seconds);
            run.err() << "levelforge: " << ProgressPrefixScope::current() << "step " << (i + 1) << "/" << n << " "
                      << a.spec().name() << " done (" << secs << ")" << std::endl;
        }
    }
    staging.commit();
}

} // namespace levelforge::ops
