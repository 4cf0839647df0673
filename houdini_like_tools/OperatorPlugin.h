// SPDX-License-Identifier: Apache-2.0
// levelforge — writing a plugin operator: a shared library that adds operators to the
// `levelforge` program through the same declaration API as the built-in ones (Operator.h).
//
//     #include <OperatorPlugin.h>
//     namespace {
//     void cookShell(levelforge::ops::OperatorArgs& args) { ... }
//     void registerOperators(levelforge::ops::OperatorRegistry& registry)
//     {
//         registry.add(levelforge::ops::OperatorSpec("shell", "Hollow a level set")
//                          .input("input", ".vdb level set").output("output", ".vdb file to write")
//                          .param(...).cook(cookShell));
//     }
//     }
//     LEVELFORGE_OPERATOR_PLUGIN("shell-example", registerOperators)
//
// Build it as a MODULE library (see examples/plugins/CMakeLists.txt) and load it with
// `levelforge --plugin FILE <op> ...`, or put it in a directory listed in
// LEVELFORGE_OPERATOR_PATH (colon-separated; every *.so there is loaded at start-up).
//
// The program checks, before it calls anything else in the library, that the plugin was
// compiled against the same operator API: the ABI version below and the layout of the declared
// types (sizes of OperatorSpec, OperatorArgs, Param) and OpenVDB's ABI must match; otherwise the
// plugin is refused with one error naming the file and what differs ("rebuild it").
#pragma once

#include "Operator.h"
#include "OperatorIO.h"
#include "OperatorRegistry.h"

#include <openvdb/version.h>

#include <cstdint>

/// Bumped whenever Operator.h, OperatorIO.h or OperatorRegistry.h change incompatibly.
#define LEVELFORGE_OPERATOR_ABI_VERSION 1

extern "C" {
/// What a plugin was built against; returned by its levelforge_plugin_info().
struct LevelforgePluginInfo
{
    int32_t abiVersion;      ///< LEVELFORGE_OPERATOR_ABI_VERSION
    int32_t openvdbAbi;      ///< OPENVDB_ABI_VERSION_NUMBER
    uint32_t sizeofSpec;     ///< sizeof(OperatorSpec)
    uint32_t sizeofArgs;     ///< sizeof(OperatorArgs)
    uint32_t sizeofParam;    ///< sizeof(Param)
    const char* name;        ///< the plugin's name, for messages
};
}

namespace levelforge::ops {
/// The info of the program itself, compared with a plugin's.
inline LevelforgePluginInfo hostPluginInfo(const char* name = "levelforge")
{
    return LevelforgePluginInfo{LEVELFORGE_OPERATOR_ABI_VERSION, OPENVDB_ABI_VERSION_NUMBER,
                                uint32_t(sizeof(OperatorSpec)), uint32_t(sizeof(OperatorArgs)),
                                uint32_t(sizeof(Param)), name};
}
} // namespace levelforge::ops

/// Defines the two entry points of a plugin: levelforge_plugin_info() and
/// levelforge_plugin_register(registry), which calls @p registerFunction.
#define LEVELFORGE_OPERATOR_PLUGIN(pluginName, registerFunction)                                   \
    extern "C" __attribute__((visibility("default"))) const LevelforgePluginInfo*                  \
    levelforge_plugin_info()                                                                      \
    {                                                                                             \
        static const LevelforgePluginInfo info = ::levelforge::ops::hostPluginInfo(pluginName);   \
        return &info;                                                                             \
    }                                                                                             \
    extern "C" __attribute__((visibility("default"))) void levelforge_plugin_register(            \
        ::levelforge::ops::OperatorRegistry& registry)                                            \
    {                                                                                             \
        registerFunction(registry);                                                               \
    }
