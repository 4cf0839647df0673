// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Pre-scan of OBJ files: every vertex parses, every face corner names a vertex.
#include "io/MeshIOInternal.h"

#include <limits>

namespace levelforge {

namespace meshio_internal {

// OBJ: every 'v' must carry three parseable, finite coordinates (OpenMesh silently skips the
// vertex otherwise, which shifts every later index); every 'f' corner must name an existing
// vertex (OpenMesh passes out-of-range indices on as invalid handles).
void prescanObj(const std::string& path, Prescan& out)
{
    FileReader reader(path);
    std::string_view line, rest, tok;
    uint64_t vertexCount = 0, faceCount = 0;

    // Faces that refer to vertices not yet defined (legal in OBJ when they come later).
    struct ForwardRef { uint64_t face, line; long long index; };
    std::vector<ForwardRef> forward;

    out.points.clear();
    while (reader.nextLine(line)) {
        rest = line;
        if (!nextToken(rest, tok) || tok[0] == '#') continue;
        if (tok == "v") {
            Vec3d p;
            for (int k = 0; k < 3; ++k) {
                if (!nextToken(rest, tok)) {
                    throwInvalid(path, reader.lineNumber(),
                        "vertex " + std::to_string(vertexCount) + " has fewer than 3 coordinates");
                }
                const NumberStatus st = parseCoordinate(tok, p[k]);
                if (st != NumberStatus::Ok) {
                    throwInvalid(path, reader.lineNumber(), "vertex " + std::to_string(vertexCount) +
                        ": " + describeCoordinateProblem(st, tok));
                }
            }
            out.points.push_back(p);
            ++vertexCount;
        } else if (tok == "f") {
            long long maxIndex = 0;
            int corners = 0;
            while (nextToken(rest, tok)) {
                if (tok[0] == '#') break; // trailing comment
                const std::string_view idxPart = tok.substr(0, tok.find('/'));
                long long idx = 0;
                const char* b = idxPart.data();
                const char* e = b + idxPart.size();
                if (b != e && *b == '+') ++b;
                const auto r = std::from_chars(b, e, idx);
                if (idxPart.empty() || r.ec != std::errc() || r.ptr == b) {
                    throwInvalid(path, reader.lineNumber(), "face " + std::to_string(faceCount) +
                        ": cannot parse corner " + message_internal::quotedExcerpt(tok));
                }
                long long resolved = idx;
                if (idx < 0) resolved = (long long)vertexCount + idx + 1; // relative index
                if (idx == 0 || resolved < 1) {
                    throwInvalid(path, reader.lineNumber(), "face " + std::to_string(faceCount) +
                        ": vertex index " + std::to_string(idx) + " is out of range (the file has " +
                        std::to_string(vertexCount) + " vertices before this line; OBJ indices "
                        "start at 1)");
                }
                maxIndex = std::max(maxIndex, resolved);
                ++corners;
            }
            if (corners > 0 && maxIndex > (long long)vertexCount) {
                forward.push_back({faceCount, reader.lineNumber(), maxIndex});
            }
            ++faceCount;
        }
    }
    for (const ForwardRef& f : forward) {
        if (f.index > (long long)vertexCount) {
            throwInvalid(path, f.line, "face " + std::to_string(f.face) + ": vertex index " +
                std::to_string(f.index) + " is out of range (the file has " +
                std::to_string(vertexCount) + " vertices; OBJ indices start at 1)");
        }
    }
    out.faces = faceCount;
    out.haveFaces = true;
    out.havePoints = true;
}

} // namespace meshio_internal

} // namespace levelforge
