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

// Attributes: vertex colours (`v x y z r g b`), `vt` and `vn` tables referenced per face corner.
// Runs only when attributes are asked for (or listed), after the mesh itself was read and
// checked, so positions and vertex indices are known to be valid here.
void scanObjAttributes(const std::string& path, const std::vector<std::string>& want, AttributeScan& out)
{
    const auto wanted = [&](const char* n) { return std::find(want.begin(), want.end(), n) != want.end(); };
    const bool wantCd = wanted("Cd"), wantN = wanted("N"), wantUv = wanted("uv");
    const bool wantCorners = wantN || wantUv;
    FileReader reader(path);
    std::string_view line, rest, tok;
    uint64_t vertexCount = 0, faceCount = 0;
    bool anyColour = false, anyVt = false, anyVn = false;
    int64_t firstWithoutColour = -1;
    uint64_t firstWithoutColourLine = 0;
    std::vector<float> colours, vt, vn;
    std::vector<int32_t> uvCorner, nCorner;
    out.faceStart.clear();
    out.cornerVertex.clear();
    if (wantCorners) out.faceStart.push_back(0);
    int64_t vtCount = 0, vnCount = 0;
    struct Corner { int32_t v, t, n; };
    std::vector<Corner> corners;
    std::string missingCorner[2]; // uv, N: the first corner without the index
    uint64_t missingLine[2] = {0, 0};
    const auto readFloats = [&](std::string_view r, float* dst, int maxCount) {
        int n = 0;
        std::string_view t;
        while (n < maxCount && nextToken(r, t)) {
            if (t[0] == '#') break;
            double d = 0.0;
            if (parseCoordinate(t, d) != NumberStatus::Ok) {
                throwInvalid(path, reader.lineNumber(), "cannot parse attribute value " + message_internal::quotedExcerpt(t));
            }
            dst[n++] = float(d);
        }
        return n;
    };
    while (reader.nextLine(line)) {
        rest = line;
        if (!nextToken(rest, tok) || tok[0] == '#') continue;
        if (tok == "v") {
            float c[7];
            const int n = readFloats(rest, c, 7);
            const bool hasColour = n >= 6;
            anyColour = anyColour || hasColour;
            if (wantCd) {
                colours.insert(colours.end(), {hasColour ? c[3] : 0.0f, hasColour ? c[4] : 0.0f, hasColour ? c[5] : 0.0f});
                if (!hasColour && firstWithoutColour < 0) {
                    firstWithoutColour = int64_t(vertexCount);
                    firstWithoutColourLine = reader.lineNumber();
                }
            }
            ++vertexCount;
        } else if (tok == "vt") {
            anyVt = true;
            ++vtCount;
            if (wantUv) {
                float c[3] = {0.0f, 0.0f, 0.0f};
                if (readFloats(rest, c, 3) < 1) {
                    throwInvalid(path, reader.lineNumber(), "texture coordinate " + std::to_string(vtCount - 1) +
                        " has no value");
                }
                vt.insert(vt.end(), c, c + 3);
            }
        } else if (tok == "vn") {
            anyVn = true;
            ++vnCount;
            if (wantN) {
                float c[3];
                if (readFloats(rest, c, 3) != 3) {
                    throwInvalid(path, reader.lineNumber(), "normal " + std::to_string(vnCount - 1) +
                        " has fewer than 3 components");
                }
                vn.insert(vn.end(), c, c + 3);
            }
        } else if (tok == "f" && wantCorners) {
            corners.clear();
            while (nextToken(rest, tok)) {
                if (tok[0] == '#') break;
                long long idx[3] = {0, 0, 0};
                std::string_view part = tok;
                for (int k = 0; k < 3; ++k) {
                    const size_t slash = part.find('/');
                    const std::string_view field = part.substr(0, slash);
                    if (!field.empty()) {
                        const char* b = field.data();
                        const char* e = b + field.size();
                        if (*b == '+') ++b;
                        const auto r = std::from_chars(b, e, idx[k]);
                        if (r.ec != std::errc() || r.ptr != e) {
                            throwInvalid(path, reader.lineNumber(), "face " + std::to_string(faceCount) +
                                ": cannot parse corner " + message_internal::quotedExcerpt(tok));
                        }
                    }
                    if (slash == std::string_view::npos) break;
                    part.remove_prefix(slash + 1);
                }
                const int64_t counts[3] = {int64_t(vertexCount), vtCount, vnCount};
                int32_t resolved[3];
                for (int k = 0; k < 3; ++k) {
                    long long r = idx[k] < 0 ? counts[k] + idx[k] + 1 : idx[k];
                    if (idx[k] != 0 && (r < 1 || (k > 0 && r > counts[k]))) {
                        throwInvalid(path, reader.lineNumber(), "face " + std::to_string(faceCount) + ": " +
                            (k == 1 ? "texture coordinate" : "normal") + " index " + std::to_string(idx[k]) +
                            " is out of range (the file has " + std::to_string(counts[k]) + " before this line)");
                    }
                    resolved[k] = idx[k] == 0 ? -1 : int32_t(r - 1);
                }
                bool repeated = false; // OpenMesh keeps the first of repeated corners
                for (const Corner& c : corners) repeated = repeated || c.v == resolved[0];
                if (!repeated) corners.push_back({resolved[0], resolved[1], resolved[2]});
            }
            if (corners.size() >= 3) {
                for (size_t j = 0; j < corners.size(); ++j) {
                    const Corner& c = corners[j];
                    // reported after the names are checked (a file without any vn has no 'N')
                    for (int a = 0; a < 2; ++a) {
                        const bool missing = a == 0 ? wantUv && c.t < 0 : wantN && c.n < 0;
                        if (!missing || !missingCorner[a].empty()) continue;
                        missingLine[a] = reader.lineNumber();
                        missingCorner[a] = "face " + std::to_string(faceCount) + " corner " + std::to_string(j) +
                            " has no " + (a == 0 ? "texture coordinate (v/vt)" : "normal (v//vn)") +
                            " index, which attribute '" + (a == 0 ? "uv" : "N") + "' needs at every corner";
                    }
                    out.cornerVertex.push_back(c.v);
                    if (wantUv) uvCorner.push_back(c.t);
                    if (wantN) nCorner.push_back(c.n);
                }
                out.faceStart.push_back(out.cornerVertex.size());
            }
            ++faceCount;
        }
    }
    out.available.clear();
    if (anyColour) out.available.push_back("Cd");
    if (anyVn) out.available.push_back("N");
    if (anyVt) out.available.push_back("uv");
    out.sources.clear();
    for (const std::string& name : want) {
        if (std::find(out.available.begin(), out.available.end(), name) == out.available.end()) {
            throwNoAttribute(path, name, out.available);
        }
        AttributeSource src;
        src.name = name;
        src.components = 3;
        if (name == "Cd") {
            if (firstWithoutColour >= 0) {
                throwInvalid(path, firstWithoutColourLine, "vertex " + std::to_string(firstWithoutColour) +
                    " has no colour (v x y z r g b), which attribute 'Cd' needs at every vertex");
            }
            src.values = colours;
        } else if (name == "N") {
            if (!missingCorner[1].empty()) throwInvalid(path, missingLine[1], missingCorner[1]);
            src.perVertex = false;
            src.values = vn;
            src.cornerIndex = nCorner;
        } else {
            if (!missingCorner[0].empty()) throwInvalid(path, missingLine[0], missingCorner[0]);
            src.perVertex = false;
            src.values = vt;
            src.cornerIndex = uvCorner;
        }
        out.sources.push_back(std::move(src));
    }
}

} // namespace meshio_internal

} // namespace levelforge
