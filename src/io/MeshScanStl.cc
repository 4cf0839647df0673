// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Pre-scan of STL files (ASCII and binary): every corner coordinate finite; counts facets.
#include "io/MeshIOInternal.h"

#include <limits>

namespace levelforge {

namespace meshio_internal {

/// OpenMesh's rule: a .stl file is binary when its size is 84 + 50 * (facet count in the header).
bool stlIsBinary(const std::string& path, const std::string& ext)
{
    if (ext == ".stlb") return true;
    if (ext == ".stla") return false;
    std::error_code ec;
    const uint64_t size = fs::file_size(path, ec);
    if (ec || size < 84) return false;
    FileReader r(path);
    char header[80];
    uint32_t n = 0;
    if (!r.readBytes(header, 80) || !r.readBytes(&n, 4)) return false;
    if (kHostBigEndian) n = __builtin_bswap32(n);
    return size == 84 + 50 * uint64_t(n);
}

// STL: every corner coordinate finite (a NaN corner in a binary STL is merged away by OpenMesh's
// vertex map and the facet disappears); counts facets.
void prescanStl(const std::string& path, const std::string& ext, Prescan& out)
{
    out.binary = stlIsBinary(path, ext);
    FileReader reader(path);
    if (out.binary) {
        char header[80];
        uint32_t n = 0;
        if (!reader.readBytes(header, 80) || !reader.readBytes(&n, 4)) {
            throwInvalid(path, 0, "truncated binary STL header");
        }
        if (kHostBigEndian) n = __builtin_bswap32(n);
        // Exactly 50 bytes per facet after the 84-byte header.
        const uint64_t remaining = bytesAfter(path, 84);
        const std::string note = 50 * uint64_t(n) > remaining
            ? " (" + headerClaimNote(n, "triangles", remaining) + ", " + std::to_string(50 * uint64_t(n)) +
                  " needed)"
            : std::string();
        unsigned char rec[50];
        for (uint32_t f = 0; f < n; ++f) {
            if (!reader.readBytes(rec, 50)) {
                throwInvalid(path, 0, "the file ends inside facet " + std::to_string(f) + " of " +
                    std::to_string(n) + note);
            }
            for (int c = 0; c < 3; ++c) {
                for (int k = 0; k < 3; ++k) {
                    unsigned char b[4];
                    std::memcpy(b, rec + 12 + 12 * c + 4 * k, 4);
                    if (kHostBigEndian) std::reverse(b, b + 4);
                    float v;
                    std::memcpy(&v, b, 4);
                    if (!std::isfinite(v)) {
                        throwInvalid(path, 0, "facet " + std::to_string(f) + ", corner " +
                            std::to_string(c) + ": non-finite coordinate " + formatDouble(v));
                    }
                }
            }
        }
        out.faces = n;
        out.haveFaces = true;
        return;
    }
    // ASCII: as OpenMesh does, a line containing "outer" starts a facet whose corners are the
    // next three lines ("vertex x y z").
    std::string_view line, rest, tok;
    uint64_t facets = 0;
    while (reader.nextLine(line)) {
        if (line.find("outer") == std::string_view::npos && line.find("OUTER") == std::string_view::npos) {
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            if (!reader.nextLine(line)) {
                throwInvalid(path, reader.lineNumber(), "the file ends inside facet " + std::to_string(facets));
            }
            rest = line;
            nextToken(rest, tok); // "vertex"
            for (int k = 0; k < 3; ++k) {
                double v = 0;
                if (!nextToken(rest, tok)) {
                    throwInvalid(path, reader.lineNumber(), "facet " + std::to_string(facets) +
                        ", corner " + std::to_string(c) + ": expected 'vertex x y z'");
                }
                const NumberStatus st = parseCoordinate(tok, v);
                if (st != NumberStatus::Ok) {
                    throwInvalid(path, reader.lineNumber(), "facet " + std::to_string(facets) +
                        ", corner " + std::to_string(c) + ": " + describeCoordinateProblem(st, tok));
                }
            }
        }
        ++facets;
    }
    if (facets == 0) {
        // Not ASCII STL. A binary STL whose size disagrees with its triangle count is read as
        // ASCII (OpenMesh's rule) and yields nothing: say what its header claims.
        std::error_code ec;
        const uint64_t size = fs::file_size(path, ec);
        FileReader head(path);
        char header[84];
        if (!ec && size >= 84 && head.readBytes(header, 84)) {
            std::string_view start(header, 80);
            while (!start.empty() && isSpace(start.front())) start.remove_prefix(1);
            const bool solid = start.size() >= 5 && io_internal::asciiLower(std::string(start.substr(0, 5))) == "solid";
            uint32_t n = 0;
            std::memcpy(&n, header + 80, 4);
            if (kHostBigEndian) n = __builtin_bswap32(n);
            if (!solid && std::memchr(header, '\0', 84) != nullptr) {
                throwInvalid(path, 0, "not a valid binary STL: " + headerClaimNote(n, "triangles", size - 84) +
                    " (a binary STL holds exactly 50 bytes per triangle after its 84-byte header: " +
                    std::to_string(84 + 50 * uint64_t(n)) + " bytes)");
            }
        }
    }
    out.faces = facets;
    out.haveFaces = true;
}

} // namespace meshio_internal

} // namespace levelforge
