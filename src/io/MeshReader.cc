// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief The parts of the mesh readers every format shares: the buffered FileReader and the
///        helpers of error messages.
#include "io/MeshIOInternal.h"

namespace levelforge {

namespace meshio_internal {

std::string formatPoint(const Vec3d& p)
{
    return "(" + formatDouble(p[0]) + ", " + formatDouble(p[1]) + ", " + formatDouble(p[2]) + ")";
}

[[noreturn]] void throwInvalid(const std::string& path, uint64_t line, const std::string& what)
{
    std::string msg = path + ": ";
    if (line > 0) msg += "line " + std::to_string(line) + ": ";
    throw InvalidMeshError(msg + what);
}

std::string describeCoordinateProblem(NumberStatus st, std::string_view tok)
{
    switch (st) {
    case NumberStatus::NotANumber: return "cannot parse coordinate " + message_internal::quotedExcerpt(tok);
    case NumberStatus::NonFinite: return "non-finite coordinate " + message_internal::quotedExcerpt(tok);
    case NumberStatus::OutOfFloatRange:
        return "coordinate " + message_internal::quotedExcerpt(tok) + " is beyond the single-precision range";
    case NumberStatus::Ok: break;
    }
    return "bad coordinate " + message_internal::quotedExcerpt(tok);
}

[[noreturn]] void throwNoAttribute(const std::string& path, const std::string& name,
                                   const std::vector<std::string>& available)
{
    std::string has;
    for (const std::string& a : available) has += (has.empty() ? "" : ", ") + a;
    throw InvalidArgumentError(path + ": no vertex attribute " + message_internal::quotedExcerpt(name) + " (" +
                               (has.empty() ? std::string("it has none") : "it has: " + has) + ")");
}

uint64_t bytesAfter(const std::string& path, uint64_t offset)
{
    std::error_code ec;
    const uint64_t size = fs::file_size(path, ec);
    return ec || size < offset ? 0 : size - offset;
}

std::string headerClaimNote(uint64_t count, const std::string& what, uint64_t bytes)
{
    return "the header claims " + std::to_string(count) + " " + what + " but the file holds only " +
           std::to_string(bytes) + " bytes after the header";
}

FileReader::FileReader(const std::string& path) : mPath(path)
{
    mFile = std::fopen(path.c_str(), "rb");
    if (!mFile) {
        throw IoError("cannot open mesh file '" + path + "': " + std::strerror(errno));
    }
    mBuf.resize(size_t(1) << 20);
}

FileReader::~FileReader()
{
    if (mFile) std::fclose(mFile);
}

void FileReader::refill()
{
    const size_t avail = mEnd - mBegin;
    if (mBegin > 0) {
        std::memmove(mBuf.data(), mBuf.data() + mBegin, avail);
        mFileOffset += mBegin;
        mBegin = 0;
        mEnd = avail;
    }
    if (mEnd == mBuf.size()) mBuf.resize(mBuf.size() * 2); // a line longer than the buffer
    const size_t got = std::fread(mBuf.data() + mEnd, 1, mBuf.size() - mEnd, mFile);
    mEnd += got;
    if (got == 0) {
        if (std::ferror(mFile)) {
            throw IoError("error reading mesh file '" + mPath + "': " + std::strerror(errno));
        }
        mEof = true;
    }
}

} // namespace meshio_internal

} // namespace levelforge
