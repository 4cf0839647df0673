// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target den: readDen() on VolPack / UNC .den density maps, plain or
///        gzip-compressed (either byte order), with a sample limit of kMaxFuzzVoxels; checks what
///        VolumeIO.h promises of every volume it returns.
#include "FuzzCommon.h"

LF_FUZZ_TARGET(den)
{
    using namespace levelforge;
    fuzz::TempFile file(data, size, ".den");
    return fuzz::runGuarded([&] {
        VolumeInfo info;
        const ScalarVolume vol = readDen(file.path(), fuzz::fuzzVolumeOptions(), &info);
        fuzz::checkVolumePromises(vol, "readDen");
    });
}
