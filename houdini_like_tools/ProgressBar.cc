// SPDX-License-Identifier: Apache-2.0
// levelforge — the operators' progress bars and lines on stderr (see CliProgress in Interrupt.h).
#include "Interrupt.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <unistd.h>

namespace levelforge::ops {
namespace {

thread_local std::string tPrefix;
thread_local bool tSilent = false;

constexpr double kQuietStartSeconds = 0.5; // work that ends sooner prints nothing
constexpr long long kRedrawNs = 100'000'000; // a bar is redrawn at most 10 times a second

bool stderrIsTerminal()
{
    if (!::isatty(STDERR_FILENO)) return false;
    const char* term = std::getenv("TERM");
    return !(term && std::strcmp(term, "dumb") == 0);
}

} // namespace

ProgressPrefixScope::ProgressPrefixScope(std::string prefix) : mSaved(tPrefix) { tPrefix = std::move(prefix); }
ProgressPrefixScope::~ProgressPrefixScope() { tPrefix = mSaved; }
const std::string& ProgressPrefixScope::current() { return tPrefix; }

SilentProgressScope::SilentProgressScope() : mSaved(tSilent) { tSilent = true; }
SilentProgressScope::~SilentProgressScope() { tSilent = mSaved; }
bool SilentProgressScope::active() { return tSilent; }

CliProgress::CliProgress(int minStep, bool enabled)
    : mMode(Mode::None)
    , mStep(minStep < 1 ? 1 : (minStep > 100 ? 100 : minStep))
    , mPrefix(tPrefix)
    , mName(tPrefix + "working")
    , mStart(std::chrono::steady_clock::now())
{
    if (!enabled || tSilent) return;
    const char* forced = std::getenv("LEVELFORGE_PROGRESS");
    if (forced && std::strcmp(forced, "none") == 0) return;
    if (forced && std::strcmp(forced, "bar") == 0) mMode = Mode::Bar;
    else if (forced && std::strcmp(forced, "plain") == 0) mMode = Mode::Plain;
    else mMode = stderrIsTerminal() ? Mode::Bar : Mode::Plain;
}

void CliProgress::start(const char* name)
{
    mName = mPrefix + ((name && *name) ? name : "working");
    mLast.store(-1);
    mLastDrawNs.store(0);
    mStart = std::chrono::steady_clock::now();
}

void CliProgress::end()
{
    if (mMode == Mode::None || mLast.load() < 0) return; // nothing printed: stay silent
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - mStart).count();
    if (mMode == Mode::Bar) {
        while (mDrawing.exchange(true)) {} // a worker may still be drawing
        std::fprintf(stderr, "\rlevelforge: %s done (%.2f s)\033[K\n", mName.c_str(), seconds);
        mDrawing.store(false);
    } else {
        std::fprintf(stderr, "levelforge: %s done (%.2f s)\n", mName.c_str(), seconds);
    }
    std::fflush(stderr);
    mLast.store(-1);
}

void CliProgress::draw(int percent, bool)
{
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - mStart).count();
    constexpr int kWidth = 24;
    char bar[kWidth + 1];
    const int filled = percent * kWidth / 100;
    for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '-';
    bar[kWidth] = '\0';
    char eta[48] = "";
    if (percent >= 3 && percent < 100) {
        const double left = elapsed * (100.0 - percent) / percent;
        if (left < 90) std::snprintf(eta, sizeof eta, "  ETA %.0f s", left);
        else if (left < 5400) std::snprintf(eta, sizeof eta, "  ETA %.0f min", left / 60);
        else std::snprintf(eta, sizeof eta, "  ETA %.1f h", left / 3600);
    }
    std::fprintf(stderr, "\rlevelforge: %s [%s] %3d%%%s\033[K", mName.c_str(), bar, percent, eta);
    std::fflush(stderr);
}

bool CliProgress::wasInterrupted(int percent)
{
    const bool stop = interruptRequested();
    if (stop || mMode == Mode::None || percent < 0) return stop;
    if (percent > 100) percent = 100;
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - mStart).count() < kQuietStartSeconds) return false;
    if (mMode == Mode::Plain) {
        // one line per new multiple of mStep; the winner of the compare-exchange prints
        const int bucket = (percent / mStep) * mStep;
        int last = mLast.load(std::memory_order_relaxed);
        while (bucket > last) {
            if (mLast.compare_exchange_weak(last, bucket, std::memory_order_relaxed)) {
                std::fprintf(stderr, "levelforge: %s %d%%\n", mName.c_str(), bucket);
                std::fflush(stderr);
                break;
            }
        }
        return false;
    }
    // bar: redraw when the percentage grew and 100 ms passed; one thread draws at a time
    const long long ns = std::chrono::duration_cast<std::chrono::nanoseconds>(now - mStart).count();
    if (percent <= mLast.load(std::memory_order_relaxed)) return false;
    if (ns - mLastDrawNs.load(std::memory_order_relaxed) < kRedrawNs && percent < 100) return false;
    if (mDrawing.exchange(true)) return false;
    if (percent > mLast.load()) {
        mLast.store(percent);
        mLastDrawNs.store(ns);
        draw(percent, false);
    }
    mDrawing.store(false);
    return false;
}

} // namespace levelforge::ops
