// SPDX-License-Identifier: Apache-2.0
// levelforge operators — pipelines: several operators cooked in one process (`levelforge run`).
//
// A pipeline file is JSON:
//   {"steps": [
//     {"op": "mesh-to-sdf", "inputs": ["bunny_$F4.obj"], "outputs": ["@band"], "params": {"voxel-count": 256}},
//     {"op": "reshape", "inputs": ["@band"], "outputs": ["out_$F4.vdb"], "params": {"op": "dilate", "offset": 2}}
//   ]}
// - "op": an operator name (any but `run`); "inputs"/"outputs": its positionals, in declaration
//   order; "params": its parameters by name without "--" (numbers, strings, true/false for
//   switches, a list of strings for a repeatable parameter). "name" (a label for messages) and,
//   at the top level, "description" are allowed; any other key is an error (a typo would
//   otherwise be ignored).
// - Names starting with '@' are grids or meshes kept in memory between steps (OperatorIO.h):
//   no file is written or read for them. Every '@' input must be written by an earlier step.
// - Everything is validated before the first step runs: the file, every operator, port count,
//   parameter name, type and range, the '@' names. At the start of each frame, every file input
//   that no step writes must exist and every file output must be writable.
// - The files a frame writes are staged in a hidden directory next to each target
//   (".levelforge-run.PID.XXXXXXXX") and moved into place only when every step of the frame has
//   succeeded: a failing step leaves no output of its frame (earlier outputs of the same frame
//   included), and later steps that read an earlier step's file read the staged one.
// - A failing step stops the frame with one error "step 2 (reshape): <message>".
#pragma once

#include "Operator.h"
#include "OperatorRegistry.h"

#include <string>
#include <vector>

namespace levelforge::ops {

/// One step of a pipeline, validated: the operator and its arguments (frame tokens not yet
/// replaced).
struct PipelineStep
{
    std::string label;   ///< "step 2 (reshape)" or "step 2 (<name>)"
    OperatorArgs args;   ///< ports and parameters set from the file
};

/// A validated pipeline.
struct Pipeline
{
    std::string path;
    std::vector<PipelineStep> steps;
};

/// @brief Reads and validates a pipeline file against @p registry.
/// @throws IoError the file cannot be read; InvalidArgumentError it is not valid JSON or not a
///         pipeline (the message names the file, the step and the problem); UsageError a step's
///         parameter is unknown, of the wrong type or out of range
Pipeline loadPipeline(const std::string& path, const OperatorRegistry& registry);

/// @brief Runs every step of @p pipeline for one frame (nullopt: no frames) in one process.
///        Prints what the steps print on run's streams; records each step's report in @p run.
/// @throws the failing step's error, its message prefixed by the step's label
void runPipeline(const Pipeline& pipeline, OperatorArgs& run, bool quiet);

} // namespace levelforge::ops
