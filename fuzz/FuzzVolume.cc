// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target volume: readVolume() on a path without a known extension, so that the
///        format is chosen from the content (NIfTI-1, INRIMAGE-4 or VDB magic, gzip recognised
///        by its magic bytes) and the chosen reader runs; sample limit kMaxFuzzVoxels. Checks
///        what VolumeIO.h promises of every volume it returns.
#include "FuzzCommon.h"

LF_FUZZ_TARGET(volume)
{
    using namespace levelforge;
    fuzz::TempFile file(data, size, ".img");
    return fuzz::runGuarded([&] {
        VolumeInfo info;
        const ScalarVolume vol = readVolume(file.path(), fuzz::fuzzVolumeOptions(), &info);
        fuzz::checkVolumePromises(vol, "readVolume");
    });
}
