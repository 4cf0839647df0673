// SPDX-License-Identifier: Apache-2.0
// levelforge — operator declarations and argument values (see Operator.h).
#include "Operator.h"

#include "FrameRange.h"
#include "FrameRunner.h"

#include "OperatorRegistry.h"

// The library's output rule (detail::resolveOutputTarget). Included by a relative path:
// levelforge_ops does not have src/ on its include path.
#include "detail/AtomicFile.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include <sys/stat.h>

namespace levelforge::ops {

namespace operator_internal {

/// Shortest text that reads back as the same double ("0.5", "256", "1e-05").
std::string formatNumber(double v)
{
    char buf[64];
    if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 1e15) {
        std::snprintf(buf, sizeof(buf), "%.0f", v);
        return buf;
    }
    for (int precision = 1; precision <= 17; ++precision) {
        std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
        if (std::strtod(buf, nullptr) == v) break;
    }
    return buf;
}

bool validName(const std::string& name)
{
    if (name.empty() || !(name[0] >= 'a' && name[0] <= 'z')) return false;
    for (char c : name) {
        if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-')) return false;
    }
    return name.back() != '-';
}

/// True if @p input names an existing file that is the same file as the output @p output
/// (resolved: its link-resolved target): same device and inode when both exist, else the same
/// canonical path.
bool sameFile(const std::string& input, const detail::OutputTarget& output)
{
    struct stat in {};
    if (::stat(input.c_str(), &in) != 0) return false; // builtin:..., a number, a missing file
    struct stat out {};
    if (::stat(output.resolved.c_str(), &out) == 0) {
        return in.st_dev == out.st_dev && in.st_ino == out.st_ino;
    }
    std::error_code ec1, ec2;
    const std::filesystem::path a = std::filesystem::weakly_canonical(input, ec1);
    const std::filesystem::path b = std::filesystem::weakly_canonical(output.resolved, ec2);
    return !ec1 && !ec2 && a == b;
}

std::string describe(const Param& p)
{
    return p.option() + (p.label.empty() ? "" : " (" + p.label + ")");
}

[[noreturn]] void invalid(const Param& p, const std::string& text, const std::string& why)
{
    throw UsageError("invalid value '" + text + "' for " + describe(p) + ": " + why);
}

std::string trim(const std::string& s)
{
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    const auto e = s.find_last_not_of(" \t\r\n");
    return s.substr(b, e - b + 1);
}

void checkRange(const Param& p, const std::string& text, double v)
{
    const bool lowOk = !p.min || (p.minBound == Bound::Inclusive ? v >= *p.min : v > *p.min);
    const bool highOk = !p.max || (p.maxBound == Bound::Inclusive ? v <= *p.max : v < *p.max);
    if (!lowOk || !highOk) {
        invalid(p, text, std::string(p.min && p.max ? "must be in " : "must be ") + p.rangeText());
    }
}

} // namespace operator_internal

using namespace operator_internal;

// ------------------------------------------------------------------------------------ Param

const char* toString(ParamType type)
{
    switch (type) {
    case ParamType::Int: return "int";
    case ParamType::Float: return "float";
    case ParamType::String: return "string";
    case ParamType::Bool: return "bool";
    case ParamType::Enum: return "enum";
    }
    return "?";
}

static Param makeParam(std::string name, ParamType type, std::string label, std::string help)
{
    Param p;
    p.name = std::move(name);
    p.type = type;
    p.label = std::move(label);
    p.help = std::move(help);
    return p;
}

Param Param::integer(std::string name, std::string label, std::string help)
{
    return makeParam(std::move(name), ParamType::Int, std::move(label), std::move(help));
}

Param Param::floating(std::string name, std::string label, std::string help)
{
    return makeParam(std::move(name), ParamType::Float, std::move(label), std::move(help));
}

Param Param::string(std::string name, std::string label, std::string help)
{
    return makeParam(std::move(name), ParamType::String, std::move(label), std::move(help));
}

Param Param::flag(std::string name, std::string label, std::string help)
{
    Param p = makeParam(std::move(name), ParamType::Bool, std::move(label), std::move(help));
    p.defaultText = "false";
    return p;
}

Param Param::choice(std::string name, std::string label, std::string help,
                    std::vector<std::string> choices)
{
    Param p = makeParam(std::move(name), ParamType::Enum, std::move(label), std::move(help));
    p.choices = std::move(choices);
    return p;
}

Param& Param::defaultValue(double v)
{
    defaultText = formatNumber(v);
    return *this;
}

Param& Param::defaultValue(std::string v)
{
    defaultText = std::move(v);
    return *this;
}

Param& Param::range(double lo, double hi, Bound loBound, Bound hiBound)
{
    min = lo;
    max = hi;
    minBound = loBound;
    maxBound = hiBound;
    return *this;
}

Param& Param::exclusiveWith(std::string otherName)
{
    excludes.push_back(std::move(otherName));
    return *this;
}

std::string Param::rangeText() const
{
    if (min && max) {
        return std::string(minBound == Bound::Inclusive ? "[" : "(") + formatNumber(*min) + ", " +
               formatNumber(*max) + (maxBound == Bound::Inclusive ? "]" : ")");
    }
    if (min) return std::string(minBound == Bound::Inclusive ? ">= " : "> ") + formatNumber(*min);
    if (max) return std::string(maxBound == Bound::Inclusive ? "<= " : "< ") + formatNumber(*max);
    return {};
}

std::string Param::metavar() const
{
    switch (type) {
    case ParamType::Int: return "INT";
    case ParamType::Float: return "FLOAT";
    case ParamType::String: return "TEXT";
    case ParamType::Bool: return "";
    case ParamType::Enum: {
        std::string s = "{";
        for (size_t i = 0; i < choices.size(); ++i) s += (i ? "|" : "") + choices[i];
        return s + "}";
    }
    }
    return {};
}

ParamValue parseParamValue(const Param& p, const std::string& rawText)
{
    const std::string text = trim(rawText);
    switch (p.type) {
    case ParamType::Int: {
        if (text.empty()) invalid(p, rawText, "expected an integer");
        errno = 0;
        char* end = nullptr;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        if (end == text.c_str() || *end != '\0') invalid(p, rawText, "expected an integer");
        if (errno == ERANGE) invalid(p, rawText, "must be " + (p.rangeText().empty()
                                                                   ? std::string("smaller")
                                                                   : p.rangeText()));
        checkRange(p, rawText, static_cast<double>(v));
        return static_cast<int64_t>(v);
    }
    case ParamType::Float: {
        if (text.empty()) invalid(p, rawText, "expected a number");
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0') invalid(p, rawText, "expected a number");
        if (!std::isfinite(v)) {
            invalid(p, rawText, "must be a finite number" +
                                    (p.rangeText().empty() ? "" : " " + p.rangeText()));
        }
        checkRange(p, rawText, v);
        return v;
    }
    case ParamType::String: return rawText;
    case ParamType::Bool: {
        std::string t = text;
        std::transform(t.begin(), t.end(), t.begin(), [](unsigned char c) { return std::tolower(c); });
        if (t == "1" || t == "true" || t == "on" || t == "yes") return true;
        if (t == "0" || t == "false" || t == "off" || t == "no") return false;
        invalid(p, rawText, "expected true or false");
    }
    case ParamType::Enum: {
        if (std::find(p.choices.begin(), p.choices.end(), text) != p.choices.end()) return text;
        std::string list;
        for (size_t i = 0; i < p.choices.size(); ++i) list += (i ? ", " : "") + p.choices[i];
        invalid(p, rawText, "must be one of: " + list);
    }
    }
    invalid(p, rawText, "unsupported parameter type");
}

// ------------------------------------------------------------------------------- OperatorSpec

OperatorSpec::OperatorSpec(std::string name, std::string help)
    : mName(std::move(name)), mHelp(std::move(help))
{
}

OperatorSpec& OperatorSpec::description(std::string text)
{
    mDescription = std::move(text);
    return *this;
}

OperatorSpec& OperatorSpec::input(std::string name, std::string help)
{
    mInputs.push_back({std::move(name), std::move(help)});
    return *this;
}

OperatorSpec& OperatorSpec::output(std::string name, std::string help)
{
    mOutputs.push_back({std::move(name), std::move(help)});
    return *this;
}

OperatorSpec& OperatorSpec::param(Param p)
{
    mParams.push_back(std::move(p));
    return *this;
}

OperatorSpec& OperatorSpec::params(const std::vector<Param>& ps)
{
    mParams.insert(mParams.end(), ps.begin(), ps.end());
    return *this;
}

OperatorSpec& OperatorSpec::example(std::string commandLine)
{
    mExamples.push_back(std::move(commandLine));
    return *this;
}

OperatorSpec& OperatorSpec::cook(CookFunction fn)
{
    mCook = std::move(fn);
    return *this;
}

OperatorSpec& OperatorSpec::precheck(CookFunction fn)
{
    mPrecheck = std::move(fn);
    return *this;
}

OperatorSpec& OperatorSpec::allowInPlace(bool on)
{
    mInPlace = on;
    return *this;
}

const Param* OperatorSpec::findParam(const std::string& name) const
{
    for (const Param& p : mParams) {
        if (p.name == name) return &p;
    }
    return nullptr;
}

void OperatorSpec::checkDeclaration() const
{
    auto bad = [&](const std::string& why) {
        throw std::logic_error("operator '" + mName + "' is declared wrongly: " + why);
    };
    if (!validName(mName)) bad("the name must be kebab-case");
    if (mHelp.empty()) bad("no help text");
    if (!mCook) bad("no cook function");
    // "help" and the common options every operator has (FrameRunner.h) are reserved
    std::set<std::string> names{"help",       "frames",     "jobs",  "stop-on-error", "report-json",
                                "task-index", "task-count", "plugin"};
    for (const Port& port : mInputs) {
        if (!validName(port.name)) bad("input '" + port.name + "' is not kebab-case");
        if (!names.insert(port.name).second) bad("duplicate name '" + port.name + "'");
    }
    for (const Port& port : mOutputs) {
        if (!validName(port.name)) bad("output '" + port.name + "' is not kebab-case");
        if (!names.insert(port.name).second) bad("duplicate name '" + port.name + "'");
    }
    for (const Param& p : mParams) {
        if (!validName(p.name)) bad("parameter '" + p.name + "' is not kebab-case");
        if (!names.insert(p.name).second) bad("duplicate name '" + p.name + "'");
        if (p.help.empty()) bad("parameter '" + p.name + "' has no help");
        if (p.label.empty()) bad("parameter '" + p.name + "' has no label");
        if ((p.min || p.max) && p.type != ParamType::Int && p.type != ParamType::Float) {
            bad("parameter '" + p.name + "' has a range but is not numeric");
        }
        if (p.type == ParamType::Enum && p.choices.empty()) {
            bad("enum parameter '" + p.name + "' has no choices");
        }
        if (p.repeatable && p.type != ParamType::String) {
            bad("parameter '" + p.name + "' is repeatable but not a string");
        }
        if (p.defaultText) {
            try {
                parseParamValue(p, *p.defaultText);
            } catch (const UsageError& e) {
                bad(std::string("default of '") + p.name + "': " + e.what());
            }
        }
        for (const std::string& other : p.excludes) {
            if (!findParam(other) || other == p.name) {
                bad("parameter '" + p.name + "' excludes unknown parameter '" + other + "'");
            }
        }
    }
}

std::string OperatorSpec::helpText(const std::string& program) const
{
    std::ostringstream os;
    os << program << " " << mName << " - " << mHelp << "\n\n";
    os << "Usage: " << program << " " << mName;
    for (const Port& port : mInputs) os << " <" << port.name << ">";
    for (const Port& port : mOutputs) os << " <" << port.name << ">";
    os << " [options]\n";
    if (!mDescription.empty()) os << "\n" << mDescription << "\n";

    // Two columns; the right one is word-wrapped to keep lines under ~100 characters.
    auto column = [&os](const std::string& left, const std::string& right) {
        const size_t width = 28, total = 100;
        os << "  " << left;
        size_t col = 2 + left.size();
        if (col + 2 > width) {
            os << "\n";
            col = 0;
        }
        os << std::string(width - col, ' ');
        col = width;
        std::istringstream words(right);
        bool first = true;
        for (std::string word; words >> word;) {
            if (!first && col + 1 + word.size() > total) {
                os << "\n" << std::string(width, ' ');
                col = width;
            } else if (!first) {
                os << ' ';
                ++col;
            }
            os << word;
            col += word.size();
            first = false;
        }
        os << "\n";
    };
    if (!mInputs.empty()) {
        os << "\nInputs:\n";
        for (const Port& port : mInputs) column(port.name, port.help);
    }
    if (!mOutputs.empty()) {
        os << "\nOutputs:\n";
        for (const Port& port : mOutputs) column(port.name, port.help);
    }
    os << "\nParameters:\n";
    for (const Param& p : mParams) {
        std::string left = p.option();
        if (p.type != ParamType::Bool) left += " " + p.metavar();
        std::string right = p.label + ": " + p.help;
        if (!right.empty() && right.back() != '.') right += ".";
        std::vector<std::string> notes;
        if (p.type != ParamType::Bool && p.defaultText && !p.defaultText->empty()) notes.push_back("default " + *p.defaultText);
        if (!p.rangeText().empty()) notes.push_back("range " + p.rangeText());
        for (const std::string& other : p.excludes) notes.push_back("not with --" + other);
        if (p.repeatable) notes.push_back("repeatable");
        if (!notes.empty()) {
            right += " [";
            for (size_t i = 0; i < notes.size(); ++i) right += (i ? "; " : "") + notes[i];
            right += "]";
        }
        column(left, right);
    }
    column("-h, --help", "Print this help and exit.");
    os << commonOptionsHelp();
    if (!mExamples.empty()) {
        os << "\nExamples:\n";
        for (const std::string& ex : mExamples) os << "  " << ex << "\n";
    }
    return os.str();
}

// ------------------------------------------------------------------------------- OperatorArgs

OperatorArgs::OperatorArgs(const OperatorSpec& spec) : OperatorArgs(spec, std::cout, std::cerr) {}

OperatorArgs::OperatorArgs(const OperatorSpec& spec, std::ostream& out, std::ostream& err)
    : mSpec(&spec), mOut(&out), mErr(&err)
{
    for (const Param& p : spec.params()) {
        if (p.defaultText) mDefaults[p.name] = parseParamValue(p, *p.defaultText);
    }
}

static const Param& requireParam(const OperatorSpec& spec, const std::string& name)
{
    const Param* p = spec.findParam(name);
    if (!p) throw UsageError("operator '" + spec.name() + "' has no parameter --" + name);
    return *p;
}

OperatorArgs& OperatorArgs::set(const std::string& name, const std::string& text)
{
    mValues[name] = parseParamValue(requireParam(*mSpec, name), text);
    return *this;
}

OperatorArgs& OperatorArgs::setFlag(const std::string& name, bool on)
{
    const Param& p = requireParam(*mSpec, name);
    if (p.type != ParamType::Bool) throw UsageError(p.option() + " is not a switch");
    mValues[name] = on;
    return *this;
}

OperatorArgs& OperatorArgs::setPort(const std::string& name, const std::string& value)
{
    for (const auto* ports : {&mSpec->inputs(), &mSpec->outputs()}) {
        for (const Port& port : *ports) {
            if (port.name == name) {
                mPorts[name] = value;
                return *this;
            }
        }
    }
    throw UsageError("operator '" + mSpec->name() + "' has no input or output '" + name + "'");
}

bool OperatorArgs::isSet(const std::string& name) const
{
    requireParam(*mSpec, name);
    return mValues.count(name) != 0;
}

bool OperatorArgs::has(const std::string& name) const
{
    // Helpers shared by several operators ask before they read; an undeclared name has no value.
    if (!mSpec->findParam(name)) return false;
    return isSet(name) || mDefaults.count(name) != 0;
}

const ParamValue& OperatorArgs::value(const std::string& name, ParamType expected) const
{
    const Param& p = requireParam(*mSpec, name);
    const bool typeOk = p.type == expected ||
                        (expected == ParamType::String && p.type == ParamType::Enum);
    if (!typeOk) {
        throw std::logic_error("parameter --" + name + " of '" + mSpec->name() + "' is " +
                               toString(p.type) + ", read as " + toString(expected));
    }
    auto it = mValues.find(name);
    if (it != mValues.end()) return it->second;
    it = mDefaults.find(name);
    if (it != mDefaults.end()) return it->second;
    throw UsageError("missing value for " + describe(p));
}

int64_t OperatorArgs::getInt(const std::string& name) const
{
    return std::get<int64_t>(value(name, ParamType::Int));
}

double OperatorArgs::getFloat(const std::string& name) const
{
    return std::get<double>(value(name, ParamType::Float));
}

const std::string& OperatorArgs::getString(const std::string& name) const
{
    return std::get<std::string>(value(name, ParamType::String));
}

bool OperatorArgs::getBool(const std::string& name) const
{
    return std::get<bool>(value(name, ParamType::Bool));
}

const std::string& OperatorArgs::input(const std::string& name) const
{
    auto it = mPorts.find(name);
    if (it == mPorts.end()) throw UsageError("missing input <" + name + ">");
    return it->second;
}

const std::string& OperatorArgs::output(const std::string& name) const
{
    auto it = mPorts.find(name);
    if (it == mPorts.end()) throw UsageError("missing output <" + name + ">");
    return it->second;
}

void OperatorArgs::checkComplete() const
{
    for (const auto* ports : {&mSpec->inputs(), &mSpec->outputs()}) {
        for (const Port& port : *ports) {
            auto it = mPorts.find(port.name);
            if (it == mPorts.end() || it->second.empty()) {
                throw UsageError("missing <" + port.name + "> (" + port.help + ")");
            }
        }
    }
    for (const Param& p : mSpec->params()) {
        if (!mValues.count(p.name)) continue;
        for (const std::string& other : p.excludes) {
            if (mValues.count(other)) {
                throw UsageError("give either " + p.option() + " or --" + other + ", not both");
            }
        }
    }
}

void OperatorArgs::checkOutputs() const
{
    std::vector<std::pair<const Port*, detail::OutputTarget>> checked;
    for (const Port& port : mSpec->outputs()) {
        auto it = mPorts.find(port.name);
        if (it == mPorts.end() || it->second.empty()) continue; // checkComplete() reports it
        const std::string& path = it->second;
        if (!path.empty() && path[0] == '@') continue; // an in-memory pipeline slot (OperatorIO.h)
        detail::OutputTarget target =
            detail::resolveOutputTarget(path, "cannot write '" + path + "'");
        if (target.discard) continue; // /dev/null: written through, never replaced
        if (!mSpec->inPlaceAllowed()) {
            for (const Port& in : mSpec->inputs()) {
                auto inIt = mPorts.find(in.name);
                if (inIt == mPorts.end() || !sameFile(inIt->second, target)) continue;
                const std::string which = mSpec->inputs().size() == 1
                                              ? std::string("the input")
                                              : "the input <" + in.name + "> ('" +
                                                    inIt->second + "')";
                throw UsageError("output '" + path + "' is the same file as " + which +
                                 "; choose another name");
            }
        }
        for (const auto& [other, otherTarget] : checked) {
            const bool same = otherTarget.resolved == target.resolved ||
                              sameFile(otherTarget.resolved, target);
            if (same) {
                throw UsageError("outputs <" + other->name + "> and <" + port.name +
                                 "> are the same file '" + path + "'; choose another name");
            }
        }
        checked.emplace_back(&port, std::move(target));
    }
}

void OperatorArgs::stat(const std::string& key, ParamValue value)
{
    for (auto& [k, v] : mStats) {
        if (k == key) {
            v = std::move(value);
            return;
        }
    }
    mStats.emplace_back(key, std::move(value));
}

OperatorArgs OperatorArgs::forFrame(int frame) const
{
    OperatorArgs a = *this;
    for (auto& [name, path] : a.mPorts) path = substituteFrame(path, frame);
    for (auto& [name, value] : a.mValues) {
        if (auto* text = std::get_if<std::string>(&value)) *text = substituteFrame(*text, frame);
    }
    a.mFrame = frame;
    return a;
}

std::map<std::string, ParamValue> OperatorArgs::effectiveValues() const
{
    std::map<std::string, ParamValue> values = mDefaults;
    for (const auto& [k, v] : mValues) values[k] = v;
    return values;
}

void OperatorArgs::cook()
{
    checkComplete();
    checkOutputs();
    mSpec->cookFunction()(*this);
}

namespace {
RegistrarCapture* gCapture = nullptr; // the RegistrarCapture alive, if any
} // namespace

OperatorRegistrar::OperatorRegistrar(OperatorSpec spec)
{
    if (RegistrarCapture* capture = gCapture) {
        try {
            capture->mTarget.add(std::move(spec));
        } catch (const std::exception& e) {
            if (capture->mError.empty()) capture->mError = e.what();
        }
        return;
    }
    OperatorRegistry::global().add(std::move(spec));
}

RegistrarCapture::RegistrarCapture(OperatorRegistry& target) : mTarget(target), mSaved(gCapture) { gCapture = this; }
RegistrarCapture::~RegistrarCapture() { gCapture = mSaved; }

} // namespace levelforge::ops
