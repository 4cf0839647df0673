// SPDX-License-Identifier: Apache-2.0
// A shared library that is not a levelforge plugin (no entry points), for the plugin tests.
extern "C" __attribute__((visibility("default"))) int levelforge_not_a_plugin() { return 42; }
