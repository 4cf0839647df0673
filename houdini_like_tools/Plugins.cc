// SPDX-License-Identifier: Apache-2.0
// levelforge — plugin operators (see Plugins.h, OperatorPlugin.h).
#include "Plugins.h"

#include "OperatorPlugin.h"

#include <levelforge/core/Exceptions.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <ostream>
#include <sstream>

#include <dlfcn.h>

namespace fs = std::filesystem;

namespace levelforge::ops {

std::vector<std::string> pluginsOnOperatorPath()
{
    std::vector<std::string> files;
    const char* env = std::getenv("LEVELFORGE_OPERATOR_PATH");
    if (!env) return files;
    std::stringstream dirs(env);
    for (std::string dir; std::getline(dirs, dir, ':');) {
        if (dir.empty()) continue;
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) continue;
        std::vector<std::string> here;
        for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
            if (e.path().extension() == ".so" && e.is_regular_file(ec)) here.push_back(e.path().string());
        }
        std::sort(here.begin(), here.end());
        files.insert(files.end(), here.begin(), here.end());
    }
    return files;
}

std::vector<std::string> pluginArguments(const std::vector<std::string>& args)
{
    std::vector<std::string> files;
    for (size_t i = 0; i < args.size(); ++i) {
        if (args[i] == "--plugin" && i + 1 < args.size()) files.push_back(args[++i]);
        else if (args[i].rfind("--plugin=", 0) == 0) files.push_back(args[i].substr(9));
    }
    return files;
}

void loadPlugin(const std::string& path, OperatorRegistry& registry)
{
    const std::string what = "cannot load plugin '" + path + "': ";
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) throw InvalidArgumentError(what + "no such file");
    // dlopen searches the library path for a name without '/': always give it a path
    const std::string file = path.find('/') == std::string::npos ? "./" + path : path;
    // What the plugin declares in its static initialisers (LEVELFORGE_REGISTER_OPERATOR, run by
    // dlopen) goes into this scratch registry too, not straight into the program's: it passes the
    // same checks as what its entry point registers, and a refused plugin adds nothing.
    auto scratch = std::make_unique<OperatorRegistry>();
    void* handle = nullptr;
    std::string staticError;
    {
        const RegistrarCapture capture(*scratch);
        handle = ::dlopen(file.c_str(), RTLD_NOW | RTLD_LOCAL);
        staticError = capture.error();
    }
    if (!handle) {
        const char* e = ::dlerror();
        throw InvalidArgumentError(what + (e ? e : "not a shared library"));
    }
    // Refusing unloads the library, after the scratch registry (whose cook functions live in
    // it) is gone. A plugin that is kept stays loaded for the life of the process.
    const auto refuse = [&](const std::string& why) {
        scratch.reset();
        ::dlclose(handle);
        throw InvalidArgumentError(what + why);
    };
    using InfoFn = const LevelforgePluginInfo* (*)();
    using RegisterFn = void (*)(OperatorRegistry&);
    auto info = reinterpret_cast<InfoFn>(::dlsym(handle, "levelforge_plugin_info"));
    auto reg = reinterpret_cast<RegisterFn>(::dlsym(handle, "levelforge_plugin_register"));
    if (!info || !reg) {
        refuse("it is not a levelforge operator plugin (no levelforge_plugin_info / "
               "levelforge_plugin_register; see OperatorPlugin.h)");
    }
    const LevelforgePluginInfo* pi = info();
    if (!pi) refuse("its levelforge_plugin_info() returned no information");
    const LevelforgePluginInfo host = hostPluginInfo();
    std::string mismatch;
    if (pi->abiVersion != host.abiVersion) {
        mismatch = "operator ABI " + std::to_string(pi->abiVersion) + ", this program has " + std::to_string(host.abiVersion);
    } else if (pi->openvdbAbi != host.openvdbAbi) {
        mismatch = "OpenVDB ABI " + std::to_string(pi->openvdbAbi) + ", this program has " + std::to_string(host.openvdbAbi);
    } else if (pi->sizeofSpec != host.sizeofSpec || pi->sizeofArgs != host.sizeofArgs ||
               pi->sizeofParam != host.sizeofParam) {
        mismatch = "another layout of the operator types (another levelforge version or compiler)";
    }
    if (!mismatch.empty()) refuse("it was built for " + mismatch + "; rebuild it against this levelforge");
    if (!staticError.empty()) refuse(staticError);
    // Register into the scratch registry first: a plugin whose declarations fail adds nothing.
    std::string error;
    try {
        reg(*scratch);
        for (const OperatorSpec* spec : scratch->list()) {
            if (registry.find(spec->name()))
                throw std::logic_error("operator '" + spec->name() + "' is already registered");
        }
    } catch (const std::exception& e) {
        error = e.what();
    }
    // (not unloaded here: the plugin's code may still be on the stack of what threw)
    if (!error.empty()) throw InvalidArgumentError(what + error);
    if (scratch->list().empty()) throw InvalidArgumentError(what + "it registers no operator");
    for (const OperatorSpec* spec : scratch->list()) registry.add(*spec);
}

int loadPlugins(const std::vector<std::string>& args, std::ostream& err)
{
    std::vector<std::string> files = pluginsOnOperatorPath();
    const std::vector<std::string> given = pluginArguments(args);
    files.insert(files.end(), given.begin(), given.end());
    std::vector<std::string> loaded; // the same file twice (path and --plugin) loads once
    for (const std::string& f : files) {
        std::error_code ec;
        const std::string canonical = fs::weakly_canonical(f, ec).string();
        if (std::find(loaded.begin(), loaded.end(), canonical) != loaded.end()) continue;
        loaded.push_back(canonical);
        try {
            loadPlugin(f, OperatorRegistry::global());
        } catch (const std::exception& e) {
            err << "levelforge: error: " << e.what() << std::endl;
            return kExitFailure;
        }
    }
    return 0;
}

} // namespace levelforge::ops
