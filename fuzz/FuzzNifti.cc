// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Fuzz target nifti: readNifti() on NIfTI-1 single files, plain or gzip-compressed
///        (either byte order, every datatype, qform / sform, scl_slope), with a sample limit of
///        kMaxFuzzVoxels; checks what VolumeIO.h promises of every volume it returns.
#include "FuzzCommon.h"

LF_FUZZ_TARGET(nifti)
{
    using namespace levelforge;
    fuzz::TempFile file(data, size, ".nii");
    return fuzz::runGuarded([&] {
        VolumeInfo info;
        const ScalarVolume vol = readNifti(file.path(), fuzz::fuzzVolumeOptions(), &info);
        fuzz::checkVolumePromises(vol, "readNifti");
    });
}
