// SPDX-License-Identifier: Apache-2.0
// Tests for VolumeIO.h: NIfTI-1 / INRIMAGE-4 / VolPack .den / raw / .vdb readers, the NIfTI and
// INR writers, and the typed errors. Headers of other datatypes and byte orders are written byte
// by byte here, so the readers are checked against files built independently of the writers.
#include "TestUtil.h"

#include <levelforge/core/Exceptions.h>
#include <levelforge/io/VdbIO.h>
#include <levelforge/io/VolumeIO.h>

#include <openvdb/openvdb.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace fs = std::filesystem;
using levelforge::ScalarVolume;
using levelforge::VolumeInfo;
using levelforge::VolumeValueType;
using levelforge_test::scratchDir;

namespace {

// ------------------------------------------------------------------------------ byte helpers

using Bytes = std::vector<unsigned char>;

template<typename T>
void putAt(Bytes& b, size_t offset, T v, bool bigEndian)
{
    unsigned char tmp[sizeof(T)];
    std::memcpy(tmp, &v, sizeof(T));
    const bool hostBig = (__BYTE_ORDER__ == __ORDER_BIG_ENDIAN__);
    if (bigEndian != hostBig) std::reverse(tmp, tmp + sizeof(T));
    if (b.size() < offset + sizeof(T)) b.resize(offset + sizeof(T), 0);
    std::memcpy(b.data() + offset, tmp, sizeof(T));
}

template<typename T>
void append(Bytes& b, T v, bool bigEndian)
{
    putAt(b, b.size(), v, bigEndian);
}

void writeBytes(const fs::path& path, const Bytes& b)
{
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
    ASSERT_TRUE(out.good()) << path;
}

Bytes readBytes(const fs::path& path)
{
    std::ifstream in(path, std::ios::binary);
    return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::vector<std::string> listDir(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

/// Runs @a fn, expects exception type E whose message contains every string of @a parts.
template<typename E, typename Fn>
void expectError(Fn fn, const std::vector<std::string>& parts)
{
    try {
        fn();
        ADD_FAILURE() << "expected an exception containing '" << parts.front() << "'";
    } catch (const E& e) {
        const std::string msg = e.what();
        for (const std::string& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "'" << p << "' not in: " << msg;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
    }
}

/// A test volume with distinct, exactly representable values.
ScalarVolume makeVolume()
{
    ScalarVolume v(openvdb::Coord(5, 4, 3), 0.0f, openvdb::Vec3d(0.5, 1.25, 2.0), openvdb::Vec3d(-3.5, 2.25, 10.0));
    for (int k = 0; k < 3; ++k) {
        for (int j = 0; j < 4; ++j) {
            for (int i = 0; i < 5; ++i) v(i, j, k) = float(i) + 10.0f * float(j) + 100.0f * float(k) - 0.75f;
        }
    }
    return v;
}

void expectSameVolume(const ScalarVolume& a, const ScalarVolume& b, double geomTol = 0.0)
{
    EXPECT_EQ(a.dims, b.dims);
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(a.spacing[i], b.spacing[i], geomTol) << "axis " << i;
        EXPECT_NEAR(a.origin[i], b.origin[i], geomTol) << "axis " << i;
    }
    ASSERT_EQ(a.data.size(), b.data.size());
    for (size_t n = 0; n < a.data.size(); ++n) {
        ASSERT_EQ(a.data[n], b.data[n]) << "sample " << n;
    }
}

// ------------------------------------------------------------------ hand-built NIfTI-1 files

struct NiftiSpec
{
    int32_t sizeofHdr = 348;
    std::array<int16_t, 8> dim{{3, 3, 2, 2, 1, 1, 1, 1}};
    int16_t datatype = 2;
    int16_t bitpix = 8;
    std::array<float, 8> pixdim{{1, 1, 1, 1, 1, 1, 1, 1}};
    float voxOffset = 352;
    float slope = 0, inter = 0;
    int16_t qformCode = 0, sformCode = 0;
    std::array<float, 3> quat{{0, 0, 0}};
    std::array<float, 3> qoffset{{0, 0, 0}};
    float srow[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
    std::string magic{"n+1", 4};
};

/// The 348-byte header plus 4 zero bytes (no extension), in the requested byte order.
Bytes niftiHeader(const NiftiSpec& s, bool big)
{
    Bytes h(352, 0);
    putAt(h, 0, s.sizeofHdr, big);
    for (int i = 0; i < 8; ++i) putAt(h, 40 + 2 * size_t(i), s.dim[size_t(i)], big);
    putAt(h, 70, s.datatype, big);
    putAt(h, 72, s.bitpix, big);
    for (int i = 0; i < 8; ++i) putAt(h, 76 + 4 * size_t(i), s.pixdim[size_t(i)], big);
    putAt(h, 108, s.voxOffset, big);
    putAt(h, 112, s.slope, big);
    putAt(h, 116, s.inter, big);
    putAt(h, 252, s.qformCode, big);
    putAt(h, 254, s.sformCode, big);
    for (int i = 0; i < 3; ++i) putAt(h, 256 + 4 * size_t(i), s.quat[size_t(i)], big);
    for (int i = 0; i < 3; ++i) putAt(h, 268 + 4 * size_t(i), s.qoffset[size_t(i)], big);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) putAt(h, 280 + 16 * size_t(r) + 4 * size_t(c), s.srow[r][c], big);
    }
    std::memcpy(h.data() + 344, s.magic.data(), 4);
    return h;
}

/// 12 values of T covering its range (negative ones for signed types).
template<typename T>
std::vector<T> sampleValues()
{
    std::vector<T> v;
    for (int n = 0; n < 12; ++n) {
        if constexpr (std::is_floating_point<T>::value) {
            v.push_back(T(n) * T(-1.5) + T(0.25));
        } else {
            v.push_back(T(n * 7));
        }
    }
    v[1] = std::numeric_limits<T>::max() / T(3) * T(2); // a large one, exactly representable as float below
    if constexpr (std::is_integral<T>::value) {
        v[1] = T(v[1] & ~T(0xffff)); // keep it exact in float (24-bit mantissa)
        if (sizeof(T) == 1) v[1] = T(std::numeric_limits<T>::max());
        if (sizeof(T) == 2) v[1] = T(std::numeric_limits<T>::max());
        if (std::is_signed<T>::value) v[2] = std::numeric_limits<T>::min();
    }
    if constexpr (std::is_same<T, double>::value) v[1] = 1.0e30;
    if constexpr (std::is_same<T, float>::value) v[1] = 3.0e37f;
    return v;
}

template<typename T>
Bytes encode(const std::vector<T>& values, bool big)
{
    Bytes b;
    for (T v : values) append(b, v, big);
    return b;
}

struct TypeCase
{
    VolumeValueType type;
    int niftiCode;
};

/// Calls fn.template operator()<T>(typeCase) for every value type.
template<typename Fn>
void forEachType(Fn&& fn)
{
    fn(TypeCase{VolumeValueType::UInt8, 2}, uint8_t());
    fn(TypeCase{VolumeValueType::Int8, 256}, int8_t());
    fn(TypeCase{VolumeValueType::UInt16, 512}, uint16_t());
    fn(TypeCase{VolumeValueType::Int16, 4}, int16_t());
    fn(TypeCase{VolumeValueType::UInt32, 768}, uint32_t());
    fn(TypeCase{VolumeValueType::Int32, 8}, int32_t());
    fn(TypeCase{VolumeValueType::UInt64, 1280}, uint64_t());
    fn(TypeCase{VolumeValueType::Int64, 1024}, int64_t());
    fn(TypeCase{VolumeValueType::Float32, 16}, float());
    fn(TypeCase{VolumeValueType::Float64, 64}, double());
}

std::string inrHeader(const std::string& body)
{
    std::string h = "#INRIMAGE-4#{\n" + body;
    const size_t total = ((h.size() + 4 + 255) / 256) * 256;
    h.append(total - 4 - h.size(), '\n');
    return h + "##}\n";
}

Bytes toBytes(const std::string& s) { return Bytes(s.begin(), s.end()); }

} // namespace

// ================================================================================ round trips

TEST(VolumeIORoundTrip, NiftiPlainAndGzip)
{
    const fs::path dir = scratchDir("volumeio_nifti_roundtrip");
    const ScalarVolume v = makeVolume();
    for (const char* name : {"a.nii", "b.nii.gz"}) {
        const std::string path = (dir / name).string();
        levelforge::writeNifti(path, v);
        VolumeInfo info;
        const ScalarVolume r = levelforge::readVolume(path, {}, &info);
        expectSameVolume(v, r);
        EXPECT_EQ(info.format, "nifti");
        EXPECT_EQ(info.sourceType, VolumeValueType::Float32);
        const bool gz = std::string(name).find(".gz") != std::string::npos;
        EXPECT_EQ(info.compressed, gz);
        const Bytes bytes = readBytes(path);
        ASSERT_GE(bytes.size(), 2u);
        EXPECT_EQ(bytes[0] == 0x1f && bytes[1] == 0x8b, gz) << "gzip magic";
        if (!gz) EXPECT_EQ(bytes.size(), 352u + 4u * v.voxelCount());
        EXPECT_EQ(info.minValue, -0.75);
        EXPECT_EQ(info.maxValue, 4.0 + 30.0 + 200.0 - 0.75);
        EXPECT_TRUE(info.warnings.empty());
    }
    // Atomic writes leave no temporary file behind; overwriting works.
    levelforge::writeNifti((dir / "a.nii").string(), v);
    EXPECT_EQ(listDir(dir), (std::vector<std::string>{"a.nii", "b.nii.gz"}));
}

TEST(VolumeIORoundTrip, InrPlainAndGzip)
{
    const fs::path dir = scratchDir("volumeio_inr_roundtrip");
    const ScalarVolume v = makeVolume();
    for (const char* name : {"a.inr", "b.inr.gz"}) {
        const std::string path = (dir / name).string();
        levelforge::writeInr(path, v);
        VolumeInfo info;
        const ScalarVolume r = levelforge::readVolume(path, {}, &info);
        expectSameVolume(v, r);
        EXPECT_EQ(info.format, "inr");
        EXPECT_EQ(info.compressed, std::string(name).find(".gz") != std::string::npos);
        if (!info.compressed) {
            const Bytes bytes = readBytes(path);
            EXPECT_EQ(bytes.size(), 256u + 4u * v.voxelCount());
            EXPECT_EQ(std::string(bytes.begin() + 252, bytes.begin() + 256), "##}\n");
        }
    }
    EXPECT_EQ(listDir(dir), (std::vector<std::string>{"a.inr", "b.inr.gz"}));
}

TEST(VolumeIORoundTrip, WriterRejectsUnwritableVolumes)
{
    const fs::path dir = scratchDir("volumeio_writer_errors");
    ScalarVolume v = makeVolume();
    v.data[7] = std::numeric_limits<float>::quiet_NaN();
    const std::string path = (dir / "nan.nii").string();
    expectError<levelforge::InvalidArgumentError>([&] { levelforge::writeNifti(path, v); }, {path, "nan"});
    expectError<levelforge::InvalidArgumentError>([&] { levelforge::writeInr(path, ScalarVolume()); }, {path});
    ScalarVolume wide(openvdb::Coord(40000, 1, 1));
    expectError<levelforge::InvalidArgumentError>([&] { levelforge::writeNifti(path, wide); }, {path, "32767"});
    const std::string missing = (dir / "no" / "dir" / "x.nii").string();
    expectError<levelforge::IoError>([&] { levelforge::writeNifti(missing, makeVolume()); }, {missing});
    EXPECT_TRUE(listDir(dir).empty());
}

// ======================================================================== hand-built NIfTI-1

TEST(VolumeIONifti, EveryDatatypeInBothByteOrders)
{
    const fs::path dir = scratchDir("volumeio_nifti_types");
    forEachType([&](TypeCase tc, auto tag) {
        using T = decltype(tag);
        const std::vector<T> values = sampleValues<T>();
        for (bool big : {false, true}) {
            NiftiSpec s;
            s.datatype = int16_t(tc.niftiCode);
            s.bitpix = int16_t(8 * sizeof(T));
            s.pixdim = {{1, 0.5f, 2.0f, 3.0f, 1, 1, 1, 1}};
            Bytes file = niftiHeader(s, big);
            const Bytes data = encode(values, big);
            file.insert(file.end(), data.begin(), data.end());
            const fs::path path = dir / (levelforge::volumeValueTypeName(tc.type) + (big ? "_be.nii" : "_le.nii"));
            writeBytes(path, file);
            VolumeInfo info;
            const ScalarVolume v = levelforge::readVolume(path.string(), {}, &info);
            SCOPED_TRACE(path.string());
            EXPECT_EQ(info.sourceType, tc.type);
            EXPECT_EQ(info.bigEndian, big);
            EXPECT_EQ(v.dims, openvdb::Coord(3, 2, 2));
            EXPECT_EQ(v.spacing, openvdb::Vec3d(0.5, 2.0, 3.0));
            EXPECT_EQ(v.origin, openvdb::Vec3d(0.0));
            ASSERT_EQ(v.data.size(), values.size());
            for (size_t n = 0; n < values.size(); ++n) EXPECT_EQ(v.data[n], float(values[n])) << "sample " << n;
        }
    });
}

TEST(VolumeIONifti, ScaleSlopeAndInterceptAreApplied)
{
    const fs::path dir = scratchDir("volumeio_nifti_scale");
    NiftiSpec s;
    s.datatype = 4; // int16
    s.bitpix = 16;
    s.slope = 0.5f;
    s.inter = -10.0f;
    Bytes file = niftiHeader(s, true);
    const std::vector<int16_t> raw{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, -10, 1000};
    const Bytes data = encode(raw, true);
    file.insert(file.end(), data.begin(), data.end());
    writeBytes(dir / "s.nii", file);
    const ScalarVolume v = levelforge::readNifti((dir / "s.nii").string());
    for (size_t n = 0; n < raw.size(); ++n) EXPECT_EQ(v.data[n], float(raw[n]) * 0.5f - 10.0f);
}

TEST(VolumeIONifti, HeaderExtensionIsSkippedAndFourthDimensionOfOneAccepted)
{
    const fs::path dir = scratchDir("volumeio_nifti_ext");
    NiftiSpec s;
    s.dim = {{4, 3, 2, 2, 1, 1, 1, 1}};
    s.voxOffset = 352 + 32;
    Bytes file = niftiHeader(s, false);
    file[348] = 1; // extension flag: 32 bytes of extension follow
    file.resize(352 + 32, 0xAB);
    for (int n = 0; n < 12; ++n) file.push_back(uint8_t(n * 3));
    writeBytes(dir / "e.nii", file);
    const ScalarVolume v = levelforge::readNifti((dir / "e.nii").string());
    ASSERT_EQ(v.data.size(), 12u);
    for (int n = 0; n < 12; ++n) EXPECT_EQ(v.data[size_t(n)], float(n * 3));
}

TEST(VolumeIONifti, SformOriginAndReversedAxisKeepWorldPositions)
{
    const fs::path dir = scratchDir("volumeio_nifti_sform");
    NiftiSpec s; // 3 x 2 x 2 uint8, sample n = value n
    s.sformCode = 2;
    s.pixdim = {{1, 2, 3, 4, 1, 1, 1, 1}};
    const float srow[3][4] = {{-2, 0, 0, 90}, {0, 3, 0, -126}, {0, 0, 4, -72}};
    std::memcpy(s.srow, srow, sizeof(srow));
    s.qformCode = 1; // ignored when the sform is set
    s.qoffset = {{1000, 1000, 1000}};
    Bytes file = niftiHeader(s, false);
    for (int n = 0; n < 12; ++n) file.push_back(uint8_t(n));
    writeBytes(dir / "f.nii", file);
    VolumeInfo info;
    const ScalarVolume v = levelforge::readNifti((dir / "f.nii").string(), {}, &info);
    EXPECT_EQ(v.spacing, openvdb::Vec3d(2, 3, 4));
    EXPECT_TRUE(info.reversedAxes[0]);
    EXPECT_FALSE(info.reversedAxes[1]);
    EXPECT_FALSE(info.reversedAxes[2]);
    // File sample (i,j,k) lies at world (90 - 2i, -126 + 3j, -72 + 4k): find it in the volume.
    for (int k = 0; k < 2; ++k) {
        for (int j = 0; j < 2; ++j) {
            for (int i = 0; i < 3; ++i) {
                const openvdb::Vec3d world(90.0 - 2.0 * i, -126.0 + 3.0 * j, -72.0 + 4.0 * k);
                const openvdb::Vec3d idx = (world - v.origin) / v.spacing;
                const int ii = int(std::lround(idx[0])), jj = int(std::lround(idx[1])), kk = int(std::lround(idx[2]));
                ASSERT_TRUE(v.inside(ii, jj, kk));
                EXPECT_NEAR((v.worldPosition(ii, jj, kk) - world).length(), 0.0, 1e-9);
                EXPECT_EQ(v(ii, jj, kk), float(i + 3 * j + 6 * k));
            }
        }
    }
}

TEST(VolumeIONifti, QformOffsetAndQfac)
{
    const fs::path dir = scratchDir("volumeio_nifti_qform");
    NiftiSpec s;
    s.qformCode = 1;
    s.pixdim = {{-1, 1.5f, 2.5f, 0.5f, 1, 1, 1, 1}}; // qfac = -1: z steps backwards
    s.qoffset = {{-5, 7, 20}};
    Bytes file = niftiHeader(s, false);
    for (int n = 0; n < 12; ++n) file.push_back(uint8_t(n));
    writeBytes(dir / "q.nii", file);
    VolumeInfo info;
    const ScalarVolume v = levelforge::readNifti((dir / "q.nii").string(), {}, &info);
    EXPECT_EQ(v.spacing, openvdb::Vec3d(1.5, 2.5, 0.5));
    EXPECT_EQ(v.origin, openvdb::Vec3d(-5, 7, 20 - 0.5));
    EXPECT_TRUE(info.reversedAxes[2]);
    // File slice k=0 (values 0..5) is at z = 20, the top: it is now slice 1.
    EXPECT_EQ(v(0, 0, 1), 0.0f);
    EXPECT_EQ(v(2, 1, 1), 5.0f);
    EXPECT_EQ(v(0, 0, 0), 6.0f);

    // A rotation cannot be represented: voxel sizes and offset are kept, and a warning says so.
    s.pixdim[0] = 1;
    s.quat = {{0, 0, float(std::sin(0.25))}}; // 0.5 rad about z
    file = niftiHeader(s, false);
    for (int n = 0; n < 12; ++n) file.push_back(uint8_t(n));
    writeBytes(dir / "rot.nii", file);
    const ScalarVolume r = levelforge::readNifti((dir / "rot.nii").string(), {}, &info);
    EXPECT_NEAR(r.spacing[0], 1.5, 1e-6);
    EXPECT_NEAR(r.spacing[1], 2.5, 1e-6);
    EXPECT_NEAR(r.spacing[2], 0.5, 1e-6);
    EXPECT_EQ(r.origin, openvdb::Vec3d(-5, 7, 20));
    ASSERT_EQ(info.warnings.size(), 1u);
    EXPECT_NE(info.warnings[0].find("rotates"), std::string::npos) << info.warnings[0];
}

TEST(VolumeIONifti, BadHeadersGiveTypedErrorsNamingFileAndField)
{
    const fs::path dir = scratchDir("volumeio_nifti_bad");
    auto writeSpec = [&](const std::string& name, const NiftiSpec& s, size_t dataBytes) {
        Bytes file = niftiHeader(s, false);
        file.resize(file.size() + dataBytes, 1);
        writeBytes(dir / name, file);
        return (dir / name).string();
    };
    using levelforge::InvalidVolumeError;
    NiftiSpec s;
    {
        NiftiSpec t = s;
        t.datatype = 32;
        const std::string p = writeSpec("complex.nii", t, 96);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "unsupported datatype 32"});
        t.datatype = 128;
        const std::string q = writeSpec("rgb.nii", t, 36);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(q); }, {q, "unsupported datatype 128", "rgb"});
    }
    {
        NiftiSpec t = s;
        t.dim = {{4, 3, 2, 2, 5, 1, 1, 1}};
        const std::string p = writeSpec("series.nii", t, 60);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "dim[4] = 5"});
    }
    {
        NiftiSpec t = s;
        t.dim[2] = 0;
        const std::string p = writeSpec("zero.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "dim[2] = 0"});
        t.dim[2] = -4;
        const std::string q = writeSpec("neg.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(q); }, {q, "dim[2] = -4"});
    }
    {
        NiftiSpec t = s;
        t.pixdim[2] = 0;
        const std::string p = writeSpec("pix0.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "pixdim[2]"});
        t.pixdim[2] = std::numeric_limits<float>::quiet_NaN();
        const std::string q = writeSpec("pixnan.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(q); }, {q, "pixdim[2] = nan"});
    }
    {
        const std::string p = writeSpec("short.nii", s, 11);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); },
                                        {p, "truncated", "claims 3x2x2 voxels of 1 byte (12 bytes)", "only 11 bytes"});
    }
    {
        NiftiSpec t = s;
        t.sizeofHdr = 540;
        const std::string p = writeSpec("nifti2.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "NIfTI-2"});
        t.sizeofHdr = 123;
        const std::string q = writeSpec("garbage.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(q); }, {q, "sizeof_hdr = 123"});
    }
    {
        NiftiSpec t = s;
        t.magic = std::string("ni1", 4);
        const std::string p = writeSpec("pair.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "ni1"});
    }
    {
        NiftiSpec t = s;
        t.voxOffset = 100;
        const std::string p = writeSpec("offset.nii", t, 12);
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "vox_offset = 100"});
    }
    {
        NiftiSpec t = s;
        t.dim = {{3, 2000, 2000, 1000, 1, 1, 1, 1}};
        const std::string p = writeSpec("huge.nii", t, 12);
        levelforge::ReadVolumeOptions opt;
        opt.maxVoxels = 1000000;
        expectError<levelforge::ResourceLimitError>([&] { levelforge::readVolume(p, opt); },
                                                    {p, "4000000000", "1000000"});
    }
    {
        // NaN sample in float data: the voxel is named.
        NiftiSpec t = s;
        t.datatype = 16;
        t.bitpix = 32;
        Bytes file = niftiHeader(t, false);
        for (int n = 0; n < 12; ++n) append(file, n == 10 ? std::numeric_limits<float>::quiet_NaN() : float(n), false);
        writeBytes(dir / "nan.nii", file);
        const std::string p = (dir / "nan.nii").string();
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(p); }, {p, "voxel (1, 1, 1) is nan"});
        file = niftiHeader(t, false);
        for (int n = 0; n < 12; ++n) append(file, n == 4 ? std::numeric_limits<float>::infinity() : float(n), false);
        writeBytes(dir / "inf.nii", file);
        const std::string q = (dir / "inf.nii").string();
        expectError<InvalidVolumeError>([&] { levelforge::readVolume(q); }, {q, "voxel (1, 1, 0) is inf"});
    }
}

// ============================================================================ hand-built INR

TEST(VolumeIOInr, TypesByteOrdersAndHeaderKeys)
{
    const fs::path dir = scratchDir("volumeio_inr_types");
    // Big-endian unsigned 16-bit (CPU=sun), spacing, origin.
    {
        std::string h = inrHeader("XDIM=3\nYDIM=2\nZDIM=2\nVDIM=1\nTYPE=unsigned fixed\nPIXSIZE=16 bits\n"
                                  "SCALE=2**0\nCPU=sun\nVX=0.25\nVY=0.5\nVZ=4\nXO=1\nYO=-2\nZO=3.5\n");
        Bytes file = toBytes(h);
        for (int n = 0; n < 12; ++n) append(file, uint16_t(n * 5000), true);
        writeBytes(dir / "u16.inr", file);
        VolumeInfo info;
        const ScalarVolume v = levelforge::readVolume((dir / "u16.inr").string(), {}, &info);
        EXPECT_EQ(info.sourceType, VolumeValueType::UInt16);
        EXPECT_TRUE(info.bigEndian);
        EXPECT_EQ(v.dims, openvdb::Coord(3, 2, 2));
        EXPECT_EQ(v.spacing, openvdb::Vec3d(0.25, 0.5, 4));
        EXPECT_EQ(v.origin, openvdb::Vec3d(1, -2, 3.5));
        for (int n = 0; n < 12; ++n) EXPECT_EQ(v.data[size_t(n)], float(n * 5000));
    }
    // Signed 8-bit, no ZDIM (defaults to 1); double on a pc; a header longer than 256 bytes.
    {
        Bytes file = toBytes(inrHeader("XDIM=4\nYDIM=3\nTYPE=signed fixed\nPIXSIZE=8 bits\nCPU=pc\n"));
        for (int n = 0; n < 12; ++n) file.push_back(uint8_t(int8_t(n - 6)));
        writeBytes(dir / "s8.inr", file);
        const ScalarVolume v = levelforge::readInr((dir / "s8.inr").string());
        EXPECT_EQ(v.dims, openvdb::Coord(4, 3, 1));
        for (int n = 0; n < 12; ++n) EXPECT_EQ(v.data[size_t(n)], float(n - 6));
    }
    {
        std::string body = "XDIM=2\nYDIM=2\nZDIM=3\nTYPE=float\nPIXSIZE=64 bits\nCPU=sgi\n#" + std::string(300, 'c') + "\n";
        Bytes file = toBytes(inrHeader(body));
        ASSERT_EQ(file.size(), 512u);
        for (int n = 0; n < 12; ++n) append(file, double(n) / 8.0 - 1e-3, true);
        writeBytes(dir / "f64.inr", file);
        VolumeInfo info;
        const ScalarVolume v = levelforge::readInr((dir / "f64.inr").string(), {}, &info);
        EXPECT_EQ(info.sourceType, VolumeValueType::Float64);
        for (int n = 0; n < 12; ++n) EXPECT_EQ(v.data[size_t(n)], float(double(n) / 8.0 - 1e-3));
    }
}

TEST(VolumeIOInr, BadHeadersGiveTypedErrors)
{
    const fs::path dir = scratchDir("volumeio_inr_bad");
    using levelforge::InvalidVolumeError;
    auto make = [&](const std::string& name, const std::string& body, size_t dataBytes) {
        Bytes file = toBytes(inrHeader(body));
        file.resize(file.size() + dataBytes, 0);
        writeBytes(dir / name, file);
        return (dir / name).string();
    };
    const std::string vdim = make("vdim.inr", "XDIM=2\nYDIM=2\nZDIM=2\nVDIM=3\nTYPE=float\nPIXSIZE=32 bits\nCPU=decm\n", 96);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(vdim); }, {vdim, "VDIM = 3"});
    const std::string type = make("type.inr", "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=packed\nPIXSIZE=8 bits\nCPU=decm\n", 8);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(type); }, {type, "unsupported TYPE 'packed'"});
    const std::string bits = make("bits.inr", "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=float\nPIXSIZE=16 bits\nCPU=decm\n", 16);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(bits); }, {bits, "PIXSIZE=16"});
    const std::string zero = make("zero.inr", "XDIM=2\nYDIM=0\nZDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=decm\n", 0);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(zero); }, {zero, "YDIM = 0"});
    const std::string vx = make("vx.inr", "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=float\nPIXSIZE=32 bits\nVX=abc\n", 32);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(vx); }, {vx, "VX"});
    const std::string cpu = make("cpu.inr", "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=vax\n", 32);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(cpu); }, {cpu, "CPU 'vax'"});
    const std::string trunc = make("trunc.inr", "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=decm\n", 31);
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(trunc); },
                                    {trunc, "truncated", "claims 2x2x2 voxels of 4 bytes (32 bytes)", "only 31 bytes"});
    // Dimensions whose product overflows 64 bits are refused before anything is allocated.
    const std::string huge = make("huge.inr", "XDIM=2000000000\nYDIM=2000000000\nZDIM=2000000000\nTYPE=float\n"
                                              "PIXSIZE=64 bits\nCPU=decm\n", 8);
    expectError<levelforge::ResourceLimitError>([&] { levelforge::readVolume(huge); }, {huge, "overflows 64 bits"});
    Bytes noEnd = toBytes("#INRIMAGE-4#{\nXDIM=2\n");
    noEnd.resize(700, '\n');
    writeBytes(dir / "noend.inr", noEnd);
    const std::string ne = (dir / "noend.inr").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(ne); }, {ne, "##}"});
    writeBytes(dir / "magic.inr", toBytes(std::string(300, 'x')));
    const std::string mg = (dir / "magic.inr").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(mg); }, {mg, "INRIMAGE-4"});
}

// ============================================================================== VolPack .den

namespace {

Bytes denFile(int nx, int ny, int nz, bool big, int version = 1, int mapLengthDelta = 0)
{
    Bytes b;
    append(b, int16_t(version), big);
    const int len[3] = {nx, ny, nz};
    for (int block = 0; block < 3; ++block) { // orig, extr, map: min, max, len
        for (int a = 0; a < 3; ++a) append(b, int16_t(0), big);
        for (int a = 0; a < 3; ++a) append(b, int16_t(len[a] - 1), big);
        for (int a = 0; a < 3; ++a) append(b, int16_t(len[a]), big);
    }
    append(b, int16_t(0), big); // warps
    append(b, int32_t(nx * ny * nz + mapLengthDelta), big);
    for (int n = 0; n < nx * ny * nz; ++n) b.push_back(uint8_t(n * 11));
    return b;
}

} // namespace

TEST(VolumeIODen, HandBuiltFilesInBothByteOrders)
{
    const fs::path dir = scratchDir("volumeio_den");
    for (bool big : {false, true}) {
        const Bytes file = denFile(4, 3, 2, big);
        ASSERT_EQ(file.size(), 62u + 24u);
        const fs::path path = dir / (big ? "be.den" : "le.den");
        writeBytes(path, file);
        VolumeInfo info;
        const ScalarVolume v = levelforge::readVolume(path.string(), {}, &info);
        EXPECT_EQ(info.format, "den");
        EXPECT_EQ(info.bigEndian, big);
        EXPECT_EQ(v.dims, openvdb::Coord(4, 3, 2));
        EXPECT_EQ(v.spacing, openvdb::Vec3d(1.0));
        for (int n = 0; n < 24; ++n) EXPECT_EQ(v.data[size_t(n)], float(uint8_t(n * 11)));
    }
}

TEST(VolumeIODen, BadFilesGiveTypedErrors)
{
    const fs::path dir = scratchDir("volumeio_den_bad");
    using levelforge::InvalidVolumeError;
    writeBytes(dir / "version.den", denFile(4, 3, 2, false, 7));
    const std::string ver = (dir / "version.den").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(ver); }, {ver, "version field = 7"});
    writeBytes(dir / "length.den", denFile(4, 3, 2, false, 1, 5));
    const std::string len = (dir / "length.den").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(len); }, {len, "map_length = 29"});
    Bytes shorter = denFile(4, 3, 2, false);
    shorter.pop_back();
    writeBytes(dir / "short.den", shorter);
    const std::string sh = (dir / "short.den").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(sh); },
                                    {sh, "truncated", "claims 4x3x2 voxels of 1 byte (24 bytes)", "only 23 bytes"});
    Bytes longer = denFile(4, 3, 2, false);
    longer.push_back(0);
    writeBytes(dir / "long.den", longer);
    const std::string lo = (dir / "long.den").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(lo); }, {lo, "1 bytes after"});
    Bytes zero = denFile(4, 3, 2, false);
    putAt(zero, 50 + 2, int16_t(0), false); // map_len[1] = 0
    writeBytes(dir / "zero.den", zero);
    const std::string ze = (dir / "zero.den").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(ze); }, {ze, "map_len[1] = 0"});
}

// ===================================================================================== raw

TEST(VolumeIORaw, EveryValueTypeBothByteOrdersWithHeader)
{
    const fs::path dir = scratchDir("volumeio_raw");
    forEachType([&](TypeCase tc, auto tag) {
        using T = decltype(tag);
        const std::vector<T> values = sampleValues<T>();
        for (bool big : {false, true}) {
            Bytes file(17, 0xEE); // a 17-byte header to skip
            const Bytes data = encode(values, big);
            file.insert(file.end(), data.begin(), data.end());
            const fs::path path = dir / (levelforge::volumeValueTypeName(tc.type) + (big ? "_be.raw" : "_le.raw"));
            writeBytes(path, file);
            levelforge::ReadVolumeOptions opt;
            opt.raw = levelforge::RawVolumeLayout{openvdb::Coord(2, 3, 2), tc.type, big,
                                                  openvdb::Vec3d(0.1, 0.2, 0.3), openvdb::Vec3d(1, 2, 3), 17};
            VolumeInfo info;
            const ScalarVolume v = levelforge::readVolume(path.string(), opt, &info);
            SCOPED_TRACE(path.string());
            EXPECT_EQ(info.format, "raw");
            EXPECT_EQ(info.sourceType, tc.type);
            EXPECT_EQ(v.dims, openvdb::Coord(2, 3, 2));
            EXPECT_EQ(v.spacing, openvdb::Vec3d(0.1, 0.2, 0.3));
            EXPECT_EQ(v.origin, openvdb::Vec3d(1, 2, 3));
            for (size_t n = 0; n < values.size(); ++n) EXPECT_EQ(v.data[n], float(values[n])) << "sample " << n;
        }
    });
}

TEST(VolumeIORaw, SizeMismatchAndMissingLayout)
{
    const fs::path dir = scratchDir("volumeio_raw_bad");
    writeBytes(dir / "v.raw", Bytes(2 * 3 * 4 * 2, 1));
    const std::string p = (dir / "v.raw").string();
    levelforge::ReadVolumeOptions opt;
    opt.raw = levelforge::RawVolumeLayout{openvdb::Coord(2, 3, 4), VolumeValueType::Int16};
    EXPECT_EQ(levelforge::readVolume(p, opt).voxelCount(), 24u);
    opt.raw->dims = openvdb::Coord(2, 3, 5); // file too short
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(p, opt); },
                                                {p, "truncated", "the raw layout claims 2x3x5 voxels of 2 bytes (60 bytes)",
                                                 "only 48 bytes"});
    opt.raw->dims = openvdb::Coord(2, 3, 3); // file too long
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(p, opt); },
                                                {p, "size mismatch", "expected 36 bytes", "has 48"});
    opt.raw->dims = openvdb::Coord(2, 0, 3);
    expectError<levelforge::InvalidArgumentError>([&] { levelforge::readVolume(p, opt); }, {p, "2x0x3"});
    expectError<levelforge::InvalidArgumentError>([&] { levelforge::readVolume(p); }, {p, "RawVolumeLayout"});
    opt.raw->dims = openvdb::Coord(2, 3, 4);
    opt.maxVoxels = 23;
    expectError<levelforge::ResourceLimitError>([&] { levelforge::readVolume(p, opt); }, {p, "24", "23"});
    // An unknown extension with a layout is read as raw.
    fs::copy_file(p, dir / "v.dat");
    opt.maxVoxels = 100;
    EXPECT_EQ(levelforge::readVolume((dir / "v.dat").string(), opt).voxelCount(), 24u);
}

// ================================================================================ detection

TEST(VolumeIODetection, ContentDecidesForUnknownExtensionsAndErrorsNameTheFile)
{
    const fs::path dir = scratchDir("volumeio_detect");
    const ScalarVolume v = makeVolume();
    levelforge::writeNifti((dir / "a.nii.gz").string(), v);
    levelforge::writeInr((dir / "b.inr").string(), v);
    fs::copy_file(dir / "a.nii.gz", dir / "a.bin");
    fs::copy_file(dir / "b.inr", dir / "b.img");
    VolumeInfo info;
    expectSameVolume(v, levelforge::readVolume((dir / "a.bin").string(), {}, &info));
    EXPECT_EQ(info.format, "nifti");
    EXPECT_TRUE(info.compressed);
    expectSameVolume(v, levelforge::readVolume((dir / "b.img").string(), {}, &info));
    EXPECT_EQ(info.format, "inr");
    EXPECT_TRUE(levelforge::isReadableVolumeFile("x/Brain.NII.GZ"));
    EXPECT_TRUE(levelforge::isReadableVolumeFile("skull.inr"));
    EXPECT_FALSE(levelforge::isReadableVolumeFile("data.raw"));
    EXPECT_FALSE(levelforge::isReadableVolumeFile("mesh.obj"));

    writeBytes(dir / "junk.xyz", Bytes(1000, 7));
    const std::string junk = (dir / "junk.xyz").string();
    expectError<levelforge::IoError>([&] { levelforge::readVolume(junk); }, {junk, "unrecognised"});
    const std::string missing = (dir / "missing.nii").string();
    expectError<levelforge::IoError>([&] { levelforge::readVolume(missing); }, {missing, "no such file"});
    expectError<levelforge::IoError>([&] { levelforge::readVolume(dir.string() + "/"); }, {dir.string()});
}

// ============================================================ declared size against the file

namespace {

/// @a data as a gzip file made of stored (uncompressed) deflate blocks: no zlib needed here.
Bytes gzipStored(const Bytes& data)
{
    static uint32_t table[256];
    static bool init = false;
    if (!init) {
        for (uint32_t n = 0; n < 256; ++n) {
            uint32_t c = n;
            for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            table[n] = c;
        }
        init = true;
    }
    uint32_t crc = 0xFFFFFFFFu;
    for (unsigned char b : data) crc = table[(crc ^ b) & 0xFF] ^ (crc >> 8);
    crc ^= 0xFFFFFFFFu;
    Bytes out = {0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 0xff};
    size_t pos = 0;
    do {
        const size_t n = std::min<size_t>(65535, data.size() - pos);
        out.push_back(pos + n == data.size() ? 1 : 0); // BFINAL, BTYPE = stored
        append(out, uint16_t(n), false);
        append(out, uint16_t(~n), false);
        out.insert(out.end(), data.begin() + long(pos), data.begin() + long(pos + n));
        pos += n;
    } while (pos < data.size());
    append(out, crc, false);
    append(out, uint32_t(data.size()), false);
    return out;
}

/// A uint8 NIfTI-1 file (header + @a dataBytes samples n * 7 % 251) claiming @a nx x ny x nz.
Bytes niftiClaiming(int16_t nx, int16_t ny, int16_t nz, size_t dataBytes)
{
    NiftiSpec s;
    s.dim = {{3, nx, ny, nz, 1, 1, 1, 1}};
    Bytes file = niftiHeader(s, false);
    for (size_t n = 0; n < dataBytes; ++n) file.push_back(uint8_t(n * 7 % 251));
    return file;
}

} // namespace

TEST(VolumeIODeclaredSize, PlainFilesAreCheckedBeforeAllocating)
{
    const fs::path dir = scratchDir("volumeio_declared_plain");
    using levelforge::InvalidVolumeError;
    writeBytes(dir / "brain.nii", niftiClaiming(181, 217, 181, 2634));
    const std::string nii = (dir / "brain.nii").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(nii); },
                                    {nii, "the header claims 181x217x181 voxels of 1 byte (7.1 MB)",
                                     "the file holds only 2,634 bytes of data"});
    // vox_offset beyond the end of the file: no data at all.
    NiftiSpec far;
    far.voxOffset = 1e8f;
    writeBytes(dir / "far.nii", niftiHeader(far, false));
    const std::string farPath = (dir / "far.nii").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(farPath); }, {farPath, "only 0 bytes"});
    // .den: a 62-byte header claiming 1000^3 voxels (and a matching map_length) over 24 bytes.
    Bytes den = denFile(4, 3, 2, false);
    for (int a = 0; a < 3; ++a) putAt(den, 50 + 2 * size_t(a), int16_t(1000), false);
    putAt(den, 58, int32_t(1000000000), false);
    writeBytes(dir / "big.den", den);
    const std::string bigDen = (dir / "big.den").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(bigDen); },
                                    {bigDen, "claims 1000x1000x1000 voxels of 1 byte (1.0 GB)", "only 24 bytes"});
}

TEST(VolumeIODeclaredSize, GzipFilesAreBoundedAndGrowAsDataArrives)
{
    const fs::path dir = scratchDir("volumeio_declared_gzip");
    using levelforge::InvalidVolumeError;
    // A few hundred bytes of gzip cannot hold a gigabyte: refused from the deflate bound.
    writeBytes(dir / "tiny.nii.gz", gzipStored(niftiClaiming(1000, 1000, 1000, 100)));
    const std::string tiny = (dir / "tiny.nii.gz").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(tiny); },
                                    {tiny, "claims 1000x1000x1000 voxels of 1 byte (1.0 GB)", "a gzip file of",
                                     "decompresses to at most"});
    // Within the bound but short: read (memory grows with the data) until the data ends.
    writeBytes(dir / "short.nii.gz", gzipStored(niftiClaiming(200, 200, 100, 100000)));
    const std::string shortGz = (dir / "short.nii.gz").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(shortGz); },
                                    {shortGz, "truncated", "expected 4000000 bytes", "decompressed file has 100000"});
    // A complete gzip volume larger than one read chunk (2^22 samples) reads back exactly.
    writeBytes(dir / "full.nii.gz", gzipStored(niftiClaiming(250, 200, 100, 5000000)));
    VolumeInfo info;
    const ScalarVolume v = levelforge::readVolume((dir / "full.nii.gz").string(), {}, &info);
    EXPECT_TRUE(info.compressed);
    ASSERT_EQ(v.data.size(), 5000000u);
    EXPECT_LE(v.data.capacity(), 5000000u);
    for (size_t n : {size_t(0), size_t(1), size_t(4194303), size_t(4194304), size_t(4999999)})
        EXPECT_EQ(v.data[n], float(uint8_t(n * 7 % 251))) << "sample " << n;
    // A gzip raw file: the layout is checked the same way.
    writeBytes(dir / "small.raw.gz", gzipStored(Bytes(10, 1)));
    levelforge::ReadVolumeOptions opt;
    opt.raw = levelforge::RawVolumeLayout{openvdb::Coord(1000, 1000, 1000), VolumeValueType::Float64};
    const std::string raw = (dir / "small.raw.gz").string();
    expectError<InvalidVolumeError>([&] { levelforge::readVolume(raw, opt); },
                                    {raw, "the raw layout claims 1000x1000x1000 voxels of 8 bytes (8.0 GB)"});
}

TEST(VolumeIODetection, CorruptGzipIsAnIoErrorNamingTheFile)
{
    const fs::path dir = scratchDir("volumeio_gz_bad");
    ScalarVolume v(openvdb::Coord(40, 30, 20));
    for (size_t n = 0; n < v.data.size(); ++n) v.data[n] = float((n * 2654435761u) % 1000) * 0.01f;
    levelforge::writeNifti((dir / "ok.nii.gz").string(), v);
    const Bytes good = readBytes(dir / "ok.nii.gz");
    ASSERT_GT(good.size(), 1000u);

    Bytes flipped = good;
    for (size_t n = good.size() / 2; n < good.size() / 2 + 64; ++n) flipped[n] ^= 0x5A;
    writeBytes(dir / "flipped.nii.gz", flipped);
    const std::string f = (dir / "flipped.nii.gz").string();
    expectError<levelforge::IoError>([&] { levelforge::readVolume(f); }, {f, "gzip"});

    Bytes truncated(good.begin(), good.begin() + long(good.size() / 2));
    writeBytes(dir / "truncated.nii.gz", truncated);
    const std::string t = (dir / "truncated.nii.gz").string();
    expectError<levelforge::IoError>([&] { levelforge::readVolume(t); }, {t, "gzip"});

    Bytes badCrc = good;
    badCrc[good.size() - 6] ^= 0xFF; // inside the CRC32 of the trailer
    writeBytes(dir / "crc.nii.gz", badCrc);
    const std::string c = (dir / "crc.nii.gz").string();
    expectError<levelforge::IoError>([&] { levelforge::readVolume(c); }, {c, "gzip"});
}

// ===================================================================================== vdb

TEST(VolumeIOVdb, FloatGridOverActiveBoundingBoxWithAnisotropicTransform)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("volumeio_vdb_float");
    auto vec = openvdb::Vec3SGrid::create();
    vec->setName("velocity");
    vec->tree().setValue(openvdb::Coord(0, 0, 0), openvdb::Vec3f(1, 2, 3));
    auto grid = openvdb::FloatGrid::create(2.0f);
    grid->setName("density");
    auto map = std::make_shared<openvdb::math::ScaleTranslateMap>(openvdb::Vec3d(0.5, 0.25, 2.0),
                                                                  openvdb::Vec3d(1.0, -2.0, 3.0));
    grid->setTransform(std::make_shared<openvdb::math::Transform>(map));
    auto acc = grid->getAccessor();
    acc.setValue(openvdb::Coord(-3, 1, 4), -1.5f);
    acc.setValue(openvdb::Coord(2, 5, 6), 0.75f);
    acc.setValue(openvdb::Coord(0, 3, 5), 9.0f);
    acc.setValueOff(openvdb::Coord(1, 2, 5), -2.0f); // inactive, inside the box: keeps its value
    levelforge::writeGridsAtomic((dir / "g.vdb").string(), openvdb::GridPtrVec{vec, grid});

    VolumeInfo info;
    const ScalarVolume v = levelforge::readVolume((dir / "g.vdb").string(), {}, &info);
    EXPECT_EQ(info.format, "vdb");
    EXPECT_EQ(info.gridName, "density");
    EXPECT_EQ(info.sourceType, VolumeValueType::Float32);
    EXPECT_EQ(v.dims, openvdb::Coord(6, 5, 3));
    EXPECT_EQ(v.spacing, openvdb::Vec3d(0.5, 0.25, 2.0));
    EXPECT_EQ(v.origin, openvdb::Vec3d(-3 * 0.5 + 1.0, 1 * 0.25 - 2.0, 4 * 2.0 + 3.0));
    const openvdb::Coord lo(-3, 1, 4);
    for (int k = 0; k < v.dims.z(); ++k) {
        for (int j = 0; j < v.dims.y(); ++j) {
            for (int i = 0; i < v.dims.x(); ++i) {
                const openvdb::Coord ijk = lo + openvdb::Coord(i, j, k);
                ASSERT_EQ(v(i, j, k), grid->tree().getValue(ijk)) << ijk;
                EXPECT_NEAR((v.worldPosition(i, j, k) - grid->transform().indexToWorld(ijk)).length(), 0.0, 1e-12);
            }
        }
    }
    EXPECT_EQ(v(0, 0, 0), -1.5f);
    EXPECT_EQ(v(5, 4, 2), 0.75f);
    EXPECT_EQ(v(4, 1, 1), -2.0f);
    EXPECT_EQ(v(1, 0, 0), 2.0f); // background
    EXPECT_EQ(info.minValue, -2.0);
    EXPECT_EQ(info.maxValue, 9.0);
}

TEST(VolumeIOVdb, IntegerAndDoubleGridsByName)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("volumeio_vdb_int");
    auto i32 = openvdb::Int32Grid::create(-7);
    i32->setName("a_labels"); // OpenVDB lists grids by name: this one is first
    i32->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
    i32->tree().setValue(openvdb::Coord(0, 0, 0), 5);
    i32->tree().setValue(openvdb::Coord(1, 1, 0), 123456);
    auto i64 = openvdb::Int64Grid::create(0);
    i64->setName("counts");
    i64->tree().setValue(openvdb::Coord(10, 10, 10), int64_t(1) << 40);
    auto dbl = openvdb::DoubleGrid::create(0.0);
    dbl->setName("precise");
    dbl->tree().setValue(openvdb::Coord(0, 0, 0), 0.125);
    dbl->tree().setValue(openvdb::Coord(0, 0, 1), -3.5);
    levelforge::writeGridsAtomic((dir / "g.vdb").string(), openvdb::GridPtrVec{i32, i64, dbl});
    const std::string path = (dir / "g.vdb").string();

    VolumeInfo info;
    ScalarVolume v = levelforge::readVolume(path, {}, &info); // first scalar grid
    EXPECT_EQ(info.gridName, "a_labels");
    EXPECT_EQ(info.sourceType, VolumeValueType::Int32);
    EXPECT_EQ(v.dims, openvdb::Coord(2, 2, 1));
    EXPECT_NEAR(v.spacing[0], 0.1, 1e-15);
    EXPECT_EQ(v.data, (std::vector<float>{5.0f, -7.0f, -7.0f, 123456.0f}));

    levelforge::ReadVolumeOptions opt;
    opt.vdbGridName = "counts";
    v = levelforge::readVolume(path, opt, &info);
    EXPECT_EQ(info.sourceType, VolumeValueType::Int64);
    EXPECT_EQ(v.dims, openvdb::Coord(1, 1, 1));
    EXPECT_EQ(v.origin, openvdb::Vec3d(10, 10, 10));
    EXPECT_EQ(v.data[0], float(int64_t(1) << 40));

    opt.vdbGridName = "precise";
    v = levelforge::readVdbVolume(path, opt, &info);
    EXPECT_EQ(info.sourceType, VolumeValueType::Float64);
    EXPECT_EQ(v.data, (std::vector<float>{0.125f, -3.5f}));

    opt.vdbGridName = "nothere";
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(path, opt); },
                                                {path, "no grid named 'nothere'", "a_labels", "counts"});
}

TEST(VolumeIOVdb, UnsupportedGridsAndTransformsAreRejected)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("volumeio_vdb_bad");
    auto vec = openvdb::Vec3SGrid::create();
    vec->setName("velocity");
    vec->tree().setValue(openvdb::Coord(0, 0, 0), openvdb::Vec3f(1, 2, 3));
    levelforge::writeGridsAtomic((dir / "vec.vdb").string(), openvdb::GridPtrVec{vec});
    const std::string vp = (dir / "vec.vdb").string();
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(vp); }, {vp, "no float, double"});
    levelforge::ReadVolumeOptions opt;
    opt.vdbGridName = "velocity";
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(vp, opt); }, {vp, "vec3s"});

    auto rot = openvdb::FloatGrid::create(0.0f);
    rot->setName("rotated");
    auto xf = openvdb::math::Transform::createLinearTransform(0.5);
    xf->postRotate(0.3, openvdb::math::Z_AXIS);
    rot->setTransform(xf);
    rot->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    levelforge::writeGridsAtomic((dir / "rot.vdb").string(), openvdb::GridPtrVec{rot});
    const std::string rp = (dir / "rot.vdb").string();
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(rp); }, {rp, "rotated", "rotates"});

    auto empty = openvdb::FloatGrid::create(0.0f);
    empty->setName("empty");
    levelforge::writeGridsAtomic((dir / "empty.vdb").string(), openvdb::GridPtrVec{empty});
    const std::string ep = (dir / "empty.vdb").string();
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(ep); }, {ep, "no active voxels"});

    writeBytes(dir / "fake.vdb", Bytes(100, 3));
    const std::string fp = (dir / "fake.vdb").string();
    expectError<levelforge::IoError>([&] { levelforge::readVolume(fp); }, {fp});
}

TEST(VolumeIOVdb, DenseBoxMustStayInsideTheIntRange)
{
    // tests/data/fuzz/vdb/ubsan-copytodense-bbox-near-int-min.vdb: two active voxels near -2^31
    // pass the sample limit, but copyToDense() splits the box at (min + max) / 2 and overflows
    // int (and writes outside the dense buffer).
    openvdb::initialize();
    const fs::path dir = scratchDir("volumeio_vdb_int_range");
    auto far = openvdb::Int32Grid::create(0);
    far->setName("labels");
    far->tree().setValue(openvdb::Coord(-2013265921, -4091, 16773122), 1);
    far->tree().setValue(openvdb::Coord(-2013265921, -4090, 16773122), 2);
    const std::string fp = (dir / "far.vdb").string();
    levelforge::writeGridsAtomic(fp, openvdb::GridPtrVec{far});
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVolume(fp); },
                                                {fp, "grid 'labels'", "-2013265921", "2^30"});
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbVolume(fp); }, {fp, "grid 'labels'", "2^30"});

    // inside the range, until the padding takes the box past it
    auto edge = openvdb::FloatGrid::create(0.0f);
    edge->setName("edge");
    const int top = (1 << 30) - 2;
    edge->tree().setValue(openvdb::Coord(top, 0, 0), 3.0f);
    const std::string ep = (dir / "edge.vdb").string();
    levelforge::writeGridsAtomic(ep, openvdb::GridPtrVec{edge});
    levelforge::ReadVolumeOptions opt;
    const ScalarVolume v = levelforge::readVdbVolume(ep, opt);
    EXPECT_EQ(v.dims, openvdb::Coord(1, 1, 1));
    EXPECT_EQ(v.data, std::vector<float>{3.0f});
    EXPECT_EQ(v.origin, openvdb::Vec3d(top, 0, 0));
    opt.vdbPadding = 1;
    EXPECT_EQ(levelforge::readVdbVolume(ep, opt).dims, openvdb::Coord(3, 3, 3));
    opt.vdbPadding = 3;
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbVolume(ep, opt); },
                                                {ep, "grid 'edge'", "3 voxels of padding", "2^30"});
}

TEST(VolumeIOVdb, ScalarGridWithNaNOrInfIsRejected)
{
    openvdb::initialize();
    const fs::path dir = scratchDir("volumeio_vdb_nonfinite");
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    auto write = [&](const std::string& name, const openvdb::GridBase::Ptr& g) {
        const std::string p = (dir / name).string();
        levelforge::writeGridsAtomic(p, openvdb::GridPtrVec{g});
        return p;
    };
    // a finite grid over many leaves is read as it is
    auto good = openvdb::FloatGrid::create(1.0f);
    good->setName("density");
    for (int i = 0; i < 64; ++i) good->tree().setValue(openvdb::Coord(8 * i, -3 * i, i), float(i));
    const std::string gp = write("good.vdb", good);
    EXPECT_EQ(levelforge::readVdbScalarGrid(gp)->activeVoxelCount(), 64);

    // active voxels: the first bad voxel in tree order is named, whatever the thread count
    auto voxel = good->deepCopy();
    voxel->tree().setValue(openvdb::Coord(400, -150, 50), nan);
    voxel->tree().setValue(openvdb::Coord(-40, 7, 9), inf); // first leaf in tree order
    const std::string vp = write("voxel.vdb", voxel);
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbScalarGrid(vp); },
                                                {vp, "grid 'density'", "active voxel (-40, 7, 9)", "non-finite"});
    // an inactive voxel of a leaf too (OpenVDB tools read it)
    auto inactive = good->deepCopy();
    inactive->tree().setValueOff(openvdb::Coord(8, -3, 2), nan);
    const std::string ip = write("inactive.vdb", inactive);
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbScalarGrid(ip); },
                                                {ip, "grid 'density'", "inactive voxel (8, -3, 2)", "non-finite"});
    // an active tile (8³ at level 1)
    auto tile = good->deepCopy();
    tile->tree().addTile(1, openvdb::Coord(-800, 0, 0), inf, true);
    const std::string tp = write("tile.vdb", tile);
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbScalarGrid(tp); },
                                                {tp, "grid 'density'", "active tile (-800, 0, 0)", "non-finite"});
    // the background
    auto bg = openvdb::FloatGrid::create(nan);
    bg->setName("density");
    bg->tree().setValue(openvdb::Coord(1, 2, 3), 1.0f);
    const std::string bp = write("background.vdb", bg);
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbScalarGrid(bp); },
                                                {bp, "grid 'density'", "background"});
    // a double that becomes Inf as float, in both readers
    auto dbl = openvdb::DoubleGrid::create(0.0);
    dbl->setName("precise");
    dbl->tree().setValue(openvdb::Coord(0, 0, 0), 1.0);
    dbl->tree().setValue(openvdb::Coord(5, 6, 7), 1e300);
    const std::string dp = write("double.vdb", dbl);
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbScalarGrid(dp); },
                                                {dp, "grid 'precise'", "(5, 6, 7)", "float range"});
    expectError<levelforge::InvalidVolumeError>([&] { levelforge::readVdbVolume(dp); },
                                                {dp, "grid 'precise'", "(5, 6, 7)", "float range"});
}

// ============================================================================= shared data

TEST(VolumeIOSharedData, CgalSkullInr)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "volumes/cgal_skull_2.9.inr");
    VolumeInfo info;
    const ScalarVolume v = levelforge::readVolume(path, {}, &info);
    EXPECT_EQ(info.format, "inr");
    EXPECT_EQ(info.sourceType, VolumeValueType::Float32);
    EXPECT_EQ(v.dims, openvdb::Coord(64, 64, 64));
    EXPECT_NEAR(v.spacing[0], 3.94305, 1e-9);
    EXPECT_NEAR(v.spacing[1], 3.94305, 1e-9);
    EXPECT_NEAR(v.spacing[2], 3.65079, 1e-9);
    // CGAL meshes it at iso-value 2.9: the value must be crossed.
    EXPECT_LT(info.minValue, 2.9);
    EXPECT_GT(info.maxValue, 2.9);
    // Same samples as a raw read of the data after the 256-byte header.
    const ScalarVolume raw = levelforge::readRaw(
        path, levelforge::RawVolumeLayout{v.dims, VolumeValueType::Float32, false, v.spacing, v.origin, 256});
    expectSameVolume(v, raw);
}

TEST(VolumeIOSharedData, Ch2betNiftiGz)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "volumes/ch2bet.nii.gz");
    VolumeInfo info;
    const ScalarVolume v = levelforge::readVolume(path, {}, &info);
    EXPECT_EQ(info.format, "nifti");
    EXPECT_TRUE(info.compressed);
    EXPECT_EQ(info.sourceType, VolumeValueType::UInt8);
    EXPECT_EQ(v.dims, openvdb::Coord(181, 217, 181));
    EXPECT_EQ(v.spacing, openvdb::Vec3d(1.0));
    EXPECT_EQ(v.origin, openvdb::Vec3d(-90, -125, -71)); // srow_x/y/z[3] of the sform (sform_code 4)
    EXPECT_EQ(info.minValue, 0.0);
    EXPECT_GT(info.maxValue, 50.0);
    EXPECT_LE(info.maxValue, 255.0);
    const size_t nonzero = size_t(std::count_if(v.data.begin(), v.data.end(), [](float x) { return x > 0.0f; }));
    // A skull-stripped brain fills a good part, but not all, of the box.
    EXPECT_GT(nonzero, v.data.size() / 10);
    EXPECT_LT(nonzero, v.data.size() / 2);
    // The file is a 352-byte header and the voxels, nothing else: a raw read agrees sample for sample.
    const ScalarVolume raw = levelforge::readRaw(
        path, levelforge::RawVolumeLayout{v.dims, VolumeValueType::UInt8, false, v.spacing, v.origin, 352});
    expectSameVolume(v, raw);
}

TEST(VolumeIOSharedData, UncMrbrainDen)
{
    LEVELFORGE_SHARED_FILE_OR_SKIP(path, "volumes/unc_mrbrain_128x128x84.den");
    VolumeInfo info;
    const ScalarVolume v = levelforge::readVolume(path, {}, &info);
    EXPECT_EQ(info.format, "den");
    EXPECT_FALSE(info.bigEndian);
    EXPECT_EQ(v.dims, openvdb::Coord(128, 128, 84));
    EXPECT_EQ(info.minValue, 0.0);
    EXPECT_GT(info.maxValue, 100.0);
    const ScalarVolume raw = levelforge::readRaw(
        path, levelforge::RawVolumeLayout{v.dims, VolumeValueType::UInt8, false, v.spacing, v.origin, 62});
    expectSameVolume(v, raw);
}
