// SPDX-License-Identifier: Apache-2.0
/// @file
/// @brief levelforge_fuzz_make_seeds [--large] OUTDIR: writes the seed inputs of every fuzz
///        target to OUTDIR/<target>/seed-*. Without --large, the small ones, committed under
///        tests/data/fuzz/ (where they are also replayed as regression inputs); with --large also
///        those above 64 KB (a real ADF), which scripts/fuzz makes in the build folder.
///
/// ../shared/data has small meshes but only large volumes, and no PLY, .vdb or ADF at all, so the
/// seeds are made here: tiny meshes in every mesh format and flavour (OBJ with quads, normals
/// and negative indices; OFF; PLY ASCII, binary little and big endian; STL ASCII and binary),
/// tiny volumes in each volume format, plain and gzip-compressed, in both byte orders and
/// several sample types, raw layouts, .vdb files with scalar and non-scalar grids, uncompressed
/// (but for the active mask, so that mutations reach the trees) and compressed, and ADF grids.
/// Every seed is a valid file or one refused with a levelforge::Error (the replay expects each
/// to run clean); without --large each is below 64 KB.
#include <levelforge/adf/AdaptiveDistanceField.h>
#include <levelforge/core/DenseVolume.h>
#include <levelforge/core/Metadata.h>
#include <levelforge/io/MeshIO.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/io/VolumeIO.h>

#include <openvdb/io/File.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<uint8_t>;

fs::path gOut;
bool gLarge = false; ///< --large: also the seeds above 64 KB (a real ADF)

fs::path seedPath(const std::string& target, const std::string& name)
{
    const fs::path dir = gOut / target;
    fs::create_directories(dir);
    return dir / ("seed-" + name);
}

void writeBytes(const fs::path& path, const Bytes& bytes)
{
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!out) throw std::runtime_error("cannot write " + path.string());
}

void writeText(const std::string& target, const std::string& name, const std::string& text)
{
    writeBytes(seedPath(target, name), Bytes(text.begin(), text.end()));
}

Bytes readBytes(const fs::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

Bytes gzipped(const Bytes& plain)
{
    const fs::path tmp = gOut / ".gzip-tmp.gz";
    gzFile f = gzopen(tmp.c_str(), "wb9");
    if (!f) throw std::runtime_error("gzopen failed");
    if (!plain.empty() && gzwrite(f, plain.data(), unsigned(plain.size())) != int(plain.size())) {
        throw std::runtime_error("gzwrite failed");
    }
    gzclose(f);
    Bytes out = readBytes(tmp);
    fs::remove(tmp);
    return out;
}

/// Copies a seed file to other targets' folders.
void copySeed(const fs::path& from, const std::vector<std::string>& targets)
{
    for (const std::string& t : targets) writeBytes(seedPath(t, from.filename().string().substr(5)), readBytes(from));
}

template<typename T>
void put(Bytes& b, size_t offset, T v, bool big)
{
    unsigned char raw[sizeof(T)];
    std::memcpy(raw, &v, sizeof(T));
    if (big) std::reverse(raw, raw + sizeof(T));
    if (b.size() < offset + sizeof(T)) b.resize(offset + sizeof(T), 0);
    std::memcpy(b.data() + offset, raw, sizeof(T));
}

template<typename T>
void append(Bytes& b, T v, bool big)
{
    put(b, b.size(), v, big);
}

// ------------------------------------------------------------------------------------ meshes

levelforge::TriangleMesh tetrahedron()
{
    levelforge::TriangleMesh m;
    m.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
}

void meshSeeds()
{
    using namespace levelforge;
    // OBJ
    writeText("obj", "tetra.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    writeText("obj", "cube-quads.obj",
              "# a unit cube of quads, with texture coordinates, normals and groups\n"
              "mtllib none.mtl\no cube\n"
              "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
              "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
              "vn 0 0 -1\nvn 0 0 1\nvn 0 -1 0\nvn 1 0 0\nvn 0 1 0\nvn -1 0 0\n"
              "g sides\nusemtl grey\ns off\n"
              "f 1/1/1 4/4/1 3/3/1 2/2/1\nf 5/1/2 6/2/2 7/3/2 8/4/2\nf 1//3 2//3 6//3 5//3\n"
              "f 2/2 3/3 7/3 6/2\nf -5 -1 -2 -6\nf 1 5 8 4\n");
    writeText("obj", "concave.obj",
              "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0.5 0.5 1e-3\n"
              "f 1 2 3 4 5 6\nf 1 2 7\nf 2 3 7\r\nf 3 4 5 4 7\n");
    // OFF
    writeText("off", "cube.off",
              "OFF\n8 6 12\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
              "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n");
    writeMesh(tetrahedron(), seedPath("off", "tetra.off").string());
    writeText("off", "colours.off",
              "OFF\n4 4 0\n0 0 0\n1e0 0 0\n0 1.5 0\n0 0 -2.25e-1\n"
              "3 0 2 1 255 0 0\n3 0 1 3 0 255 0\n3 0 3 2 0 0 255\n3 1 2 3 10 20 30\n");
    // PLY
    writeText("ply", "ascii.ply",
              "ply\nformat ascii 1.0\ncomment a cube of quads\nelement vertex 8\n"
              "property float x\nproperty float y\nproperty float z\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\n"
              "element face 6\nproperty list uchar int vertex_indices\nend_header\n"
              "0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 1 2 3\n"
              "0 0 1 4 5 6\n1 0 1 7 8 9\n1 1 1 10 11 12\n0 1 1 13 14 15\n"
              "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n");
    writeText("ply", "ascii-double.ply",
              "ply\nformat ascii 1.0\nelement vertex 4\nproperty double x\nproperty double y\nproperty double z\n"
              "element face 4\nproperty list uint8 int32 vertex_index\nend_header\n"
              "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n");
    writeMesh(tetrahedron(), seedPath("ply", "binary-le.ply").string());
    {
        const std::string header = "ply\nformat binary_big_endian 1.0\nelement vertex 4\n"
                                   "property float x\nproperty float y\nproperty float z\n"
                                   "element face 4\nproperty list uchar int vertex_indices\nend_header\n";
        Bytes b(header.begin(), header.end());
        const levelforge::TriangleMesh t = tetrahedron();
        for (const auto& p : t.points)
            for (int a = 0; a < 3; ++a) append<float>(b, float(p[a]), true);
        for (const auto& f : t.triangles) {
            append<uint8_t>(b, 3, true);
            for (int k = 0; k < 3; ++k) append<int32_t>(b, int32_t(f[k]), true);
        }
        writeBytes(seedPath("ply", "binary-be.ply"), b);
    }
    // STL
    const std::string asciiStl =
        "solid tetra\n"
        "facet normal 0 0 -1\n outer loop\n  vertex 0 0 0\n  vertex 0 1 0\n  vertex 1 0 0\n endloop\nendfacet\n"
        "facet normal 0 -1 0\n outer loop\n  vertex 0 0 0\n  vertex 1 0 0\n  vertex 0 0 1\n endloop\nendfacet\n"
        "facet normal -1 0 0\n outer loop\n  vertex 0 0 0\n  vertex 0 0 1\n  vertex 0 1 0\n endloop\nendfacet\n"
        "facet normal 0.577 0.577 0.577\n outer loop\n  vertex 1 0 0\n  vertex 0 1 0\n  vertex 0 0 1\n endloop\nendfacet\n"
        "endsolid tetra\n";
    for (const char* t : {"stl", "stl_ascii"}) writeText(t, "tetra-ascii.stl", asciiStl);
    writeMesh(tetrahedron(), seedPath("stl", "tetra-binary.stl").string());
    copySeed(seedPath("stl", "tetra-binary.stl"), {"stl_binary"});
    {
        // a binary STL whose header starts with "solid" (a classic trap for format sniffing)
        Bytes b = readBytes(seedPath("stl", "tetra-binary.stl"));
        std::memcpy(b.data(), "solid binary", 12);
        writeBytes(seedPath("stl", "solid-binary.stl"), b);
        writeBytes(seedPath("stl_binary", "solid-binary.stl"), b);
    }
    // convert: one of each format (the target picks the reader from the content)
    copySeed(seedPath("obj", "tetra.obj"), {"convert"});
    copySeed(seedPath("off", "cube.off"), {"convert"});
    copySeed(seedPath("ply", "ascii.ply"), {"convert"});
    copySeed(seedPath("stl", "tetra-binary.stl"), {"convert"});
    copySeed(seedPath("stl", "tetra-ascii.stl"), {"convert"});
}

// ----------------------------------------------------------------------------------- volumes

levelforge::ScalarVolume smallVolume()
{
    levelforge::ScalarVolume v = levelforge::makeSphereField(openvdb::Coord(4, 3, 2), openvdb::Vec3d(1.5, 1.0, 0.5), 1.2,
                                                             openvdb::Vec3d(0.5, 0.75, 1.25));
    v.origin = openvdb::Vec3d(-1.0, 2.0, 0.5);
    return v;
}

/// A NIfTI-1 header (348 bytes + 4 extension bytes) for @p dims of @p datatype.
Bytes niftiHeader(const int16_t dims[3], int16_t datatype, int16_t bitpix, bool big)
{
    Bytes h(352, 0);
    put<int32_t>(h, 0, 348, big);
    put<int16_t>(h, 40, 3, big);
    for (int a = 0; a < 3; ++a) put<int16_t>(h, 42 + 2 * size_t(a), dims[a], big);
    for (int i = 4; i < 8; ++i) put<int16_t>(h, 40 + 2 * size_t(i), 1, big);
    put<int16_t>(h, 70, datatype, big);
    put<int16_t>(h, 72, bitpix, big);
    put<float>(h, 76, -1.0f, big); // qfac
    put<float>(h, 80, 1.0f, big);
    put<float>(h, 84, 2.0f, big);
    put<float>(h, 88, 0.5f, big);
    put<float>(h, 108, 352.0f, big);
    std::memcpy(h.data() + 344, "n+1", 4);
    return h;
}

void volumeSeeds()
{
    using namespace levelforge;
    const ScalarVolume vol = smallVolume();
    // NIfTI-1
    writeNifti(seedPath("nifti", "float.nii").string(), vol);
    writeNifti(seedPath("nifti", "float.nii.gz").string(), vol);
    {
        // big endian int16, qform with a 90-degree rotation about z (a warning, not an error)
        const int16_t dims[3] = {3, 2, 2};
        Bytes b = niftiHeader(dims, 4, 16, true);
        put<int16_t>(b, 252, 1, true);          // qform_code
        put<float>(b, 264, 0.70710678f, true);  // quatern_d
        put<float>(b, 268, 10.0f, true);        // qoffset
        for (int i = 0; i < 12; ++i) append<int16_t>(b, int16_t(i * 100 - 300), true);
        writeBytes(seedPath("nifti", "int16-be-qform.nii"), b);
    }
    {
        // uint8 with scl_slope / scl_inter and an sform with a negative step (a reversed axis)
        const int16_t dims[3] = {2, 2, 3};
        Bytes b = niftiHeader(dims, 2, 8, false);
        put<float>(b, 112, 0.5f, false);  // scl_slope
        put<float>(b, 116, -3.0f, false); // scl_inter
        put<int16_t>(b, 254, 2, false);   // sform_code
        put<float>(b, 280, -1.0f, false);
        put<float>(b, 292, 5.0f, false);
        put<float>(b, 300, 2.0f, false);
        put<float>(b, 320, 0.5f, false);
        for (int i = 0; i < 12; ++i) append<uint8_t>(b, uint8_t(i * 20), false);
        writeBytes(seedPath("nifti", "uint8-sform-scaled.nii"), b);
    }
    {
        const int16_t dims[3] = {2, 2, 1};
        Bytes b = niftiHeader(dims, 64, 64, false);
        put<int16_t>(b, 40, 2, false); // a 2-D image
        for (int i = 0; i < 4; ++i) append<double>(b, 0.25 * i, false);
        writeBytes(seedPath("nifti", "float64-2d.nii"), gzipped(b));
    }
    // INRIMAGE-4
    writeInr(seedPath("inr", "float.inr").string(), vol);
    writeInr(seedPath("inr", "float.inr.gz").string(), vol);
    auto inrHeader = [](const std::string& fields) {
        std::string h = "#INRIMAGE-4#{\n" + fields;
        h.resize(256 - 4, '\n');
        h += "##}\n";
        return Bytes(h.begin(), h.end());
    };
    {
        Bytes b = inrHeader("XDIM=3\nYDIM=2\nZDIM=2\nVDIM=1\nTYPE=unsigned fixed\nPIXSIZE=8 bits\nCPU=sun\n"
                            "VX=0.5\nVY=1\nVZ=2\n");
        for (int i = 0; i < 12; ++i) b.push_back(uint8_t(i * 17));
        writeBytes(seedPath("inr", "uint8-sun.inr"), b);
    }
    {
        Bytes b = inrHeader("XDIM=2\r\nYDIM=2\r\nVDIM=1\r\nTYPE=signed fixed\r\nPIXSIZE=16 bits\r\nCPU=sgi\r\n"
                            "XO=-4.5\r\nYO=3\r\nZO=0\r\n#comment=ignored\r\n");
        for (int i = 0; i < 4; ++i) append<int16_t>(b, int16_t(i * 1000 - 1500), true);
        writeBytes(seedPath("inr", "int16-sgi-2d.inr"), gzipped(b));
    }
    // VolPack .den
    auto den = [](const int16_t dims[3], bool big) {
        Bytes h(62, 0);
        put<int16_t>(h, 0, 1, big);
        for (int a = 0; a < 3; ++a) {
            put<int16_t>(h, 2 + 2 * size_t(a), 0, big);                 // orig_min
            put<int16_t>(h, 8 + 2 * size_t(a), int16_t(dims[a] - 1), big); // orig_max
            put<int16_t>(h, 14 + 2 * size_t(a), dims[a], big);          // orig_len
            put<int16_t>(h, 20 + 2 * size_t(a), 0, big);
            put<int16_t>(h, 26 + 2 * size_t(a), int16_t(dims[a] - 1), big);
            put<int16_t>(h, 32 + 2 * size_t(a), dims[a], big);
            put<int16_t>(h, 38 + 2 * size_t(a), 0, big);
            put<int16_t>(h, 44 + 2 * size_t(a), int16_t(dims[a] - 1), big);
            put<int16_t>(h, 50 + 2 * size_t(a), dims[a], big);          // map_len
        }
        const int32_t n = int32_t(dims[0]) * dims[1] * dims[2];
        put<int16_t>(h, 56, 0, big); // map_warps
        put<int32_t>(h, 58, n, big); // map_length
        for (int32_t i = 0; i < n; ++i) h.push_back(uint8_t(i * 7));
        return h;
    };
    {
        const int16_t dims[3] = {4, 3, 2};
        writeBytes(seedPath("den", "le.den"), den(dims, false));
        writeBytes(seedPath("den", "be.den"), den(dims, true));
        writeBytes(seedPath("den", "le.den.gz"), gzipped(den(dims, false)));
    }
    // raw: a 16-byte layout (see FuzzRaw.cc), then the file
    auto rawSeed = [](uint8_t type, uint8_t flags, int16_t x, int16_t y, int16_t z, uint32_t headerBytes,
                      float spacing, const Bytes& file) {
        Bytes b;
        append<uint8_t>(b, type, false);
        append<uint8_t>(b, flags, false);
        append<int16_t>(b, x, false);
        append<int16_t>(b, y, false);
        append<int16_t>(b, z, false);
        append<uint32_t>(b, headerBytes, false);
        append<float>(b, spacing, false);
        b.insert(b.end(), file.begin(), file.end());
        return b;
    };
    {
        Bytes u8;
        for (int i = 0; i < 24; ++i) u8.push_back(uint8_t(i * 9));
        writeBytes(seedPath("raw", "uint8-4x3x2"), rawSeed(0, 0, 4, 3, 2, 0, 1.0f, u8));
        Bytes f32be;
        for (int i = 0; i < 8; ++i) append<float>(f32be, 0.5f * float(i) - 1.0f, true);
        writeBytes(seedPath("raw", "float32-be-readvolume"), rawSeed(8, 3, 2, 2, 2, 0, 0.25f, f32be));
        Bytes i16(8, 0xEE); // an 8-byte header
        for (int i = 0; i < 6; ++i) append<int16_t>(i16, int16_t(i * 3000 - 9000), false);
        writeBytes(seedPath("raw", "int16-header8"), rawSeed(3, 0, 3, 2, 1, 8, 2.0f, i16));
        Bytes f64;
        for (int i = 0; i < 4; ++i) append<double>(f64, 1e3 * i, false);
        writeBytes(seedPath("raw", "float64-gz"), rawSeed(9, 0, 1, 2, 2, 0, 1.0f, gzipped(f64)));
        Bytes u64;
        for (int i = 0; i < 2; ++i) append<uint64_t>(u64, uint64_t(1) << (20 * i), true);
        writeBytes(seedPath("raw", "uint64-be"), rawSeed(6, 1, 2, 1, 1, 0, 3.0f, u64));
    }
    // volume (the format chosen from the content)
    copySeed(seedPath("nifti", "float.nii"), {"volume"});
    copySeed(seedPath("nifti", "float.nii.gz"), {"volume"});
    copySeed(seedPath("inr", "uint8-sun.inr"), {"volume"});
    copySeed(seedPath("inr", "float.inr.gz"), {"volume"});
}

// --------------------------------------------------------------------------------------- vdb

void writeVdb(const fs::path& path, const openvdb::GridPtrVec& grids, uint32_t compression)
{
    openvdb::io::File file(path.string());
    file.setCompression(compression);
    openvdb::MetaMap meta;
    meta.insertMeta("creator", openvdb::StringMetadata("levelforge_fuzz_make_seeds"));
    file.write(grids, meta);
    file.close();
}

void vdbSeeds()
{
    using namespace levelforge;
    openvdb::FloatGrid::Ptr sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        2.5f, openvdb::Vec3f(4.0f, 4.5f, 5.0f), 0.5f, 1.5f); // in one node of each level: a small file
    sphere->setName("surface");
    stampLevelSetMetadata(*sphere, 1.5, 1.5, "sphere", "openvdb");
    writeVdb(seedPath("vdb", "levelset-mask.vdb"), {sphere}, openvdb::io::COMPRESS_ACTIVE_MASK);
    writeVdb(seedPath("vdb", "levelset-zip.vdb"), {sphere},
             openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
#ifdef OPENVDB_USE_BLOSC
    writeVdb(seedPath("vdb", "levelset-blosc.vdb"), {sphere},
             openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
#endif

    // a few voxels of every scalar type, one with an active tile, translated transforms
    openvdb::DoubleGrid::Ptr d = openvdb::DoubleGrid::create(-1.0);
    d->setName("density");
    d->tree().setValue(openvdb::Coord(0, 0, 0), 0.5);
    d->tree().setValue(openvdb::Coord(3, -2, 9), 1.5);
    d->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    d->transform().postTranslate(openvdb::Vec3d(1.0, -2.0, 3.0));
    openvdb::Int32Grid::Ptr i32 = openvdb::Int32Grid::create(0);
    i32->setName("labels");
    i32->tree().setValue(openvdb::Coord(-1, 5, 2), 7);
    i32->tree().setValue(openvdb::Coord(-1, 6, 2), -3);
    openvdb::Int64Grid::Ptr i64 = openvdb::Int64Grid::create(0);
    i64->setName("ids");
    i64->tree().addTile(1, openvdb::Coord(0, 0, 0), int64_t(1) << 40, true); // one active 8^3 tile
    openvdb::Vec3SGrid::Ptr vec = openvdb::Vec3SGrid::create();
    vec->setName("velocity");
    vec->tree().setValue(openvdb::Coord(1, 1, 1), openvdb::Vec3s(1, 2, 3));
    writeVdb(seedPath("vdb", "scalar-types-mask.vdb"), {vec, d, i32, i64}, openvdb::io::COMPRESS_ACTIVE_MASK);
    writeVdb(seedPath("vdb", "int32-zip.vdb"), {i32}, openvdb::io::COMPRESS_ZIP);
    writeVdb(seedPath("vdb", "vec3-only.vdb"), {vec}, openvdb::io::COMPRESS_ACTIVE_MASK);

    // a rotated transform (refused as a volume) and a scaled, non-uniform one (accepted)
    openvdb::FloatGrid::Ptr rotated = openvdb::FloatGrid::create(0.0f);
    rotated->setName("rotated");
    rotated->tree().setValue(openvdb::Coord(2, 2, 2), 1.0f);
    openvdb::math::Transform::Ptr rot = openvdb::math::Transform::createLinearTransform(1.0);
    rot->postRotate(0.5, openvdb::math::Z_AXIS);
    rotated->setTransform(rot);
    openvdb::FloatGrid::Ptr scaled = openvdb::FloatGrid::create(2.0f);
    scaled->setName("scaled");
    scaled->tree().setValue(openvdb::Coord(0, 1, 2), -1.0f);
    scaled->tree().setValue(openvdb::Coord(1, 1, 2), 0.5f);
    openvdb::math::Transform::Ptr sc = openvdb::math::Transform::createLinearTransform(1.0);
    sc->preScale(openvdb::Vec3d(0.5, 1.0, 2.0));
    scaled->setTransform(sc);
    writeVdb(seedPath("vdb", "transforms-mask.vdb"), {rotated, scaled}, openvdb::io::COMPRESS_ACTIVE_MASK);
    copySeed(seedPath("vdb", "levelset-mask.vdb"), {"volume"});

    // adf. A real ADF has 27 level-1 internal nodes of distinct tile values (about 180 KB even
    // zip-compressed), so it is made only with --large (scripts/fuzz seeds its working corpus
    // with those). The small seeds are ADF grids as the wrapper sees them: the metadata of a
    // real ADF on a grid with a few tiles and voxels, accepted; and with a domain that is not
    // made of whole 128^3 blocks, refused.
    AdaptiveDistanceFieldOptions options;
    options.voxelCount = 4;
    options.paddingVoxels = 1.0;
    const AdaptiveDistanceField adf = meshToAdaptiveDistanceField(tetrahedron(), options);
    openvdb::FloatGrid::Ptr adfGrid = adf.grid()->deepCopy();
    const uint32_t zip = openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK;
    if (gLarge) {
        writeVdb(seedPath("adf", "tetra-zip.vdb"), {adfGrid}, zip);
        writeVdb(seedPath("adf", "tetra-sphere-zip.vdb"), {sphere, adfGrid}, zip);
    }
    openvdb::FloatGrid::Ptr small = openvdb::FloatGrid::create(adfGrid->background());
    small->setName("adf");
    small->setTransform(adfGrid->transform().copy());
    for (auto it = adfGrid->beginMeta(); it != adfGrid->endMeta(); ++it) small->insertMeta(it->first, *it->second);
    small->insertMeta(meta::kAdfDomainMin, openvdb::Vec3IMetadata(openvdb::Vec3i(0, 0, 0)));
    small->insertMeta(meta::kAdfDomainMax, openvdb::Vec3IMetadata(openvdb::Vec3i(128, 128, 256)));
    small->tree().addTile(2, openvdb::Coord(0, 0, 128), 2.5f, false); // a level-2 tile
    small->tree().addTile(1, openvdb::Coord(8, 0, 0), -0.5f, false);  // a level-1 tile
    small->tree().setValue(openvdb::Coord(1, 2, 3), -0.25f);          // a leaf
    small->tree().setValue(openvdb::Coord(2, 2, 3), 0.25f);
    writeVdb(seedPath("adf", "metadata-mask.vdb"), {small}, openvdb::io::COMPRESS_ACTIVE_MASK);
    openvdb::FloatGrid::Ptr refused = small->deepCopy();
    refused->insertMeta(meta::kAdfDomainMax, openvdb::Vec3IMetadata(openvdb::Vec3i(128, 100, 128)));
    writeVdb(seedPath("adf", "bad-domain-mask.vdb"), {refused, sphere}, openvdb::io::COMPRESS_ACTIVE_MASK);
}

} // namespace

int main(int argc, char** argv)
{
    if (argc == 3 && std::string(argv[1]) == "--large") gLarge = true;
    if (argc != 2 + int(gLarge)) {
        std::cerr << "usage: levelforge_fuzz_make_seeds [--large] OUTDIR   (writes OUTDIR/<target>/seed-*)\n";
        return 2;
    }
    openvdb::initialize();
    gOut = argv[argc - 1];
    try {
        fs::create_directories(gOut);
        meshSeeds();
        volumeSeeds();
        vdbSeeds();
    } catch (const std::exception& e) {
        std::cerr << "levelforge_fuzz_make_seeds: " << e.what() << "\n";
        return 1;
    }
    for (const auto& dir : fs::directory_iterator(gOut)) {
        if (!dir.is_directory()) continue;
        for (const auto& f : fs::directory_iterator(dir.path())) {
            std::cout << f.path().string() << " " << fs::file_size(f.path()) << "\n";
        }
    }
    return 0;
}
