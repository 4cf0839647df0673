// SPDX-License-Identifier: Apache-2.0
// levelforge operators — frame loops and JSON reports (see FrameRunner.h).
#include "FrameRunner.h"

#include "Interrupt.h"
#include "OperatorRegistry.h"

#include "detail/AtomicFile.h"
#include "detail/MessageText.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h> // generatorString()

#include <nlohmann/json.hpp>
#include <tbb/info.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <ostream>
#include <sstream>
#include <thread>

#include <unistd.h>

namespace levelforge::ops {
namespace {

using Clock = std::chrono::steady_clock;

std::string oneLine(std::string msg)
{
    for (char& c : msg) {
        if (c == '\n' || c == '\r') c = ' ';
    }
    while (!msg.empty() && msg.back() == ' ') msg.pop_back();
    return msg.empty() ? std::string("unknown error") : msg;
}

/// What one cook gave: the exit code and the one-line error ("" when it worked).
struct Outcome
{
    int code = kExitOk;
    std::string error;
    double seconds = 0;
};

/// Cooks and turns every exception into an exit code and a message (as runCli does).
Outcome cookCaught(OperatorArgs& args)
{
    Outcome o;
    const auto t0 = Clock::now();
    try {
        args.cook();
    } catch (const UsageError& e) {
        o = {kExitUsage, e.what()};
    } catch (const InterruptedError& e) {
        o = {kExitInterrupted, e.what()};
    } catch (const std::bad_alloc&) {
        o = {kExitFailure, "out of memory"};
    } catch (const std::exception& e) {
        o = {kExitFailure, message_internal::cutDependencyMessage(e.what(), 2000)};
    } catch (...) {
        o = {kExitFailure, "unknown failure"};
    }
    o.error = o.code == kExitOk ? std::string() : oneLine(o.error);
    o.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    return o;
}

nlohmann::json toJson(const ParamValue& v)
{
    if (const auto* i = std::get_if<int64_t>(&v)) return *i;
    if (const auto* d = std::get_if<double>(&v)) return *d;
    if (const auto* b = std::get_if<bool>(&v)) return *b;
    return std::get<std::string>(v);
}

nlohmann::json reportObject(const OperatorArgs& args, double seconds, const std::string& error)
{
    nlohmann::json j;
    j["operator"] = args.spec().name();
    if (args.frame()) j["frame"] = *args.frame();
    nlohmann::json inputs = nlohmann::json::object(), outputs = nlohmann::json::object();
    for (const Port& p : args.spec().inputs())
        if (args.ports().count(p.name)) inputs[p.name] = args.ports().at(p.name);
    for (const Port& p : args.spec().outputs())
        if (args.ports().count(p.name)) outputs[p.name] = args.ports().at(p.name);
    j["inputs"] = inputs;
    j["outputs"] = outputs;
    nlohmann::json params = nlohmann::json::object();
    for (const auto& [name, value] : args.effectiveValues()) params[name] = toJson(value);
    j["params"] = params;
    nlohmann::json stats = nlohmann::json::object();
    for (const auto& [name, value] : args.stats()) stats[name] = toJson(value);
    j["stats"] = stats;
    if (!args.stepReports().empty()) {
        nlohmann::json steps = nlohmann::json::array();
        for (const std::string& s : args.stepReports()) steps.push_back(nlohmann::json::parse(s));
        j["steps"] = steps;
    }
    j["seconds"] = seconds;
    j["status"] = error.empty() ? "ok" : "failed";
    if (!error.empty()) j["error"] = error;
    return j;
}

std::string durationText(double seconds)
{
    char buf[48];
    if (seconds < 90) std::snprintf(buf, sizeof buf, "%.0f s", seconds);
    else if (seconds < 5400) std::snprintf(buf, sizeof buf, "%.0f min", seconds / 60);
    else std::snprintf(buf, sizeof buf, "%.1f h", seconds / 3600);
    return buf;
}

/// With frames, an output file without a frame token would be written by every frame.
void checkFrameOutputs(const OperatorArgs& args)
{
    for (const Port& p : args.spec().outputs()) {
        if (!args.ports().count(p.name)) continue;
        const std::string& path = args.ports().at(p.name);
        if (path.empty() || path[0] == '@' || path == "/dev/null" || hasFrameToken(path)) continue;
        throw UsageError("with --frames, the output <" + p.name + "> '" + path +
                         "' needs a frame token ($F, $F4, %04d): every frame would write the same file");
    }
}

/// JSON text of @p j; bytes of strings that are not UTF-8 (a Latin-1 file name, a message quoting
/// a corrupt file) become U+FFFD instead of failing the report.
std::string jsonText(const nlohmann::json& j, int indent)
{
    return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

int writeReport(const CommonOptions& common, const nlohmann::json& report, std::ostream& err)
{
    if (common.reportJson.empty()) return kExitOk;
    // After Ctrl-C nothing more is written (Interrupt.h), and the one error line is "interrupted".
    if (interruptRequested()) return kExitOk;
    try {
        detail::writeTextAtomic(common.reportJson, jsonText(report, 2) + "\n");
    } catch (const std::exception& e) {
        err << "levelforge: error: " << oneLine(e.what()) << std::endl;
        return kExitFailure;
    }
    return kExitOk;
}

} // namespace

const std::vector<std::string>& commonOptionNames()
{
    static const std::vector<std::string> names{"frames",      "jobs",       "stop-on-error", "report-json",
                                                "task-index",  "task-count", "plugin"};
    return names;
}

std::string commonOptionsHelp()
{
    return "\nCommon options:\n"
           "  --frames A-B[:step]         Frame Range: cook once per frame, replacing $F, $F4 and %04d in\n"
           "                              paths and text parameters by the frame number.\n"
           "  --jobs INT                  Jobs: frames cooked at the same time [default 1].\n"
           "  --stop-on-error             Stop at the first frame that fails (default: report it, go on).\n"
           "  --report-json FILE          Write the statistics of the cook (every frame, every step) as JSON.\n"
           "  --task-index INT            Task Index: with --frames, cook only this farm task's share (0-based;\n"
           "                              default from SLURM_ARRAY_TASK_ID or LEVELFORGE_TASK_INDEX).\n"
           "  --task-count INT            Task Count: the number of farm tasks sharing the frames.\n"
           "  --plugin FILE               Load operators from a plugin library first (see docs/pipelines.md).\n";
}

namespace {

std::optional<long long> envInteger(const char* name)
{
    const char* v = std::getenv(name);
    if (!v || !*v) return std::nullopt;
    char* end = nullptr;
    errno = 0;
    const long long x = std::strtoll(v, &end, 10);
    if (errno || *end != '\0' || x < -1000000000LL || x > 1000000000LL)
        throw UsageError(std::string("the environment variable ") + name + "='" + v + "' is not an integer");
    return x;
}

} // namespace

TaskShare taskShare(const CommonOptions& common)
{
    TaskShare t;
    long long index = 0, count = 1;
    if (common.taskIndex || common.taskCount) {
        if (!common.taskIndex || !common.taskCount)
            throw UsageError("give --task-index and --task-count together");
        index = *common.taskIndex;
        count = *common.taskCount;
        t.source = "--task-index";
    } else if (const auto id = envInteger("SLURM_ARRAY_TASK_ID")) {
        const auto min = envInteger("SLURM_ARRAY_TASK_MIN");
        const auto max = envInteger("SLURM_ARRAY_TASK_MAX");
        const auto n = envInteger("SLURM_ARRAY_TASK_COUNT");
        // --array=A-B:S numbers the tasks A, A+S, A+2S, ...
        const long long step = envInteger("SLURM_ARRAY_TASK_STEP").value_or(1);
        if (step < 1) throw UsageError("the environment variable SLURM_ARRAY_TASK_STEP=" + std::to_string(step) + " is not a step");
        const long long offset = *id - min.value_or(0);
        if (offset % step != 0)
            throw UsageError("SLURM_ARRAY_TASK_ID=" + std::to_string(*id) + " is not SLURM_ARRAY_TASK_MIN=" +
                             std::to_string(min.value_or(0)) + " plus a multiple of SLURM_ARRAY_TASK_STEP=" + std::to_string(step) +
                             "; give --task-index and --task-count for arrays of listed ids");
        index = offset / step;
        if (n) count = *n;
        else if (min && max) count = (*max - *min) / step + 1;
        else throw UsageError("SLURM_ARRAY_TASK_ID is set but neither SLURM_ARRAY_TASK_COUNT nor SLURM_ARRAY_TASK_MIN/MAX");
        t.source = "SLURM_ARRAY_TASK_ID=" + std::to_string(*id);
    } else if (const auto li = envInteger("LEVELFORGE_TASK_INDEX")) {
        const auto lc = envInteger("LEVELFORGE_TASK_COUNT");
        if (!lc) throw UsageError("LEVELFORGE_TASK_INDEX is set but LEVELFORGE_TASK_COUNT is not");
        index = *li;
        count = *lc;
        t.source = "LEVELFORGE_TASK_INDEX=" + std::to_string(*li);
    } else {
        return t;
    }
    if (count < 1) throw UsageError("the task count must be at least 1, got " + std::to_string(count) + " (" + t.source + ")");
    if (index < 0 || index >= count)
        throw UsageError("the task index must be in [0, " + std::to_string(count) + "), got " + std::to_string(index) + " (" +
                         t.source + ")");
    t.index = int(index);
    t.count = int(count);
    return t;
}

std::vector<int> taskFrames(const std::vector<int>& frames, int index, int count)
{
    const size_t n = frames.size();
    const size_t begin = size_t((unsigned long long)(n) * unsigned(index) / unsigned(count));
    const size_t end = size_t((unsigned long long)(n) * unsigned(index + 1) / unsigned(count));
    return std::vector<int>(frames.begin() + long(begin), frames.begin() + long(end));
}

std::string cookReportJson(const OperatorArgs& args, double seconds, const std::string& error)
{
    return jsonText(reportObject(args, seconds, error), -1);
}

int cookWithCommonOptions(const OperatorArgs& args, const CommonOptions& common, std::ostream& out,
                          std::ostream& err)
{
    nlohmann::json report;
    report["levelforge"] = generatorString();
    if (!common.frames) {
        if (common.taskIndex || common.taskCount) {
            err << "levelforge: error: --task-index and --task-count split the frames of --frames; give --frames A-B"
                << std::endl;
            return kExitUsage;
        }
        OperatorArgs a = args;
        for (const Port& p : a.spec().outputs()) {
            if (a.ports().count(p.name) && hasFrameToken(a.ports().at(p.name)) && a.spec().name() != "run") {
                err << "levelforge: error: the output '" << a.ports().at(p.name)
                    << "' has a frame token; give --frames A-B[:step] (see '" << "levelforge " << a.spec().name()
                    << " --help')" << std::endl;
                return kExitUsage;
            }
        }
        const Outcome o = cookCaught(a);
        if (o.code != kExitOk) err << "levelforge: error: " << o.error << std::endl;
        report.update(reportObject(a, o.seconds, o.error));
        const int rc = writeReport(common, report, err);
        return o.code != kExitOk ? o.code : rc;
    }

    try {
        checkFrameOutputs(args);
    } catch (const UsageError& e) {
        err << "levelforge: error: " << oneLine(e.what()) << " (see 'levelforge " << args.spec().name()
            << " --help')" << std::endl;
        return kExitUsage;
    }
    std::vector<int> frames = common.frames->frames();
    TaskShare task;
    try {
        task = taskShare(common);
    } catch (const UsageError& e) {
        err << "levelforge: error: " << oneLine(e.what()) << std::endl;
        return kExitUsage;
    }
    if (task.count > 1) {
        frames = taskFrames(frames, task.index, task.count);
        err << "levelforge: task " << task.index << " of " << task.count << " (" << task.source << "): ";
        if (frames.empty()) err << "no frames" << std::endl;
        else err << "frames " << frames.front() << "-" << frames.back() << " (" << frames.size() << ")" << std::endl;
    }
    const size_t n = frames.size();
    const int jobs = int(std::max<size_t>(1, std::min<size_t>(size_t(std::max(common.jobs, 1)), n)));
    const int threadsPerJob = std::max(1, tbb::info::default_concurrency() / jobs);

    std::vector<Outcome> outcomes(n);
    std::vector<nlohmann::json> frameReports(n);
    std::atomic<size_t> next{0}, finished{0};
    std::atomic<bool> stop{false};
    std::mutex printing;
    const auto t0 = Clock::now();

    auto worker = [&]() {
        tbb::task_arena arena(threadsPerJob);
        for (;;) {
            if (stop.load() || interruptRequested()) return;
            const size_t i = next.fetch_add(1);
            if (i >= n) return;
            const int frame = frames[i];
            OperatorArgs a = args.forFrame(frame);
            std::ostringstream fout, ferr;
            if (jobs > 1) a.setStreams(fout, ferr);
            Outcome o;
            {
                const ProgressPrefixScope prefix("frame " + std::to_string(frame) + " (" + std::to_string(i + 1) +
                                                 "/" + std::to_string(n) + "): " +
                                                 ProgressPrefixScope::current());
                std::optional<SilentProgressScope> silent;
                if (jobs > 1) silent.emplace();
                arena.execute([&] { o = cookCaught(a); });
            }
            outcomes[i] = o;
            frameReports[i] = reportObject(a, o.seconds, o.error);
            const size_t done = finished.fetch_add(1) + 1;
            {
                const std::lock_guard<std::mutex> lock(printing);
                if (jobs > 1) {
                    out << fout.str();
                    err << ferr.str();
                }
                if (o.code != kExitOk) {
                    err << "levelforge: error: frame " << frame << ": " << o.error << std::endl;
                } else if (jobs > 1) {
                    const double elapsed = std::chrono::duration<double>(Clock::now() - t0).count();
                    char secs[32];
                    std::snprintf(secs, sizeof secs, "%.2f s", o.seconds);
                    err << "levelforge: frame " << frame << " done (" << done << "/" << n << ", " << secs;
                    if (done < n) err << ", ETA " << durationText(elapsed / double(done) * double(n - done));
                    err << ")" << std::endl;
                }
                out.flush();
            }
            if (o.code == kExitInterrupted || (o.code != kExitOk && common.stopOnError)) stop.store(true);
        }
    };
    std::vector<std::thread> threads;
    for (int j = 1; j < jobs; ++j) threads.emplace_back(worker);
    worker();
    for (std::thread& t : threads) t.join();

    size_t ok = 0, failed = 0, skipped = 0;
    bool interrupted = interruptRequested();
    std::string failedList;
    nlohmann::json list = nlohmann::json::array();
    for (size_t i = 0; i < n; ++i) {
        if (frameReports[i].is_null()) {
            ++skipped;
            continue;
        }
        list.push_back(frameReports[i]);
        if (outcomes[i].code == kExitOk) {
            ++ok;
            continue;
        }
        if (outcomes[i].code == kExitInterrupted) interrupted = true;
        if (++failed <= 10) failedList += (failedList.empty() ? "" : ", ") + std::to_string(frames[i]);
    }
    if (failed > 10) failedList += ", ...";
    out << "levelforge: frames " << common.frames->text() << ": " << ok << " of " << n << " done";
    if (failed) out << ", " << failed << " failed (" << failedList << ")";
    if (skipped) out << ", " << skipped << " not cooked";
    char total[32];
    std::snprintf(total, sizeof total, "%.2f s", std::chrono::duration<double>(Clock::now() - t0).count());
    out << "; " << total << " with " << jobs
        << (jobs == 1 ? " job" : " jobs") << "\n";
    out.flush();
    report["operator"] = args.spec().name();
    report["frames"] = list;
    report["summary"] = {{"frames", n}, {"done", ok}, {"failed", failed}, {"not_cooked", skipped}, {"jobs", jobs},
                         {"task_index", task.index}, {"task_count", task.count}};
    const int rc = writeReport(common, report, err);
    if (interrupted) {
        err << "levelforge: error: interrupted" << std::endl;
        return kExitInterrupted;
    }
    if (failed) return kExitFailure;
    return rc;
}

} // namespace levelforge::ops
