// SPDX-License-Identifier: Apache-2.0
// levelforge operator `run`: a pipeline of operators in one process (see Pipeline.h).
// vdb_tool: one command line of actions; Houdini: a SOP network cooked by hbatch.
#include "FrameRange.h"
#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorRegistry.h"
#include "Pipeline.h"

#include <string>

namespace levelforge::ops {
namespace {

/// With frames, a file output without a frame token would be written by every frame.
void checkFrameTokens(const Pipeline& p)
{
    for (const PipelineStep& step : p.steps) {
        for (const Port& port : step.args.spec().outputs()) {
            const std::string& out = step.args.output(port.name);
            if (isMemoryName(out) || out == "/dev/null" || hasFrameToken(out)) continue;
            throw UsageError(step.label + ": with --frames, the output '" + out +
                             "' needs a frame token ($F, $F4, %04d): every frame would write the same file");
        }
    }
}

/// Without frames, a file output with a frame token would be written under the token's text.
void checkNoFrameTokens(const Pipeline& p)
{
    for (const PipelineStep& step : p.steps) {
        for (const Port& port : step.args.spec().outputs()) {
            const std::string& out = step.args.output(port.name);
            if (isMemoryName(out) || !hasFrameToken(out)) continue;
            throw UsageError(step.label + ": the output '" + out +
                             "' has a frame token; give --frames A-B[:step] (see 'levelforge run --help')");
        }
    }
}

void checkTokens(const Pipeline& p, const OperatorArgs& args)
{
    if (args.frame()) checkFrameTokens(p);
    else checkNoFrameTokens(p);
}

void precheckRun(OperatorArgs& args)
{
    const Pipeline p = loadPipeline(args.input("pipeline"), OperatorRegistry::global());
    checkTokens(p, args);
}

void cookRun(OperatorArgs& args)
{
    const Pipeline p = loadPipeline(args.input("pipeline"), OperatorRegistry::global());
    checkTokens(p, args);
    runPipeline(p, args, args.getBool("quiet"));
    args.stat("steps", int(p.steps.size()));
}

} // namespace

LEVELFORGE_REGISTER_OPERATOR(
    OperatorSpec("run", "Run a pipeline of operators in one process (like a vdb_tool command line)")
        .description(
            "Reads a JSON pipeline: {\"steps\": [{\"op\": \"mesh-to-sdf\", \"inputs\": [\"bunny.obj\"],\n"
            "\"outputs\": [\"@band\"], \"params\": {\"voxel-count\": 256}}, {\"op\": \"reshape\", \"inputs\":\n"
            "[\"@band\"], \"outputs\": [\"out.vdb\"], \"params\": {\"op\": \"dilate\", \"offset\": 2}}]}.\n"
            "params keys are the operators' parameter names without --, switches take true;\n"
            "names starting with @ are grids or meshes kept in memory between steps (no file).\n"
            "Every step and parameter is checked before the first step runs. The files of a\n"
            "frame appear only when all its steps succeeded; a failing step stops the frame\n"
            "with one error line naming the step. With --frames, $F, $F4 and %04d in the\n"
            "pipeline's names are replaced per frame. See docs/pipelines.md.")
        .input("pipeline", "JSON pipeline file")
        .param(Param::flag("quiet", "Quiet", "Print no step lines on stderr (the steps' own --quiet silences their progress)"))
        .example("levelforge run dilate.json")
        .example("levelforge run shots.json --frames 1-240 --jobs 2")
        .precheck(precheckRun)
        .cook(cookRun));

} // namespace levelforge::ops
