// SPDX-License-Identifier: Apache-2.0
// Tests for the operator registry (houdini_like_tools): declarations are data, and help,
// parsing, range checks and error messages are generated from them.
#include "TestUtil.h"

#include "Operator.h"
#include "GridParams.h"
#include "OperatorRegistry.h"

#include <levelforge/io/VolumeIO.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace levelforge::ops;

using levelforge_test::countLines;

namespace {

const OperatorSpec& meshToSdf()
{
    const OperatorSpec* spec = OperatorRegistry::global().find("mesh-to-sdf");
    if (!spec) throw std::runtime_error("mesh-to-sdf is not registered");
    return *spec;
}

struct CliResult
{
    int code;
    std::string out, err;
};

CliResult cli(const std::vector<std::string>& args,
              const OperatorRegistry& registry = OperatorRegistry::global())
{
    std::ostringstream out, err;
    const int code = runCli(args, out, err, registry);
    return {code, out.str(), err.str()};
}

/// A toy operator whose cook records what it was given (no mesh conversion needed).
struct Recorded
{
    int64_t count = 0;
    double scale = 0;
    std::string mode, label, in, out;
    bool verbose = false, scaleSet = false;
    int cooks = 0;
};

OperatorRegistry toyRegistry(Recorded& rec)
{
    OperatorRegistry registry;
    registry.add(OperatorSpec("toy", "A toy operator for tests")
                     .input("source", "input thing")
                     .output("target", "output thing")
                     .param(Param::integer("count", "Count", "How many").defaultValue(4).range(1, 10))
                     .param(Param::floating("scale", "Scale", "Scale, world units").above(0.0))
                     .param(Param::choice("mode", "Mode", "How", {"fast", "exact"})
                                .defaultValue("exact"))
                     .param(Param::string("label", "Label", "A name").defaultValue("x"))
                     .param(Param::flag("verbose", "Verbose", "Say more"))
                     .cook([&rec](OperatorArgs& a) {
                         rec.count = a.getInt("count");
                         rec.scaleSet = a.isSet("scale");
                         rec.scale = a.has("scale") ? a.getFloat("scale") : -1.0;
                         rec.mode = a.getString("mode");
                         rec.label = a.getString("label");
                         rec.verbose = a.getBool("verbose");
                         rec.in = a.input("source");
                         rec.out = a.output("target");
                         ++rec.cooks;
                     }));
    return registry;
}

} // namespace

TEST(Operators, RegistryHasTheOperators)
{
    const auto ops = OperatorRegistry::global().list();
    std::vector<std::string> names;
    for (const OperatorSpec* op : ops) names.push_back(op->name());
    EXPECT_NE(std::find(names.begin(), names.end(), "mesh-to-sdf"), names.end());
    EXPECT_NE(std::find(names.begin(), names.end(), "info"), names.end());
    EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
    for (const OperatorSpec* op : ops) {
        EXPECT_NO_THROW(op->checkDeclaration()) << op->name();
        EXPECT_FALSE(op->help().empty()) << op->name();
        for (const Param& p : op->params()) {
            EXPECT_FALSE(p.label.empty()) << op->name() << " --" << p.name;
            EXPECT_FALSE(p.help.empty()) << op->name() << " --" << p.name;
        }
    }
    EXPECT_EQ(OperatorRegistry::global().find("no-such-operator"), nullptr);
}

TEST(Operators, MeshToSdfDeclaration)
{
    const OperatorSpec& spec = meshToSdf();
    ASSERT_EQ(spec.inputs().size(), 1u);
    EXPECT_EQ(spec.inputs()[0].name, "mesh");
    ASSERT_EQ(spec.outputs().size(), 1u);
    EXPECT_EQ(spec.outputs()[0].name, "output");

    const Param* vs = spec.findParam("voxel-size");
    ASSERT_TRUE(vs);
    EXPECT_EQ(vs->type, ParamType::Float);
    EXPECT_FALSE(vs->defaultText.has_value());
    ASSERT_TRUE(vs->min.has_value());
    EXPECT_EQ(*vs->min, 0.0);
    EXPECT_EQ(vs->minBound, Bound::Exclusive);
    EXPECT_EQ(vs->excludes, std::vector<std::string>{"voxel-count"});

    const Param* vc = spec.findParam("voxel-count");
    ASSERT_TRUE(vc);
    EXPECT_EQ(vc->type, ParamType::Int);
    EXPECT_EQ(vc->defaultText.value_or(""), "256");
    ASSERT_TRUE(vc->min.has_value());
    EXPECT_GE(*vc->min, 1.0);

    for (const char* name : {"exterior-band", "interior-band"}) {
        const Param* band = spec.findParam(name);
        ASSERT_TRUE(band) << name;
        EXPECT_EQ(band->type, ParamType::Float);
        EXPECT_EQ(band->defaultText.value_or(""), "3");
        EXPECT_EQ(band->rangeText(), "(0, 1000]");
    }
    const Param* gn = spec.findParam("grid-name");
    ASSERT_TRUE(gn);
    EXPECT_EQ(gn->type, ParamType::String);
    EXPECT_EQ(gn->defaultText.value_or(""), "surface");
    for (const char* name : {"quiet", "report"}) {
        const Param* f = spec.findParam(name);
        ASSERT_TRUE(f) << name;
        EXPECT_EQ(f->type, ParamType::Bool);
    }

    // Defaults as the cook sees them.
    OperatorArgs args(spec);
    EXPECT_FALSE(args.isSet("voxel-size"));
    EXPECT_FALSE(args.has("voxel-size"));
    EXPECT_EQ(args.getInt("voxel-count"), 256);
    EXPECT_EQ(args.getFloat("exterior-band"), 3.0);
    EXPECT_EQ(args.getFloat("interior-band"), 3.0);
    EXPECT_EQ(args.getString("grid-name"), "surface");
    EXPECT_FALSE(args.getBool("quiet"));
    EXPECT_FALSE(args.getBool("report"));
}

TEST(Operators, GeneratedHelpMentionsEverything)
{
    for (const OperatorSpec* op : OperatorRegistry::global().list()) {
        const std::string help = op->helpText();
        EXPECT_NE(help.find(op->name()), std::string::npos);
        EXPECT_NE(help.find(op->help()), std::string::npos);
        for (const Port& port : op->inputs()) EXPECT_NE(help.find("<" + port.name + ">"), std::string::npos) << help;
        for (const Port& port : op->outputs()) EXPECT_NE(help.find("<" + port.name + ">"), std::string::npos) << help;
        for (const Param& p : op->params()) {
            EXPECT_NE(help.find("--" + p.name), std::string::npos) << op->name() << ": " << p.name;
            EXPECT_NE(help.find(p.label), std::string::npos) << op->name() << ": " << p.label;
            if (!p.rangeText().empty()) {
                EXPECT_NE(help.find(p.rangeText()), std::string::npos) << p.name;
            }
        }
        // `levelforge <op> --help` prints exactly the generated text and succeeds.
        const CliResult r = cli({op->name(), "--help"});
        EXPECT_EQ(r.code, 0);
        EXPECT_EQ(r.out, op->helpText());
        EXPECT_TRUE(r.err.empty()) << r.err;
    }
    const std::string top = OperatorRegistry::global().helpText();
    for (const OperatorSpec* op : OperatorRegistry::global().list()) {
        EXPECT_NE(top.find(op->name()), std::string::npos);
        EXPECT_NE(top.find(op->help()), std::string::npos);
    }
    const CliResult r = cli({"--help"});
    EXPECT_EQ(r.code, 0);
    EXPECT_EQ(r.out, top);
    const CliResult v = cli({"--version"});
    EXPECT_EQ(v.code, 0);
    EXPECT_EQ(v.out.rfind("levelforge ", 0), 0u) << v.out;
}

TEST(Operators, RangeViolationsNameTheParameter)
{
    const OperatorSpec& spec = meshToSdf();
    const std::vector<std::pair<std::string, std::string>> bad = {
        {"voxel-size", "0"},        {"voxel-size", "-1"},     {"voxel-size", "nan"},
        {"voxel-size", "inf"},      {"voxel-size", "abc"},    {"voxel-size", ""},
        {"voxel-size", "0.1x"},     {"voxel-count", "0"},     {"voxel-count", "2.5"},
        {"voxel-count", "-3"},      {"voxel-count", "99999999999999999999"},
        {"exterior-band", "0"},     {"exterior-band", "1e9"}, {"exterior-band", "-2"},
        {"interior-band", "1001"},  {"interior-band", "NaN"},
    };
    for (const auto& [name, value] : bad) {
        OperatorArgs args(spec);
        try {
            args.set(name, value);
            ADD_FAILURE() << "--" << name << " " << value << " was accepted";
        } catch (const UsageError& e) {
            EXPECT_NE(std::string(e.what()).find("--" + name), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("'" + value + "'"), std::string::npos) << e.what();
        }
        EXPECT_FALSE(args.isSet(name));
    }
    OperatorArgs args(spec);
    EXPECT_NO_THROW(args.set("voxel-size", "0.01"));
    EXPECT_DOUBLE_EQ(args.getFloat("voxel-size"), 0.01);
    EXPECT_NO_THROW(args.set("exterior-band", "1000"));
    EXPECT_NO_THROW(args.set("interior-band", "0.5"));
    EXPECT_NO_THROW(args.set("voxel-count", "512"));
    EXPECT_EQ(args.getInt("voxel-count"), 512);
    // voxel-size and voxel-count together are refused when the arguments are checked.
    args.setPort("mesh", "a.obj").setPort("output", "a.vdb");
    try {
        args.checkComplete();
        ADD_FAILURE() << "voxel-size together with voxel-count was accepted";
    } catch (const UsageError& e) {
        EXPECT_NE(std::string(e.what()).find("--voxel-size"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("--voxel-count"), std::string::npos) << e.what();
    }
    EXPECT_THROW(args.set("no-such-parameter", "1"), UsageError);
}

TEST(Operators, CliUsageErrorsAreOneLineAndWriteNothing)
{
    const fs::path dir = levelforge_test::scratchDir("ops_usage_errors");
    const std::string out = (dir / "out.vdb").string();
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"mesh-to-sdf", "builtin:sphere", out, "--voxel-size", "0"}, "--voxel-size"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--voxel-size", "-1"}, "--voxel-size"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--voxel-size=nan"}, "--voxel-size"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--exterior-band", "1e9"}, "--exterior-band"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--interior-band", "0"}, "--interior-band"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--voxel-count", "0"}, "--voxel-count"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--voxel-size", "0.1", "--voxel-count", "10"},
         "--voxel-count"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--voxel-size"}, "--voxel-size"},
        {{"mesh-to-sdf", "builtin:sphere", out, "--no-such-option"}, "--no-such-option"},
        {{"mesh-to-sdf", "builtin:sphere"}, "output"},
        {{"mesh-to-sdf", "builtin:sphere", out, "extra"}, "extra"},
        {{"no-such-operator"}, "no-such-operator"},
        {{}, "operator"},
    };
    for (const auto& [args, mention] : cases) {
        std::string joined;
        for (const std::string& a : args) joined += a + " ";
        const CliResult r = cli(args);
        EXPECT_EQ(r.code, kExitUsage) << joined << "\n" << r.err;
        EXPECT_EQ(countLines(r.err, "levelforge: error: "), 1) << joined << "\n" << r.err;
        EXPECT_EQ(countLines(r.err, ""), 1) << joined << "\n" << r.err;
        EXPECT_NE(r.err.find(mention), std::string::npos) << joined << "\n" << r.err;
        EXPECT_FALSE(fs::exists(out)) << joined;
    }
    EXPECT_TRUE(fs::is_empty(dir));
}

TEST(Operators, GeneratedParsingOfEveryType)
{
    Recorded rec;
    const OperatorRegistry registry = toyRegistry(rec);

    CliResult r = cli({"toy", "a", "b"}, registry);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(rec.cooks, 1);
    EXPECT_EQ(rec.count, 4);
    EXPECT_FALSE(rec.scaleSet);
    EXPECT_EQ(rec.scale, -1.0);
    EXPECT_EQ(rec.mode, "exact");
    EXPECT_EQ(rec.label, "x");
    EXPECT_FALSE(rec.verbose);
    EXPECT_EQ(rec.in, "a");
    EXPECT_EQ(rec.out, "b");

    r = cli({"toy", "--count", "7", "in", "--scale=0.5", "--mode", "fast", "out", "--verbose",
             "--label", "hello world"},
            registry);
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(rec.cooks, 2);
    EXPECT_EQ(rec.count, 7);
    EXPECT_TRUE(rec.scaleSet);
    EXPECT_EQ(rec.scale, 0.5);
    EXPECT_EQ(rec.mode, "fast");
    EXPECT_EQ(rec.label, "hello world");
    EXPECT_TRUE(rec.verbose);
    EXPECT_EQ(rec.in, "in");
    EXPECT_EQ(rec.out, "out");

    for (const auto& [args, mention] :
         std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"toy", "a", "b", "--count", "11"}, "[1, 10]"},
             {{"toy", "a", "b", "--count", "0"}, "--count (Count)"},
             {{"toy", "a", "b", "--scale", "0"}, "> 0"},
             {{"toy", "a", "b", "--mode", "slow"}, "fast, exact"},
             {{"toy", "a"}, "<target>"},
         }) {
        r = cli(args, registry);
        EXPECT_EQ(r.code, kExitUsage);
        EXPECT_EQ(countLines(r.err, "levelforge: error: "), 1) << r.err;
        EXPECT_NE(r.err.find(mention), std::string::npos) << r.err;
    }
    EXPECT_EQ(rec.cooks, 2);

    // A failing cook is a failure (status 1), reported in one line.
    OperatorRegistry failing;
    failing.add(OperatorSpec("boom", "Always fails").cook([](OperatorArgs&) {
        throw levelforge::IoError("cannot read 'x.obj': no such file\n(second line)");
    }));
    r = cli({"boom"}, failing);
    EXPECT_EQ(r.code, kExitFailure);
    EXPECT_EQ(r.err, "levelforge: error: cannot read 'x.obj': no such file (second line)\n");
}

TEST(Operators, DeclarationsAreChecked)
{
    auto cookNothing = [](OperatorArgs&) {};
    OperatorRegistry registry;
    EXPECT_THROW(registry.add(OperatorSpec("Bad_Name", "x").cook(cookNothing)), std::logic_error);
    EXPECT_THROW(registry.add(OperatorSpec("no-cook", "x")), std::logic_error);
    EXPECT_THROW(registry.add(OperatorSpec("bad-default", "x")
                                  .param(Param::floating("w", "W", "w").defaultValue(5.0).range(0, 1))
                                  .cook(cookNothing)),
                 std::logic_error);
    EXPECT_THROW(registry.add(OperatorSpec("dup", "x")
                                  .param(Param::flag("a", "A", "a"))
                                  .param(Param::flag("a", "A", "a"))
                                  .cook(cookNothing)),
                 std::logic_error);
    EXPECT_THROW(registry.add(OperatorSpec("bad-excl", "x")
                                  .param(Param::flag("a", "A", "a").exclusiveWith("b"))
                                  .cook(cookNothing)),
                 std::logic_error);
    EXPECT_NO_THROW(registry.add(OperatorSpec("fine", "x").cook(cookNothing)));
    EXPECT_THROW(registry.add(OperatorSpec("fine", "x").cook(cookNothing)), std::logic_error);
}

TEST(Operators, ParseParamValue)
{
    const Param f = Param::floating("f", "F", "f").range(-1, 1, Bound::Inclusive, Bound::Exclusive);
    EXPECT_EQ(std::get<double>(parseParamValue(f, "-1")), -1.0);
    EXPECT_EQ(std::get<double>(parseParamValue(f, " 0.5 ")), 0.5);
    EXPECT_THROW(parseParamValue(f, "1"), UsageError);
    EXPECT_THROW(parseParamValue(f, "-inf"), UsageError);
    const Param i = Param::integer("i", "I", "i");
    EXPECT_EQ(std::get<int64_t>(parseParamValue(i, "-42")), -42);
    EXPECT_THROW(parseParamValue(i, "4e2"), UsageError);
    const Param b = Param::flag("b", "B", "b");
    EXPECT_TRUE(std::get<bool>(parseParamValue(b, "true")));
    EXPECT_FALSE(std::get<bool>(parseParamValue(b, "0")));
    EXPECT_THROW(parseParamValue(b, "maybe"), UsageError);
    const Param e = Param::choice("e", "E", "e", {"x", "y"});
    EXPECT_EQ(std::get<std::string>(parseParamValue(e, "y")), "y");
    EXPECT_THROW(parseParamValue(e, "z"), UsageError);
    EXPECT_EQ(f.rangeText(), "[-1, 1)");
    EXPECT_EQ(Param::floating("g", "G", "g").above(0).rangeText(), "> 0");
    EXPECT_EQ(i.rangeText(), "");
}

TEST(Operators, CliReferenceIsCurrent)
{
    // docs/cli.md holds the generated help of every operator verbatim (see its header for the
    // command that regenerates it).
    const fs::path doc = fs::path(LEVELFORGE_SOURCE_DIR) / "docs" / "cli.md";
    ASSERT_TRUE(fs::exists(doc)) << doc << " not found";
    std::ifstream in(doc);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("```text\n" + OperatorRegistry::global().helpText() + "```"),
              std::string::npos)
        << "docs/cli.md is out of date: top-level help";
    for (const OperatorSpec* op : OperatorRegistry::global().list()) {
        EXPECT_NE(text.find("## levelforge " + op->name() + "\n\n```text\n" + op->helpText() + "```"),
                  std::string::npos)
            << "docs/cli.md is out of date for operator " << op->name();
    }
}

TEST(Operators, SharedHelpersAskBeforeReading)
{
    // The volume loader is shared by volume-to-sdf and dt-report; it asks has() for parameters
    // only one of them declares. has() is false for an undeclared name, so dt-report reads files.
    const OperatorSpec* dt = OperatorRegistry::global().find("dt-report");
    ASSERT_TRUE(dt);
    OperatorArgs args(*dt);
    EXPECT_FALSE(args.has("exterior-band"));
    EXPECT_TRUE(args.has("iso"));
    EXPECT_THROW(args.isSet("exterior-band"), UsageError);

    const fs::path dir = levelforge_test::scratchDir("ops_dt_report_file");
    const std::string path = (dir / "ball.nii").string();
    levelforge::ScalarVolume ball;
    ball.dims = openvdb::Coord(24, 20, 22);
    ball.spacing = openvdb::Vec3d(1.0);
    ball.data.resize(ball.voxelCount());
    for (int k = 0; k < 22; ++k)
        for (int j = 0; j < 20; ++j)
            for (int i = 0; i < 24; ++i)
                ball(i, j, k) = float(8.0 - std::sqrt((i - 11.5) * (i - 11.5) + (j - 9.7) * (j - 9.7) +
                                                      (k - 10.2) * (k - 10.2)));
    levelforge::writeNifti(path, ball);
    const CliResult r = cli({"dt-report", path, "--iso", "0"});
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("VCVDT8"), std::string::npos) << r.out;
}

TEST(Operators, GridParameterGroupIsSharedAndRead)
{
    // mesh-to-sdf, mesh-to-adf and volume-to-sdf declare the GridSpec parameters from one group.
    for (const char* name : {"mesh-to-sdf", "mesh-to-adf", "volume-to-sdf"}) {
        const OperatorSpec* spec = OperatorRegistry::global().find(name);
        ASSERT_TRUE(spec) << name;
        const Param* g = spec->findParam("grid-name");
        ASSERT_TRUE(g) << name;
        EXPECT_EQ(g->label, "Grid Name") << name;
    }
    const OperatorSpec& spec = meshToSdf();
    OperatorArgs args(spec);
    args.set("voxel-size", "0.25").set("exterior-band", "0.5").set("interior-band", "4").setFlag("world-units");
    args.set("grid-name", "solid");
    levelforge::GridSpec grid;
    readGridParams(args, grid);
    EXPECT_EQ(grid.voxelSize, 0.25);
    EXPECT_EQ(grid.voxelCount, 0);
    EXPECT_EQ(grid.exteriorWidth, 0.5);
    EXPECT_EQ(grid.interiorWidth, 4.0);
    EXPECT_EQ(grid.units, levelforge::WidthUnits::World);
    EXPECT_EQ(grid.gridName, "solid");
    EXPECT_DOUBLE_EQ(grid.widthInVoxels(grid.exteriorWidth, grid.voxelSize), 2.0);

    const OperatorSpec* vol = OperatorRegistry::global().find("volume-to-sdf");
    OperatorArgs vargs(*vol);
    levelforge::GridSpec vgrid;
    readGridParams(vargs, vgrid); // no --voxel-size / --voxel-count: the volume brings its spacing
    EXPECT_EQ(vgrid.voxelSize, 0.0);
    EXPECT_EQ(vgrid.voxelCount, 0);
    EXPECT_EQ(vgrid.exteriorWidth, 3.0);
}
