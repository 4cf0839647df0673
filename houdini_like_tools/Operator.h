// SPDX-License-Identifier: Apache-2.0
// levelforge — Houdini-like operators, declared as data.
//
// An operator (think SOP: *VDB from Polygons*) declares in ONE place its name, a one-line help,
// its positional inputs and outputs, its parameters (Houdini parm templates: name, type,
// label, default, range, help) and its cook function. Everything else is generated from that
// declaration by OperatorRegistry: `levelforge --help`, `levelforge <op> --help`, command-line
// parsing (CLI11), type and range checks and their error messages. Operators can also be
// cooked from C++ (OperatorArgs::set + OperatorSpec::cook), which runs the same checks.
//
// Adding an operator = adding one file to houdini_like_tools/operators/:
//
//     namespace levelforge::ops {
//     namespace {
//     void cookSmooth(OperatorArgs& args) { ... args.getFloat("radius") ... }
//     }
//     LEVELFORGE_REGISTER_OPERATOR(
//         OperatorSpec("smooth", "Smooth a level set (like VDB Smooth SDF)")
//             .input("input", ".vdb file with a level set")
//             .output("output", ".vdb file to write")
//             .param(Param::floating("radius", "Filter Radius", "Filter radius, in voxels")
//                        .defaultValue(1.0).range(0.0, 16.0, Bound::Exclusive, Bound::Inclusive))
//             .param(Param::flag("quiet", "Quiet", "Print no progress"))
//             .cook(cookSmooth));
//     }
//
// Names are kebab-case and become `--name` options; inputs and outputs become positionals, in
// declaration order.
//
// Outputs are files. Before any operator cooks, OperatorArgs::cook() checks every output once,
// for all operators (OperatorArgs::checkOutputs()): an output that exists and is not a regular
// file (a directory, a device other than /dev/null, a FIFO, a socket) is refused, and so is an
// output that is the same file as one of the operator's inputs (same device and inode, links
// and hard links included) or as another output. An operator that documents in-place writing
// declares it with OperatorSpec::allowInPlace().
#pragma once

#include <levelforge/core/Exceptions.h>

#include <cstdint>
#include <functional>
#include <iosfwd>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace levelforge::ops {

/// A parameter value given on the command line (or via OperatorArgs::set) is invalid:
/// not a number, out of the declared range, not one of the choices, an unknown name, or
/// excluded by another parameter that was also given. The CLI exits with status 2.
class UsageError : public InvalidArgumentError
{
public:
    explicit UsageError(const std::string& msg) : InvalidArgumentError(msg) {}
};

enum class ParamType { Int, Float, String, Bool, Enum };
enum class Bound { Inclusive, Exclusive };

/// "int", "float", "string", "bool", "enum".
const char* toString(ParamType type);

/// One parameter: what a Houdini parm template says. Build with the factory functions and the
/// chainable setters, e.g.
///     Param::floating("voxel-size", "Voxel Size", "Voxel edge length, world units").above(0)
struct Param
{
    std::string name;                 ///< kebab-case, becomes `--name`
    ParamType type = ParamType::Float;
    std::string label;                ///< Houdini-style label ("Exterior Band Voxels")
    std::string help;                 ///< one sentence; say the units
    std::optional<std::string> defaultText; ///< default as text; nullopt: no value unless given
    std::optional<double> min, max;   ///< range of Int / Float values
    Bound minBound = Bound::Inclusive, maxBound = Bound::Inclusive;
    std::vector<std::string> choices; ///< allowed values of an Enum
    std::vector<std::string> excludes;///< parameters that may not be given together with this one
    bool repeatable = false;          ///< String only: may be given more than once; the values are joined with commas

    static Param integer(std::string name, std::string label, std::string help);
    static Param floating(std::string name, std::string label, std::string help);
    static Param string(std::string name, std::string label, std::string help);
    /// A switch (`--quiet`); false unless given.
    static Param flag(std::string name, std::string label, std::string help);
    static Param choice(std::string name, std::string label, std::string help,
                        std::vector<std::string> choices);

    Param& defaultValue(double v);
    Param& defaultValue(int v) { return defaultValue(static_cast<double>(v)); }
    Param& defaultValue(const char* v) { return defaultValue(std::string(v)); }
    Param& defaultValue(std::string v);
    Param& range(double lo, double hi, Bound loBound = Bound::Inclusive,
                 Bound hiBound = Bound::Inclusive);
    Param& above(double lo) { min = lo; minBound = Bound::Exclusive; return *this; }   ///< > lo
    Param& atLeast(double lo) { min = lo; minBound = Bound::Inclusive; return *this; } ///< >= lo
    Param& below(double hi) { max = hi; maxBound = Bound::Exclusive; return *this; }   ///< < hi
    Param& atMost(double hi) { max = hi; maxBound = Bound::Inclusive; return *this; }  ///< <= hi
    Param& exclusiveWith(std::string otherName);
    /// A String parameter that may be given more than once (`--attribute Cd --attribute N`):
    /// the operator sees the values joined with commas ("Cd,N"), as if given once that way.
    Param& repeat() { repeatable = true; return *this; }

    /// "--name".
    std::string option() const { return "--" + name; }
    /// The declared range in words, e.g. "(0, 1000]", "> 0", ">= 1"; empty when unbounded.
    std::string rangeText() const;
    /// Placeholder shown in help: INT, FLOAT, TEXT, or {a|b|c}.
    std::string metavar() const;
};

/// A positional input or output (a file path, or a name such as builtin:torus-knot).
struct Port
{
    std::string name;
    std::string help;
};

using ParamValue = std::variant<int64_t, double, std::string, bool>;

/// Converts `text` to a value of `param`'s type and checks the range and choices. Floats must
/// be finite. Throws UsageError naming the parameter, e.g.
/// "invalid value '0' for --voxel-size (Voxel Size): must be > 0".
ParamValue parseParamValue(const Param& param, const std::string& text);

class OperatorArgs;
class MemoryStore; // OperatorIO.h
using CookFunction = std::function<void(OperatorArgs&)>;

/// The whole declaration of one operator.
class OperatorSpec
{
public:
    OperatorSpec() = default;
    OperatorSpec(std::string name, std::string help);

    OperatorSpec& description(std::string text); ///< optional paragraph shown in --help
    OperatorSpec& input(std::string name, std::string help);
    OperatorSpec& output(std::string name, std::string help);
    OperatorSpec& param(Param p);
    /// Declares several parameters at once, e.g. a shared group (GridParams.h).
    OperatorSpec& params(const std::vector<Param>& ps);
    OperatorSpec& example(std::string commandLine); ///< shown in --help
    OperatorSpec& cook(CookFunction fn);
    /// Optional: checks the arguments once before anything is cooked (with --frames: once, with
    /// the first frame's tokens replaced, not once per frame), e.g. `run` validates its
    /// pipeline file. Throws like a cook.
    OperatorSpec& precheck(CookFunction fn);
    /// Allows an output to be the same file as an input (the operator reads its inputs
    /// completely before it writes, and says so in its help). Off by default.
    OperatorSpec& allowInPlace(bool on = true);

    const std::string& name() const { return mName; }
    const std::string& help() const { return mHelp; }
    const std::string& descriptionText() const { return mDescription; }
    const std::vector<Port>& inputs() const { return mInputs; }
    const std::vector<Port>& outputs() const { return mOutputs; }
    const std::vector<Param>& params() const { return mParams; }
    const std::vector<std::string>& examples() const { return mExamples; }
    const CookFunction& cookFunction() const { return mCook; }
    const CookFunction& precheckFunction() const { return mPrecheck; }
    /// True if allowInPlace() was declared.
    bool inPlaceAllowed() const { return mInPlace; }

    /// nullptr if there is no such parameter.
    const Param* findParam(const std::string& name) const;
    /// Throws std::logic_error describing the first inconsistency in the declaration (duplicate
    /// or malformed names, a default outside its range, an unknown exclusion, no cook function).
    void checkDeclaration() const;
    /// Generated `levelforge <op> --help` text.
    std::string helpText(const std::string& program = "levelforge") const;

private:
    std::string mName, mHelp, mDescription;
    std::vector<Port> mInputs, mOutputs;
    std::vector<Param> mParams;
    std::vector<std::string> mExamples;
    CookFunction mCook, mPrecheck;
    bool mInPlace = false;
};

/// Parameter values and positional paths for one cook, plus the streams to report on.
/// Values not given fall back to the declared defaults.
class OperatorArgs
{
public:
    /// Streams default to std::cout / std::cerr.
    explicit OperatorArgs(const OperatorSpec& spec);
    OperatorArgs(const OperatorSpec& spec, std::ostream& out, std::ostream& err);

    const OperatorSpec& spec() const { return *mSpec; }

    /// Sets a parameter from text (parsed and range-checked: UsageError on failure).
    OperatorArgs& set(const std::string& name, const std::string& text);
    /// Sets a flag (Bool parameter) on or off.
    OperatorArgs& setFlag(const std::string& name, bool on = true);
    /// Sets a positional input or output by its declared name.
    OperatorArgs& setPort(const std::string& name, const std::string& value);

    /// True if the parameter was given explicitly (not just defaulted).
    bool isSet(const std::string& name) const;
    /// True if the parameter has a value (given, or declared with a default); false for a name the
    /// operator does not declare (so helpers shared by several operators can ask first).
    bool has(const std::string& name) const;

    int64_t getInt(const std::string& name) const;
    double getFloat(const std::string& name) const;
    const std::string& getString(const std::string& name) const; ///< String and Enum
    bool getBool(const std::string& name) const;
    /// Positional input / output by declared name.
    const std::string& input(const std::string& name) const;
    const std::string& output(const std::string& name) const;

    /// Throws UsageError if a declared positional is missing or two mutually exclusive
    /// parameters were both given.
    void checkComplete() const;
    /// Checks the outputs before any work (see the file comment), each output path as given:
    /// @throws IoError "cannot write '<out>': '<out>' is a FIFO (named pipe), not a regular
    ///         file; ..." for an existing output that is neither a regular file nor /dev/null
    ///         (the library's output rule, detail::resolveOutputTarget());
    /// @throws UsageError "output '<out>' is the same file as the input; choose another name"
    ///         (with several inputs: "... as the input <name> ('<path>'); ..."), unless the
    ///         operator allowInPlace(); "outputs <a> and <b> are the same file '<out>'; ...".
    /// Inputs that are not existing files (builtin:sphere, coordinates) never match. /dev/null
    /// may be given as any number of outputs.
    void checkOutputs() const;
    /// checkComplete(), checkOutputs(), then runs the operator's cook function.
    void cook();

    std::ostream& out() const { return *mOut; }
    std::ostream& err() const { return *mErr; }

    /// Redirects what the cook prints (a frame cooked in parallel prints into a buffer).
    OperatorArgs& setStreams(std::ostream& out, std::ostream& err) { mOut = &out; mErr = &err; return *this; }
    /// The frame being cooked (`--frames`, `levelforge run --frames`); nullopt without frames.
    std::optional<int> frame() const { return mFrame; }
    OperatorArgs& setFrame(std::optional<int> frame) { mFrame = frame; return *this; }
    /// A copy for one frame: every input, output and given text parameter with its frame tokens
    /// ($F, $F4, %04d; FrameRange.h) replaced by @p frame, and frame() set.
    OperatorArgs forFrame(int frame) const;

    /// Reports of nested cooks (the steps of `levelforge run`), each one JSON object as text,
    /// embedded by --report-json under "steps".
    void addStepReport(std::string json) { mStepReports.push_back(std::move(json)); }
    const std::vector<std::string>& stepReports() const { return mStepReports; }

    /// The in-memory slots ("@name") of the pipeline this cook is a step of; null outside
    /// `levelforge run` (OperatorIO.h reads and writes through it).
    MemoryStore* memory() const { return mMemory; }
    OperatorArgs& setMemory(MemoryStore* store) { mMemory = store; return *this; }

    /// Records a statistic of this cook under @p key (replacing an earlier value), for
    /// `--report-json`: the numbers the operator prints (voxel counts, seconds, ...).
    void stat(const std::string& key, ParamValue value);
    void stat(const std::string& key, const std::string& value) { stat(key, ParamValue(value)); }
    void stat(const std::string& key, const char* value) { stat(key, ParamValue(std::string(value))); }
    void stat(const std::string& key, double value) { stat(key, ParamValue(value)); }
    void stat(const std::string& key, bool value) { stat(key, ParamValue(value)); }
    void stat(const std::string& key, int value) { stat(key, ParamValue(int64_t(value))); }
    void stat(const std::string& key, unsigned value) { stat(key, ParamValue(int64_t(value))); }
    void stat(const std::string& key, long value) { stat(key, ParamValue(int64_t(value))); }
    void stat(const std::string& key, unsigned long value) { stat(key, ParamValue(int64_t(value))); }
    void stat(const std::string& key, long long value) { stat(key, ParamValue(int64_t(value))); }
    void stat(const std::string& key, unsigned long long value) { stat(key, ParamValue(int64_t(value))); }
    /// The statistics recorded by the cook, in the order they were first recorded.
    const std::vector<std::pair<std::string, ParamValue>>& stats() const { return mStats; }
    /// The parameter values in effect (given or defaulted), by name, for reports.
    std::map<std::string, ParamValue> effectiveValues() const;
    /// The positional inputs and outputs as given, by declared name.
    const std::map<std::string, std::string>& ports() const { return mPorts; }

private:
    const ParamValue& value(const std::string& name, ParamType expected) const;

    const OperatorSpec* mSpec;
    std::ostream* mOut;
    std::ostream* mErr;
    std::map<std::string, ParamValue> mValues;   ///< given explicitly
    std::map<std::string, ParamValue> mDefaults; ///< parsed declared defaults
    std::map<std::string, std::string> mPorts;
    MemoryStore* mMemory = nullptr;
    std::optional<int> mFrame;
    std::vector<std::pair<std::string, ParamValue>> mStats;
    std::vector<std::string> mStepReports;
};

/// Adds `spec` to OperatorRegistry::global() during static initialisation (or, while a
/// RegistrarCapture is alive, to its registry).
struct OperatorRegistrar
{
    explicit OperatorRegistrar(OperatorSpec spec);
};

class OperatorRegistry; // OperatorRegistry.h

/// @brief While alive, OperatorRegistrar adds to @p target instead of the global registry and
///        never throws: the first declaration error is kept (error()). The plugin loader holds one
///        around dlopen(), so that a plugin's static LEVELFORGE_REGISTER_OPERATOR declarations go
///        through the same version check and name check as its entry point's (Plugins.h).
///        One at a time, on the main thread.
class RegistrarCapture
{
public:
    explicit RegistrarCapture(OperatorRegistry& target);
    ~RegistrarCapture();
    RegistrarCapture(const RegistrarCapture&) = delete;
    RegistrarCapture& operator=(const RegistrarCapture&) = delete;
    /// The first error of a captured registration ("" if none).
    const std::string& error() const { return mError; }

private:
    friend struct OperatorRegistrar;
    OperatorRegistry& mTarget;
    std::string mError;
    RegistrarCapture* mSaved;
};

#define LEVELFORGE_OPS_CONCAT_INNER(a, b) a##b
#define LEVELFORGE_OPS_CONCAT(a, b) LEVELFORGE_OPS_CONCAT_INNER(a, b)
/// Registers an operator declaration; use once per operator file, at namespace scope.
#define LEVELFORGE_REGISTER_OPERATOR(...)                                                         \
    static const ::levelforge::ops::OperatorRegistrar LEVELFORGE_OPS_CONCAT(                      \
        levelforgeOperatorRegistrar_, __LINE__){__VA_ARGS__}

} // namespace levelforge::ops
