// SPDX-License-Identifier: Apache-2.0
// A plugin built for another operator ABI (tests/tools/TestCliPipelines.cc): it must be refused
// with a clear error before its register function is called.
#include <OperatorPlugin.h>

#include <cstdlib>

extern "C" __attribute__((visibility("default"))) const LevelforgePluginInfo* levelforge_plugin_info()
{
    static LevelforgePluginInfo info = levelforge::ops::hostPluginInfo("wrong-abi");
    info.abiVersion = LEVELFORGE_OPERATOR_ABI_VERSION + 998;
    return &info;
}

extern "C" __attribute__((visibility("default"))) void levelforge_plugin_register(levelforge::ops::OperatorRegistry&)
{
    std::abort(); // never called: the program refuses the plugin first
}
