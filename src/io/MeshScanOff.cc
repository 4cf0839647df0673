// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Pre-scan of OFF files (ASCII and OpenMesh's binary layout): header, counts, coordinates
///        and face indices checked against the data.
#include "io/MeshIOInternal.h"

#include <limits>

namespace levelforge {

namespace meshio_internal {

// OFF (binary, OpenMesh's layout: little-endian uint32 counts, float32 coordinates, uint32
// corner counts and indices). OpenMesh trusts the counts (its face loop does not stop at the end
// of the file), so they are checked against the data here.
void prescanBinaryOff(const std::string& path, FileReader& reader, bool extras, Prescan& out)
{
    auto readU32 = [&](uint32_t& v) {
        unsigned char b[4];
        if (!reader.readBytes(b, 4)) return false;
        v = uint32_t(b[0]) | (uint32_t(b[1]) << 8) | (uint32_t(b[2]) << 16) | (uint32_t(b[3]) << 24);
        return true;
    };
    uint32_t nV = 0, nF = 0, nE = 0;
    if (!readU32(nV) || !readU32(nF) || !readU32(nE)) throwInvalid(path, 0, "truncated binary OFF header");
    if (nV > uint32_t(std::numeric_limits<int>::max()) || nF > uint32_t(std::numeric_limits<int>::max())) {
        throwInvalid(path, 0, "binary OFF vertex or face count too large");
    }
    // Exact bytes: 12 per vertex, at least 4 (the corner count) per face.
    const uint64_t remaining = bytesAfter(path, reader.offset());
    std::string note;
    if (12 * uint64_t(nV) > remaining) note = " (" + headerClaimNote(nV, "vertices", remaining) + ")";
    else if (12 * uint64_t(nV) + 4 * uint64_t(nF) > remaining) note = " (" + headerClaimNote(nF, "faces", remaining) + ")";
    if (extras) {
        // Colours / normals / texture coordinates: only make sure the counts are plausible.
        std::error_code ec;
        const uint64_t size = fs::file_size(path, ec);
        if (!ec && size < 12 * uint64_t(nV) + 4 * uint64_t(nF)) {
            throwInvalid(path, 0, "binary OFF is shorter than its " + std::to_string(nV) +
                " vertices and " + std::to_string(nF) + " faces" + note);
        }
        return;
    }
    for (uint32_t v = 0; v < nV; ++v) {
        for (int k = 0; k < 3; ++k) {
            uint32_t bits = 0;
            if (!readU32(bits)) {
                throwInvalid(path, 0, "the file ends inside vertex " + std::to_string(v) + " of " +
                    std::to_string(nV) + note);
            }
            float x;
            std::memcpy(&x, &bits, 4);
            if (!std::isfinite(x)) {
                throwInvalid(path, 0, "vertex " + std::to_string(v) + ": non-finite coordinate " +
                    formatDouble(x));
            }
        }
    }
    for (uint32_t f = 0; f < nF; ++f) {
        uint32_t corners = 0;
        if (!readU32(corners)) {
            throwInvalid(path, 0, "the file ends before face " + std::to_string(f) + " of " +
                std::to_string(nF) + note);
        }
        for (uint32_t c = 0; c < corners; ++c) {
            uint32_t idx = 0;
            if (!readU32(idx)) throwInvalid(path, 0, "the file ends inside face " + std::to_string(f) + note);
            if (idx >= nV) {
                throwInvalid(path, 0, "face " + std::to_string(f) + ": vertex index " +
                    std::to_string(idx) + " is out of range (the file has " + std::to_string(nV) +
                    " vertices, numbered from 0)");
            }
        }
    }
    out.faces = nF;
    out.haveFaces = true;
}

// OFF (ASCII): header counts, then vertices and faces read the way OpenMesh reads them (three
// numbers then the rest of the line per vertex; a count and that many indices per face).
void prescanOff(const std::string& path, Prescan& out)
{
    FileReader reader(path);
    std::string_view header;
    if (!reader.nextLine(header)) throwInvalid(path, 0, "the file is empty");
    header = trimmed(header);

    // [ST][C][N][4][n]OFF [BINARY]
    std::string_view p = header;
    bool hasTex = false, hasColor = false, hasNormal = false, higherDim = false;
    if (p.substr(0, 2) == "ST") { hasTex = true; p.remove_prefix(2); }
    if (p.substr(0, 1) == "C") { hasColor = true; p.remove_prefix(1); }
    if (p.substr(0, 1) == "N") { hasNormal = true; p.remove_prefix(1); }
    if (p.substr(0, 1) == "4") { higherDim = true; p.remove_prefix(1); }
    if (p.substr(0, 1) == "n") { higherDim = true; p.remove_prefix(1); }
    if (p.substr(0, 3) != "OFF") {
        throwInvalid(path, 1, "not an OFF file: the first line is " + message_internal::quotedExcerpt(header) +
            ", expected 'OFF' (optionally prefixed by ST, C, N)");
    }
    p.remove_prefix(3);
    std::string_view extra = trimmed(p);
    if (extra.substr(0, 6) == "BINARY") {
        out.binary = true;
        prescanBinaryOff(path, reader, hasTex || hasColor || hasNormal || higherDim, out);
        return;
    }
    if (!extra.empty()) {
        throwInvalid(path, 1, "the OFF header line must hold only the keyword (OpenMesh reads the "
            "counts from the next line), found " + message_internal::quotedExcerpt(header));
    }
    if (higherDim) return; // let OpenMesh decide about 4OFF / nOFF
    (void)hasTex;

    TokenReader tokens(reader);
    std::string_view tok;
    uint64_t counts[3] = {0, 0, 0};
    const char* countNames[3] = {"vertex count", "face count", "edge count"};
    for (int i = 0; i < 3; ++i) {
        if (!tokens.next(tok)) throwInvalid(path, tokens.line(), std::string("missing ") + countNames[i]);
        long long signedCount = 0;
        if (parseInteger(tok, signedCount) && signedCount < 0) {
            // OpenMesh reads the counts as unsigned int: -1 would become 4294967295.
            throwInvalid(path, tokens.line(), std::string("negative ") + countNames[i] + " " +
                message_internal::quotedExcerpt(tok));
        }
        if (!parseInteger(tok, counts[i])) {
            throwInvalid(path, tokens.line(), std::string("cannot parse the ") + countNames[i] +
                " " + message_internal::quotedExcerpt(tok) + (tok[0] == '#' ? " (OpenMesh's OFF reader does not accept "
                "comments)" : ""));
        }
    }
    const uint64_t nV = counts[0], nF = counts[1];
    if (nV > uint64_t(std::numeric_limits<int>::max()) || nF > uint64_t(std::numeric_limits<int>::max())) {
        throwInvalid(path, tokens.line(), "vertex or face count too large");
    }
    // No skipRestOfLine() here: OpenMesh reads the three counts with operator>> and goes on
    // reading the same stream, so whatever follows them on their line is the first vertex (or,
    // with no vertices, the first face's corner count). Skipping it here made the pre-scan check
    // a different face list than the one OpenMesh then read ("OFF\n0 1 0 -2\n0\n": OpenMesh
    // took -2 as the first face's corner count, 4294967294 as unsigned, and pushed corners until
    // memory ran out).

    // At least two bytes per number (a digit and a separator; one less at the very end): a
    // header that claims more than the file can hold allocates only what the file can hold and
    // its count is named when the data runs out.
    const uint64_t perVertex = hasNormal ? 6 : 3;
    const uint64_t remaining = bytesAfter(path, reader.offset());
    std::string note;
    if (2 * perVertex * nV > remaining + 1) {
        note = " (" + headerClaimNote(nV, "vertices", remaining) + ")";
    } else if (2 * (perVertex * nV + nF) > remaining + 1) {
        note = " (" + headerClaimNote(nF, "faces", remaining) + ")";
    }
    out.points.clear();
    out.points.reserve(size_t(std::min<uint64_t>(nV, remaining / (2 * perVertex) + 1)));
    for (uint64_t v = 0; v < nV; ++v) {
        Vec3d q(0.0);
        for (int k = 0; k < (hasNormal ? 6 : 3); ++k) {
            if (!tokens.next(tok)) {
                throwInvalid(path, tokens.line(), "the file ends inside vertex " + std::to_string(v) +
                    " of " + std::to_string(nV) + note);
            }
            double value = 0;
            const NumberStatus st = parseCoordinate(tok, value);
            if (st != NumberStatus::Ok) {
                throwInvalid(path, tokens.line(), "vertex " + std::to_string(v) + ": " +
                    (k < 3 ? describeCoordinateProblem(st, tok) : "cannot parse normal " + message_internal::quotedExcerpt(tok)));
            }
            if (k < 3) q[k] = value;
        }
        out.points.push_back(q);
        tokens.skipRestOfLine(); // colours / texture coordinates
    }
    for (uint64_t f = 0; f < nF; ++f) {
        if (!tokens.next(tok)) {
            throwInvalid(path, tokens.line(), "the file ends before face " + std::to_string(f) +
                " of " + std::to_string(nF) + note);
        }
        // OpenMesh reads the corner count as unsigned int and pushes that many indices, whatever
        // the file holds: a negative count (-2 -> 4294967294) or one beyond what the rest of the
        // file can hold (an index and a separator are at least two bytes) is refused here.
        long long signedCorners = 0;
        if (parseInteger(tok, signedCorners) && signedCorners < 0) {
            throwInvalid(path, tokens.line(), "face " + std::to_string(f) + ": negative corner count " +
                message_internal::quotedExcerpt(tok));
        }
        uint32_t corners = 0;
        if (!parseInteger(tok, corners)) {
            throwInvalid(path, tokens.line(), "face " + std::to_string(f) +
                ": cannot parse the corner count " + message_internal::quotedExcerpt(tok));
        }
        if (uint64_t(corners) > remaining / 2 + 1) {
            throwInvalid(path, tokens.line(), "face " + std::to_string(f) + ": corner count " +
                std::to_string(corners) + " is more than the " + std::to_string(remaining) +
                " bytes after the header can hold");
        }
        for (uint32_t c = 0; c < corners; ++c) {
            if (!tokens.next(tok)) {
                throwInvalid(path, tokens.line(), "the file ends inside face " + std::to_string(f) + note);
            }
            long long idx = 0;
            if (!parseInteger(tok, idx)) {
                throwInvalid(path, tokens.line(), "face " + std::to_string(f) +
                    ": cannot parse vertex index " + message_internal::quotedExcerpt(tok));
            }
            if (idx < 0 || uint64_t(idx) >= nV) {
                throwInvalid(path, tokens.line(), "face " + std::to_string(f) + ": vertex index " +
                    std::to_string(idx) + " is out of range (the file has " + std::to_string(nV) +
                    " vertices, numbered from 0)");
            }
        }
        if (hasColor) tokens.skipRestOfLine();
    }
    out.faces = nF;
    out.haveFaces = true;
    out.havePoints = true;
}

} // namespace meshio_internal

} // namespace levelforge
