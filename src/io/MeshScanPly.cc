// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief Pre-scan of PLY files (ASCII and binary): the header, then every element; checks vertex
///        x/y/z and the face index lists, keeps exact positions.
#include "io/MeshIOInternal.h"

#include <limits>

namespace levelforge {

namespace meshio_internal {

// PLY (ASCII and binary): header, then every element in order; checks vertex x/y/z and the
// face index lists, keeps exact positions.
PlyType plyType(std::string_view s)
{
    if (s == "char" || s == "int8") return PlyType::Int8;
    if (s == "uchar" || s == "uint8") return PlyType::UInt8;
    if (s == "short" || s == "int16") return PlyType::Int16;
    if (s == "ushort" || s == "uint16") return PlyType::UInt16;
    if (s == "int" || s == "int32") return PlyType::Int32;
    if (s == "uint" || s == "uint32") return PlyType::UInt32;
    if (s == "float" || s == "float32") return PlyType::Float32;
    if (s == "double" || s == "float64") return PlyType::Float64;
    return PlyType::Invalid;
}

size_t plySize(PlyType t)
{
    switch (t) {
    case PlyType::Int8: case PlyType::UInt8: return 1;
    case PlyType::Int16: case PlyType::UInt16: return 2;
    case PlyType::Int32: case PlyType::UInt32: case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
    case PlyType::Invalid: break;
    }
    return 0;
}

struct PlyProperty
{
    std::string name;
    bool isList = false;
    PlyType type = PlyType::Invalid;      ///< value type (list item type for lists)
    PlyType countType = PlyType::Invalid; ///< list count type
};

struct PlyElement
{
    std::string name;
    uint64_t count = 0;
    std::vector<PlyProperty> props;
};

enum class PlyFormat { Ascii, BinaryLE, BinaryBE };

/// Reads one PLY value (binary) as double.
bool readPlyBinary(FileReader& r, PlyType t, bool swap, double& out)
{
    unsigned char b[8];
    const size_t n = plySize(t);
    if (!r.readBytes(b, n)) return false;
    if (swap) std::reverse(b, b + n);
    switch (t) {
    case PlyType::Int8: { int8_t v; std::memcpy(&v, b, 1); out = v; break; }
    case PlyType::UInt8: { uint8_t v; std::memcpy(&v, b, 1); out = v; break; }
    case PlyType::Int16: { int16_t v; std::memcpy(&v, b, 2); out = v; break; }
    case PlyType::UInt16: { uint16_t v; std::memcpy(&v, b, 2); out = v; break; }
    case PlyType::Int32: { int32_t v; std::memcpy(&v, b, 4); out = v; break; }
    case PlyType::UInt32: { uint32_t v; std::memcpy(&v, b, 4); out = v; break; }
    case PlyType::Float32: { float v; std::memcpy(&v, b, 4); out = v; break; }
    case PlyType::Float64: { std::memcpy(&out, b, 8); break; }
    case PlyType::Invalid: return false;
    }
    return true;
}

/// Reads the header of a PLY file (the reader stops after 'end_header'); throws InvalidMeshError
/// naming the line for anything OpenMesh would misread.
void readPlyHeader(const std::string& path, FileReader& reader, PlyFormat& format, std::vector<PlyElement>& elements)
{
    std::string_view line, rest, tok;
    if (!reader.nextLine(line)) throwInvalid(path, 0, "the file is empty");
    if (trimmed(line) != "ply") {
        throwInvalid(path, 1, "not a PLY file: the first line is " + message_internal::quotedExcerpt(trimmed(line)) +
            ", expected 'ply'");
    }
    format = PlyFormat::Ascii;
    bool haveFormat = false, ended = false;
    elements.clear();
    // OpenMesh parses the header token by token across lines and loops forever when a line has
    // a token too few or a non-number where it expects one: check every line exactly.
    std::string_view t[6];
    while (reader.nextLine(line)) {
        rest = line;
        if (!nextToken(rest, t[0])) continue;
        if (t[0] == "comment" || t[0] == "obj_info") continue;
        int n = 1;
        while (n < 6 && nextToken(rest, t[n])) ++n;
        if (n == 6 || nextToken(rest, tok)) n = 7; // too many
        auto malformed = [&](const char* expected) {
            throwInvalid(path, reader.lineNumber(), "malformed PLY header line " + message_internal::quotedExcerpt(trimmed(line)) +
                ", expected '" + expected + "'");
        };
        if (t[0] == "end_header") {
            if (n != 1) malformed("end_header");
            ended = true;
            break;
        }
        if (t[0] == "format") {
            double version = 0;
            if (n != 3 || parseCoordinate(t[2], version) != NumberStatus::Ok) {
                malformed("format ascii|binary_little_endian|binary_big_endian 1.0");
            }
            if (t[1] == "ascii") format = PlyFormat::Ascii;
            else if (t[1] == "binary_little_endian") format = PlyFormat::BinaryLE;
            else if (t[1] == "binary_big_endian") format = PlyFormat::BinaryBE;
            else throwInvalid(path, reader.lineNumber(), "unknown PLY format " + message_internal::quotedExcerpt(t[1]));
            haveFormat = true;
        } else if (t[0] == "element") {
            PlyElement e;
            if (n != 3 || !parseInteger(t[2], e.count) ||
                e.count > uint64_t(std::numeric_limits<int>::max())) {
                malformed("element <name> <count>");
            }
            e.name = std::string(t[1]);
            elements.push_back(std::move(e));
        } else if (t[0] == "property") {
            if (elements.empty()) {
                throwInvalid(path, reader.lineNumber(), "property before any element");
            }
            PlyProperty prop;
            if (n >= 2 && t[1] == "list") {
                if (n != 5) malformed("property list <count type> <item type> <name>");
                prop.isList = true;
                prop.countType = plyType(t[2]);
                prop.type = plyType(t[3]);
                prop.name = std::string(t[4]);
                if (prop.countType == PlyType::Invalid || prop.type == PlyType::Invalid ||
                    prop.countType == PlyType::Float32 || prop.countType == PlyType::Float64) {
                    throwInvalid(path, reader.lineNumber(), "unsupported PLY list types in " +
                        message_internal::quotedExcerpt(trimmed(line)));
                }
            } else {
                if (n != 3) malformed("property <type> <name>");
                prop.type = plyType(t[1]);
                prop.name = std::string(t[2]);
                if (prop.type == PlyType::Invalid) {
                    throwInvalid(path, reader.lineNumber(), "unknown PLY type " + message_internal::quotedExcerpt(t[1]));
                }
            }
            elements.back().props.push_back(std::move(prop));
        } else {
            const bool number = std::isdigit(static_cast<unsigned char>(t[0][0])) || t[0][0] == '-' ||
                                t[0][0] == '.';
            throwInvalid(path, reader.lineNumber(), "unknown PLY header keyword " + message_internal::quotedExcerpt(t[0]) +
                (number ? " (is 'end_header' missing?)" : ""));
        }
    }
    if (!ended) throwInvalid(path, reader.lineNumber(), "the PLY header has no 'end_header'");
    if (!haveFormat) throwInvalid(path, 0, "the PLY header has no 'format' line");
}

void prescanPly(const std::string& path, Prescan& out)
{
    FileReader reader(path);
    std::string_view tok;
    PlyFormat format = PlyFormat::Ascii;
    std::vector<PlyElement> elements;
    readPlyHeader(path, reader, format, elements);
    out.binary = format != PlyFormat::Ascii;
    const bool swap = (format == PlyFormat::BinaryLE) == kHostBigEndian;

    uint64_t nV = 0;
    for (const PlyElement& e : elements) {
        if (e.name == "vertex") nV = e.count;
    }
    // The counts against the bytes after the header, before anything is sized from them: binary,
    // the exact bytes of fixed-size properties and at least the count of each list; text, at
    // least two bytes per number (one less at the very end).
    const bool binaryBody = format != PlyFormat::Ascii;
    const uint64_t fileSize = bytesAfter(path, 0);
    const uint64_t remaining = fileSize > reader.offset() ? fileSize - reader.offset() : 0;
    std::string note;
    {
        uint64_t needed = 0;
        for (const PlyElement& e : elements) {
            uint64_t per = 0;
            for (const PlyProperty& p : e.props) per += binaryBody ? plySize(p.isList ? p.countType : p.type) : 2;
            needed += per * e.count;
            if (needed > remaining + (binaryBody ? 0 : 1)) {
                const std::string what = e.name == "vertex" ? "vertices" : e.name == "face" ? "faces" :
                    "'" + e.name + "' elements";
                note = " (" + headerClaimNote(e.count, what, remaining) + ")";
                break;
            }
        }
    }
    TokenReader tokens(reader);
    bool sawVertices = false;
    for (const PlyElement& e : elements) {
        const bool isVertex = e.name == "vertex";
        const bool isFace = e.name == "face";
        int xyz[3] = {-1, -1, -1};
        int faceList = -1;
        for (size_t i = 0; i < e.props.size(); ++i) {
            const PlyProperty& p = e.props[i];
            if (isVertex && !p.isList) {
                if (p.name == "x") xyz[0] = int(i);
                if (p.name == "y") xyz[1] = int(i);
                if (p.name == "z") xyz[2] = int(i);
            }
            if (isFace && p.isList && (p.name == "vertex_indices" || p.name == "vertex_index")) {
                faceList = int(i);
            }
        }
        const bool keepPoints = isVertex && xyz[0] >= 0 && xyz[1] >= 0 && xyz[2] >= 0;
        if (keepPoints) {
            // Only as many vertices as the file can hold (the loop below ends there).
            uint64_t per = 0;
            for (const PlyProperty& p : e.props) per += binaryBody ? plySize(p.isList ? p.countType : p.type) : 2;
            out.points.resize(size_t(std::min<uint64_t>(e.count, remaining / std::max<uint64_t>(per, 1) + 2)));
        }
        if (isVertex) sawVertices = true;
        const std::string what = isVertex ? "vertex" : (isFace ? "face" : e.name);
        for (uint64_t n = 0; n < e.count; ++n) {
            for (size_t i = 0; i < e.props.size(); ++i) {
                const PlyProperty& p = e.props[i];
                double value = 0;
                uint64_t items = 1;
                if (p.isList) {
                    if (format == PlyFormat::Ascii) {
                        if (!tokens.next(tok) || !parseInteger(tok, items)) {
                            throwInvalid(path, tokens.line(), what + " " + std::to_string(n) +
                                ": cannot read the list length of '" + p.name + "'" + note);
                        }
                    } else {
                        if (!readPlyBinary(reader, p.countType, swap, value)) {
                            throwInvalid(path, 0, "the file ends inside " + what + " " + std::to_string(n) + note);
                        }
                        items = uint64_t(value);
                    }
                    // A list length the rest of the file cannot hold.
                    const uint64_t left = fileSize > reader.offset() ? fileSize - reader.offset() : 0;
                    const uint64_t need = binaryBody ? items * plySize(p.type) : 2 * items;
                    if (note.empty() && need > left + (binaryBody ? 0 : 1)) {
                        note = " (its list '" + p.name + "' claims " + std::to_string(items) +
                               " items but the file holds only " + std::to_string(left) + " more bytes)";
                    }
                }
                for (uint64_t k = 0; k < items; ++k) {
                    NumberStatus st = NumberStatus::Ok;
                    if (format == PlyFormat::Ascii) {
                        if (!tokens.next(tok)) {
                            throwInvalid(path, tokens.line(), "the file ends inside " + what + " " +
                                std::to_string(n) + " of " + std::to_string(e.count) + note);
                        }
                        st = parseCoordinate(tok, value);
                        if (st == NumberStatus::NotANumber) {
                            throwInvalid(path, tokens.line(), what + " " + std::to_string(n) +
                                ": cannot parse the value " + message_internal::quotedExcerpt(tok) + " of '" + p.name + "'");
                        }
                    } else {
                        if (!readPlyBinary(reader, p.type, swap, value)) {
                            throwInvalid(path, 0, "the file ends inside " + what + " " +
                                std::to_string(n) + " of " + std::to_string(e.count) + note);
                        }
                        if (!std::isfinite(value)) st = NumberStatus::NonFinite;
                        else if (std::abs(value) > double(FLT_MAX)) st = NumberStatus::OutOfFloatRange;
                    }
                    const uint64_t lineNo = format == PlyFormat::Ascii ? tokens.line() : 0;
                    if (keepPoints && (int(i) == xyz[0] || int(i) == xyz[1] || int(i) == xyz[2])) {
                        if (st != NumberStatus::Ok) {
                            throwInvalid(path, lineNo, "vertex " + std::to_string(n) + ": " +
                                describeCoordinateProblem(st, format == PlyFormat::Ascii ? tok
                                    : std::string_view(formatDouble(value))));
                        }
                        if (n >= out.points.size()) { // cannot happen: the data ends first
                            throwInvalid(path, lineNo, "vertex " + std::to_string(n) + ": beyond the data" + note);
                        }
                        out.points[n][int(i) == xyz[0] ? 0 : (int(i) == xyz[1] ? 1 : 2)] = value;
                    }
                    if (int(i) == faceList) {
                        if (st != NumberStatus::Ok || value != std::floor(value) || value < 0 ||
                            value >= double(nV) || !sawVertices) {
                            throwInvalid(path, lineNo, "face " + std::to_string(n) + ": vertex index " +
                                formatDouble(value) + " is out of range (the file has " +
                                std::to_string(nV) + " vertices, numbered from 0)");
                        }
                    }
                }
            }
        }
        if (isFace) {
            out.faces = e.count;
            out.haveFaces = true;
        }
        if (keepPoints) out.havePoints = true;
    }
}

// Attributes: the vertex element's properties. Runs only when attributes are asked for (or
// listed), after the mesh itself was read and checked.
void scanPlyAttributes(const std::string& path, const std::vector<std::string>& want, AttributeScan& out)
{
    FileReader reader(path);
    PlyFormat format = PlyFormat::Ascii;
    std::vector<PlyElement> elements;
    readPlyHeader(path, reader, format, elements);
    const bool swap = (format == PlyFormat::BinaryLE) == kHostBigEndian;

    // The names: Cd, N, uv from their properties, then every other scalar vertex property.
    const PlyElement* vertex = nullptr;
    size_t vertexElement = 0;
    for (size_t i = 0; i < elements.size() && !vertex; ++i) {
        if (elements[i].name == "vertex") { vertex = &elements[i]; vertexElement = i; }
    }
    struct Named { std::string name; int prop[3]; };
    std::vector<Named> named;
    if (vertex) {
        const auto find = [&](const char* n) {
            for (size_t i = 0; i < vertex->props.size(); ++i)
                if (!vertex->props[i].isList && vertex->props[i].name == n) return int(i);
            return -1;
        };
        std::vector<bool> used(vertex->props.size(), false);
        for (const char* n : {"x", "y", "z"}) if (find(n) >= 0) used[size_t(find(n))] = true;
        const auto group = [&](const char* name, std::initializer_list<std::initializer_list<const char*>> sets) {
            for (const auto& set : sets) {
                Named g{name, {-1, -1, -1}};
                int k = 0;
                bool all = true;
                for (const char* n : set) { g.prop[k] = find(n); all = all && g.prop[k] >= 0; ++k; }
                if (!all) continue;
                for (int j = 0; j < k; ++j) used[size_t(g.prop[j])] = true;
                named.push_back(g);
                return;
            }
        };
        group("Cd", {{"red", "green", "blue"}, {"r", "g", "b"}});
        group("N", {{"nx", "ny", "nz"}});
        group("uv", {{"u", "v"}, {"s", "t"}, {"texture_u", "texture_v"}, {"texture_s", "texture_t"}});
        for (size_t i = 0; i < vertex->props.size(); ++i) {
            if (used[i] || vertex->props[i].isList) continue;
            named.push_back({vertex->props[i].name, {int(i), -1, -1}});
        }
    }
    out.available.clear();
    for (const Named& n : named) out.available.push_back(n.name);
    std::vector<const Named*> asked;
    for (const std::string& name : want) {
        const Named* found = nullptr;
        for (const Named& n : named) if (n.name == name) found = &n;
        if (!found) throwNoAttribute(path, name, out.available);
        asked.push_back(found);
    }
    out.sources.clear();
    if (asked.empty()) return;
    // Where each property's value goes: (source, component), or nowhere.
    std::vector<std::vector<std::pair<int, int>>> dest(vertex->props.size());
    for (size_t a = 0; a < asked.size(); ++a) {
        AttributeSource src;
        src.name = asked[a]->name;
        src.components = asked[a]->prop[1] >= 0 ? 3 : 1;
        src.values.assign(size_t(vertex->count) * size_t(src.components), 0.0f);
        for (int k = 0; k < 3; ++k) {
            if (asked[a]->prop[k] >= 0) dest[size_t(asked[a]->prop[k])].push_back({int(a), k});
        }
        out.sources.push_back(std::move(src));
    }
    // Colours of integer types are scaled to 0..1 by their type's maximum.
    const auto scale = [](PlyType t) {
        switch (t) {
        case PlyType::UInt8: return 1.0 / 255.0;
        case PlyType::Int8: return 1.0 / 127.0;
        case PlyType::UInt16: return 1.0 / 65535.0;
        case PlyType::Int16: return 1.0 / 32767.0;
        case PlyType::UInt32: return 1.0 / 4294967295.0;
        case PlyType::Int32: return 1.0 / 2147483647.0;
        default: return 1.0;
        }
    };
    TokenReader tokens(reader);
    std::string_view tok;
    const auto readValue = [&](PlyType t, const std::string& what, uint64_t n, double& value) {
        if (format == PlyFormat::Ascii) {
            if (!tokens.next(tok)) throwInvalid(path, tokens.line(), "the file ends inside " + what + " " + std::to_string(n));
            if (parseCoordinate(tok, value) != NumberStatus::Ok) {
                throwInvalid(path, tokens.line(), what + " " + std::to_string(n) + ": cannot parse the value " +
                    message_internal::quotedExcerpt(tok));
            }
        } else if (!readPlyBinary(reader, t, swap, value)) {
            throwInvalid(path, 0, "the file ends inside " + what + " " + std::to_string(n));
        }
    };
    for (size_t e = 0; e <= vertexElement; ++e) {
        const PlyElement& el = elements[e];
        const bool isVertex = e == vertexElement;
        for (uint64_t n = 0; n < el.count; ++n) {
            for (size_t i = 0; i < el.props.size(); ++i) {
                const PlyProperty& p = el.props[i];
                double value = 0.0;
                uint64_t items = 1;
                if (p.isList) {
                    readValue(p.countType, el.name, n, value);
                    items = uint64_t(value);
                }
                for (uint64_t k = 0; k < items; ++k) {
                    readValue(p.type, el.name, n, value);
                    if (!isVertex || p.isList) continue;
                    for (const auto& [a, c] : dest[i]) {
                        AttributeSource& src = out.sources[size_t(a)];
                        const double v = src.name == "Cd" ? value * scale(p.type) : value;
                        src.values[size_t(n) * size_t(src.components) + size_t(c)] = float(v);
                    }
                }
            }
        }
    }
}

} // namespace meshio_internal

} // namespace levelforge
