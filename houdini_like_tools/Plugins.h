// SPDX-License-Identifier: Apache-2.0
// levelforge — loading plugin operators (see OperatorPlugin.h for writing one).
#pragma once

#include "OperatorRegistry.h"

#include <iosfwd>
#include <string>
#include <vector>

namespace levelforge::ops {

/// The plugin files of LEVELFORGE_OPERATOR_PATH: every regular `*.so` file of each listed
/// directory (colon-separated; empty entries and missing directories are skipped), sorted by
/// name within a directory, directories in the order listed.
std::vector<std::string> pluginsOnOperatorPath();

/// @brief Loads the plugin @p path and adds its operators to @p registry.
/// @throws InvalidArgumentError naming the file when it cannot be loaded (not a shared library,
///         unresolved symbols), lacks the entry points, was built against another operator API
///         (ABI version, type layouts, OpenVDB ABI), or declares an operator wrongly or under a
///         name that is taken. A refused plugin adds no operator.
void loadPlugin(const std::string& path, OperatorRegistry& registry);

/// The `--plugin FILE` / `--plugin=FILE` values of a command line, in order.
std::vector<std::string> pluginArguments(const std::vector<std::string>& args);

/// @brief Loads the plugins of LEVELFORGE_OPERATOR_PATH, then those of the `--plugin` options
///        of @p args, into OperatorRegistry::global() (main() calls it before runCli()).
/// @return 0, or kExitFailure after printing one "levelforge: error: ..." line on @p err
int loadPlugins(const std::vector<std::string>& args, std::ostream& err);

} // namespace levelforge::ops
