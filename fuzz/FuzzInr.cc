// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target inr: readInr() on INRIMAGE-4 images, plain or gzip-compressed, with a
///        sample limit of kMaxFuzzVoxels; checks what VolumeIO.h promises of every volume it
///        returns.
#include "FuzzCommon.h"

LF_FUZZ_TARGET(inr)
{
    using namespace levelforge;
    fuzz::TempFile file(data, size, ".inr");
    return fuzz::runGuarded([&] {
        VolumeInfo info;
        const ScalarVolume vol = readInr(file.path(), fuzz::fuzzVolumeOptions(), &info);
        fuzz::checkVolumePromises(vol, "readInr");
    });
}
