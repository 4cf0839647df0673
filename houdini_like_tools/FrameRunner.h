// SPDX-License-Identifier: Apache-2.0
// levelforge operators — the options every operator has besides its own parameters, and the
// cook loop they drive: frame sequences (`--frames`, `--jobs`, `--stop-on-error`) and
// statistics (`--report-json`).
//
// With --frames A-B[:step], the operator is cooked once per frame with the frame tokens of its
// paths and text parameters replaced (FrameRange.h). Frames run `--jobs` at a time, each in its
// own TBB arena of (cores / jobs) threads, so the results are those of the frame cooked alone
// (every algorithm is deterministic for any thread count). A frame that fails is reported as
// "levelforge: error: frame 12: <message>" and the others go on, unless --stop-on-error; the
// exit status is then 1. Ctrl-C stops every frame (status 130). With --jobs above 1 what the
// frames print is buffered and printed frame by frame, and stage progress gives way to one
// "levelforge: frame 12 done (3/240, 1.52 s, ETA 5 min)" line per frame.
#pragma once

#include "FrameRange.h"
#include "Operator.h"

#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace levelforge::ops {

/// The options of every operator (shown under "Common options" in each operator's --help).
struct CommonOptions
{
    std::optional<FrameRange> frames; ///< --frames; nullopt: cook once
    int jobs = 1;                     ///< --jobs: frames cooked at the same time
    bool stopOnError = false;         ///< --stop-on-error
    std::string reportJson;           ///< --report-json FILE; empty: none
    /// --task-index / --task-count: this farm task's share of the frames (0-based index);
    /// nullopt: all frames (or the share the scheduler's environment gives, see taskShare()).
    std::optional<int> taskIndex, taskCount;
};

/// A farm task's share of a frame sequence.
struct TaskShare
{
    int index = 0, count = 1; ///< 0-based task index, number of tasks
    std::string source;       ///< "--task-index", "SLURM_ARRAY_TASK_ID=4", or "" (no split)
};

/// @brief Which task this is: --task-index/--task-count when given, else Slurm's array
///        variables (SLURM_ARRAY_TASK_ID minus SLURM_ARRAY_TASK_MIN, divided by
///        SLURM_ARRAY_TASK_STEP when set, and SLURM_ARRAY_TASK_COUNT or (MAX - MIN) / STEP + 1), else the generic LEVELFORGE_TASK_INDEX / LEVELFORGE_TASK_COUNT, else one
///        task of one.
/// @throws UsageError an index without a count (or the reverse), a count below 1, an index
///         outside [0, count), or a variable that is not an integer (naming it)
TaskShare taskShare(const CommonOptions& common);

/// @brief The frames of task @p index of @p count: contiguous blocks of equal size (± 1 frame),
///        in order; every frame belongs to exactly one task. A task beyond the frames gets none.
std::vector<int> taskFrames(const std::vector<int>& frames, int index, int count);

/// Names reserved for the common options; no operator may declare a parameter with one of them.
const std::vector<std::string>& commonOptionNames();

/// "Common options:" help block, two columns like the operators' own parameters.
std::string commonOptionsHelp();

/// @brief Cooks @p args once, or once per frame, as @p common says, prints the errors
///        ("levelforge: error: ...") and writes the report. Returns an ExitCode
///        (OperatorRegistry.h). Never throws.
int cookWithCommonOptions(const OperatorArgs& args, const CommonOptions& common, std::ostream& out,
                          std::ostream& err);

/// @brief The JSON report of one cook (as text): operator, inputs, outputs, parameters in
///        effect, the statistics recorded with OperatorArgs::stat(), the steps of a pipeline,
///        seconds, status ("ok" or "failed") and the error message.
std::string cookReportJson(const OperatorArgs& args, double seconds, const std::string& error);

} // namespace levelforge::ops
