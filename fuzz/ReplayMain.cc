// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief levelforge_fuzz_replay: runs saved inputs through the fuzz targets without libFuzzer
///        (any compiler; ctest Fuzz.Replay.<target>).
///
///     levelforge_fuzz_replay --list
///     levelforge_fuzz_replay TARGET PATH... [--optional PATH...]
///
/// Each PATH is an input file or a folder of them (its regular files, in name order, except
/// names starting with '.', README* and *.pending: a *.pending input is a known finding not yet
/// fixed). PATHs after --optional may be missing (the seeds of ../shared/data): a missing one
/// is reported and skipped. Every input runs once through the target; the exit status is 0 when
/// every input ran clean, 1 when a target reported a finding (the input and the finding are
/// printed), 2 on a usage error or an unreadable input.
#include "FuzzCommon.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

bool skippedName(const std::string& name)
{
    const std::string pending = ".pending";
    return name.empty() || name[0] == '.' || name.rfind("README", 0) == 0 ||
           (name.size() >= pending.size() && name.compare(name.size() - pending.size(), pending.size(), pending) == 0);
}

int usage()
{
    std::cerr << "usage: levelforge_fuzz_replay --list\n"
                 "       levelforge_fuzz_replay TARGET PATH... [--optional PATH...]\n";
    return 2;
}

} // namespace

int main(int argc, char** argv)
{
    using levelforge::fuzz::registry;
    if (argc < 2) return usage();
    if (std::strcmp(argv[1], "--list") == 0) {
        for (const auto& t : registry()) std::cout << t.name << "\n";
        return 0;
    }
    const std::string name = argv[1];
    const auto target = std::find_if(registry().begin(), registry().end(),
                                     [&](const auto& t) { return name == t.name; });
    if (target == registry().end()) {
        std::cerr << "levelforge_fuzz_replay: no target '" << name << "' (--list shows them)\n";
        return 2;
    }
    levelforge::fuzz::initialize();

    // The inputs, in order.
    std::vector<fs::path> inputs;
    uint64_t pending = 0;
    bool optional = false;
    for (int i = 2; i < argc; ++i) {
        if (std::strcmp(argv[i], "--optional") == 0) {
            optional = true;
            continue;
        }
        const fs::path p(argv[i]);
        std::error_code ec;
        if (fs::is_directory(p, ec)) {
            std::vector<fs::path> files;
            for (const fs::directory_entry& e : fs::directory_iterator(p, ec)) {
                if (!e.is_regular_file(ec)) continue;
                const std::string base = e.path().filename().string();
                if (skippedName(base)) {
                    if (base.size() > 8 && base.compare(base.size() - 8, 8, ".pending") == 0) ++pending;
                    continue;
                }
                files.push_back(e.path());
            }
            std::sort(files.begin(), files.end());
            inputs.insert(inputs.end(), files.begin(), files.end());
        } else if (fs::is_regular_file(p, ec)) {
            inputs.push_back(p);
        } else if (optional) {
            std::cout << "skipped: " << p.string() << " is not present\n";
        } else {
            std::cerr << "levelforge_fuzz_replay: " << p.string() << " is neither a file nor a folder\n";
            return 2;
        }
    }

    uint64_t failed = 0;
    for (const fs::path& p : inputs) {
        std::ifstream in(p, std::ios::binary);
        const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        if (in.bad()) {
            std::cerr << "levelforge_fuzz_replay: cannot read " << p.string() << "\n";
            return 2;
        }
        std::cout << "run  " << name << " " << p.string() << " (" << bytes.size() << " bytes)" << std::endl;
        try {
            const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
            target->function(bytes.empty() ? nullptr : data, bytes.size());
        } catch (const std::exception& e) {
            ++failed;
            std::cout << "FAIL " << name << " " << p.string() << ": " << e.what() << std::endl;
        }
    }
    std::cout << name << ": " << inputs.size() << " inputs replayed, " << failed << " failed";
    if (pending) std::cout << ", " << pending << " pending (*.pending, not run)";
    std::cout << std::endl;
    return failed ? 1 : 0;
}
