// SPDX-License-Identifier: Apache-2.0
// levelforge_bench_meshes: writes the meshes (and the fog volume) of the main-road matrix
// (scripts/bench main-road) into a cache folder, skipping files that already exist, and a
// manifest that lists every input of the matrix with its triangle count and reference box.
//
//   levelforge_bench_meshes [--out DIR] [--data DIR] [--force]
//
//   --out   cache folder (default $BENCH_MESHES, else ./bench-meshes)
//   --data  shared data folder holding meshes/watertight, meshes/cad, volumes
//           (default $LEVELFORGE_SHARED_DATA, else ../shared/data)
//   --force rewrite the files even when they exist
//
// Generated:
//   armadillo_loop1.obj     armadillo_100k Loop-subdivided once (OpenMesh LoopT), 399,904 faces
//   armadillo_loop2.obj     ... twice, 1,599,616 faces
//   sliver_sphere.obj       UV sphere, 6000 segments x 4 latitude bands, poles closed: 36,000
//                           triangles, all slivers (aspect ~ 1000)
//   vertex_fan.obj          double cone, 6000 rim segments: 12,000 triangles, 6000 of them
//                           sharing the apex (and 6000 the other tip)
//   armadillo_stray.obj     armadillo_100k plus one thin extra triangle with one vertex 1000
//                           bounding-box diagonals away (a bad export)
//   armadillo_1e30.obj      the same with that vertex's x coordinate set to 1e30
//   <name>.obj              every .off mesh of meshes/watertight converted (vdb_tool reads no OFF)
//   ch2bet_fog.vdb          volumes/ch2bet.nii.gz as a dense fog FloatGrid "density" (every voxel
//                           active, spacing from the header) for vdb_tool -iso2ls
//   ch2bet_half_fog.vdb     the same, every second sample along each axis (the quick matrix)
//   manifest.tsv            name, group, path, triangles, reference box (min xyz, max xyz); for
//                           the stray meshes the box is the clean armadillo's, so that a voxel
//                           count means the same resolution of the object as for armadillo_100k.
//
// Readers and writers are deliberately minimal (OBJ v/f, OFF, STL ASCII/binary); OBJ files are
// written with 9 significant digits.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Subdivider/Uniform/LoopT.hh>

#include <openvdb/openvdb.h>

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

using Vec3 = std::array<double, 3>;
using Tri = std::array<std::int64_t, 3>;

struct Mesh {
    std::vector<Vec3> v;
    std::vector<Tri> f;
};

struct Box {
    Vec3 lo{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
            std::numeric_limits<double>::max()};
    Vec3 hi{-std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(),
            -std::numeric_limits<double>::max()};
    void add(const Vec3& p)
    {
        for (int i = 0; i < 3; ++i) {
            lo[i] = std::min(lo[i], p[i]);
            hi[i] = std::max(hi[i], p[i]);
        }
    }
    double diagonal() const
    {
        return std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                         (hi[2] - lo[2]) * (hi[2] - lo[2]));
    }
};

[[noreturn]] void fail(const std::string& msg) { throw std::runtime_error(msg); }

Box boxOfReferenced(const Mesh& m)
{
    Box b;
    for (const Tri& t : m.f)
        for (auto i : t) b.add(m.v[size_t(i)]);
    return b;
}

// Fan-triangulates a polygon given as 0-based indices.
void addPolygon(Mesh& m, const std::vector<std::int64_t>& poly, const std::string& path)
{
    for (auto i : poly)
        if (i < 0 || size_t(i) >= m.v.size()) fail(path + ": face index out of range");
    for (size_t k = 2; k < poly.size(); ++k) m.f.push_back({poly[0], poly[k - 1], poly[k]});
}

Mesh readObj(const std::string& path)
{
    std::ifstream in(path);
    if (!in) fail(path + ": cannot open");
    Mesh m;
    std::string line, tok;
    std::vector<std::int64_t> poly;
    while (std::getline(in, line)) {
        if (line.size() < 2) continue;
        if (line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) {
            Vec3 p{};
            if (std::sscanf(line.c_str() + 1, "%lf %lf %lf", &p[0], &p[1], &p[2]) != 3)
                fail(path + ": bad vertex line");
            m.v.push_back(p);
        } else if (line[0] == 'f' && (line[1] == ' ' || line[1] == '\t')) {
            std::istringstream ls(line.substr(1));
            poly.clear();
            while (ls >> tok) {
                long long i = std::atoll(tok.c_str()); // "a/b/c": atoll stops at '/'
                poly.push_back(i < 0 ? std::int64_t(m.v.size()) + i : i - 1);
            }
            addPolygon(m, poly, path);
        }
    }
    return m;
}

// Next token of an OFF file, skipping '#' comments.
bool offToken(std::istream& in, std::string& tok)
{
    while (in >> tok) {
        if (tok[0] != '#') return true;
        std::string rest;
        std::getline(in, rest);
    }
    return false;
}

Mesh readOff(const std::string& path)
{
    std::ifstream in(path);
    if (!in) fail(path + ": cannot open");
    std::string tok;
    if (!offToken(in, tok) || tok != "OFF") fail(path + ": not an OFF file");
    auto num = [&](void) -> std::string {
        if (!offToken(in, tok)) fail(path + ": truncated");
        return tok;
    };
    const long long nv = std::atoll(num().c_str()), nf = std::atoll(num().c_str());
    num(); // edges
    Mesh m;
    m.v.resize(size_t(nv));
    for (auto& p : m.v)
        for (double& c : p) c = std::strtod(num().c_str(), nullptr);
    std::vector<std::int64_t> poly;
    for (long long i = 0; i < nf; ++i) {
        const long long n = std::atoll(num().c_str());
        poly.clear();
        for (long long k = 0; k < n; ++k) poly.push_back(std::atoll(num().c_str()));
        std::string rest;
        std::getline(in, rest); // optional colour
        addPolygon(m, poly, path);
    }
    return m;
}

// STL: triangle count and box only (the matrix reads the STL files themselves).
std::pair<size_t, Box> scanStl(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path + ": cannot open");
    std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    Box b;
    size_t n = 0;
    if (data.size() >= 84) {
        std::uint32_t count = 0;
        std::memcpy(&count, data.data() + 80, 4);
        if (84 + size_t(count) * 50 == data.size()) { // binary
            for (size_t t = 0; t < count; ++t)
                for (int k = 0; k < 3; ++k) {
                    float c[3];
                    std::memcpy(c, data.data() + 84 + t * 50 + 12 + k * 12, 12);
                    b.add({c[0], c[1], c[2]});
                }
            return {count, b};
        }
    }
    std::istringstream ls(data);
    std::string tok;
    while (ls >> tok) {
        if (tok == "facet") ++n;
        else if (tok == "vertex") {
            Vec3 p{};
            ls >> p[0] >> p[1] >> p[2];
            b.add(p);
        }
    }
    return {n, b};
}

void writeObj(const Mesh& m, const fs::path& path)
{
    const fs::path tmp = path.string() + ".tmp";
    FILE* out = std::fopen(tmp.c_str(), "w");
    if (!out) fail(tmp.string() + ": cannot write");
    std::vector<char> buf(1 << 20);
    std::setvbuf(out, buf.data(), _IOFBF, buf.size());
    std::fprintf(out, "# levelforge_bench_meshes: %zu vertices, %zu triangles\n", m.v.size(),
                 m.f.size());
    for (const Vec3& p : m.v) std::fprintf(out, "v %.9g %.9g %.9g\n", p[0], p[1], p[2]);
    for (const Tri& t : m.f)
        std::fprintf(out, "f %lld %lld %lld\n", (long long)t[0] + 1, (long long)t[1] + 1,
                     (long long)t[2] + 1);
    if (std::fclose(out) != 0) fail(tmp.string() + ": write error");
    fs::rename(tmp, path);
}

struct DoubleTraits : OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
};
using OmMesh = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

Mesh loop(const Mesh& in, size_t steps)
{
    OmMesh om;
    std::vector<OmMesh::VertexHandle> vh;
    vh.reserve(in.v.size());
    for (const Vec3& p : in.v) vh.push_back(om.add_vertex(OmMesh::Point(p[0], p[1], p[2])));
    for (const Tri& t : in.f)
        if (!om.add_face(vh[size_t(t[0])], vh[size_t(t[1])], vh[size_t(t[2])]).is_valid())
            fail("Loop subdivision: the mesh is not manifold");
    OpenMesh::Subdivider::Uniform::LoopT<OmMesh, double> subdivider;
    subdivider.attach(om);
    if (!subdivider(steps)) fail("Loop subdivision failed");
    subdivider.detach();
    Mesh out;
    out.v.reserve(om.n_vertices());
    for (auto v : om.vertices()) {
        const auto& p = om.point(v);
        out.v.push_back({p[0], p[1], p[2]});
    }
    out.f.reserve(om.n_faces());
    for (auto f : om.faces()) {
        Tri t{};
        int k = 0;
        for (auto v : om.fv_range(f)) t[size_t(k++)] = v.idx();
        out.f.push_back(t);
    }
    return out;
}

// UV sphere: `segments` around, `bands` latitude bands, one vertex per pole.
Mesh sliverSphere(int segments, int bands)
{
    Mesh m;
    const double pi = std::acos(-1.0);
    m.v.push_back({0, 0, 1});
    for (int r = 1; r < bands; ++r) {
        const double th = pi * r / bands;
        for (int s = 0; s < segments; ++s) {
            const double ph = 2 * pi * s / segments;
            m.v.push_back({std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th)});
        }
    }
    const std::int64_t south = std::int64_t(m.v.size());
    m.v.push_back({0, 0, -1});
    auto ring = [&](int r, int s) { return 1 + std::int64_t(r - 1) * segments + (s % segments); };
    for (int s = 0; s < segments; ++s) m.f.push_back({0, ring(1, s), ring(1, s + 1)});
    for (int r = 1; r + 1 < bands; ++r)
        for (int s = 0; s < segments; ++s) {
            m.f.push_back({ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
            m.f.push_back({ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
        }
    for (int s = 0; s < segments; ++s)
        m.f.push_back({south, ring(bands - 1, s + 1), ring(bands - 1, s)});
    return m;
}

// Double cone: apex (0,0,1), tip (0,0,-0.5), rim = unit circle; outward orientation.
Mesh vertexFan(int segments)
{
    Mesh m;
    const double pi = std::acos(-1.0);
    m.v.push_back({0, 0, 1});
    m.v.push_back({0, 0, -0.5});
    for (int s = 0; s < segments; ++s) {
        const double ph = 2 * pi * s / segments;
        m.v.push_back({std::cos(ph), std::sin(ph), 0});
    }
    auto rim = [&](int s) { return 2 + std::int64_t(s % segments); };
    for (int s = 0; s < segments; ++s) {
        m.f.push_back({0, rim(s), rim(s + 1)});
        m.f.push_back({1, rim(s + 1), rim(s)});
    }
    return m;
}

// The clean mesh plus one thin triangle reaching `diagonals` box diagonals away
// (direction (1, 0.3, 0.2)); with `x1e30` the far vertex's x is 1e30 instead.
Mesh withStray(const Mesh& clean, double diagonals, bool x1e30)
{
    Mesh m = clean;
    const Box b = boxOfReferenced(clean);
    const double d = b.diagonal();
    const Vec3 a = clean.v[size_t(clean.f[0][0])];
    const std::int64_t base = std::int64_t(m.v.size());
    m.v.push_back({a[0] + 1e-3 * d, a[1], a[2]});
    m.v.push_back({a[0], a[1] + 1e-3 * d, a[2]});
    const double len = std::sqrt(1 + 0.09 + 0.04);
    Vec3 far{a[0] + diagonals * d / len, a[1] + 0.3 * diagonals * d / len,
             a[2] + 0.2 * diagonals * d / len};
    if (x1e30) far[0] = 1e30;
    m.v.push_back(far);
    m.f.push_back({base, base + 1, base + 2});
    return m;
}

// NIfTI-1 (.nii or .nii.gz, read through zlib) to a dense fog FloatGrid, every voxel active.
void niftiToFog(const std::string& in, const fs::path& out, int stride)
{
    gzFile gz = gzopen(in.c_str(), "rb");
    if (!gz) fail(in + ": cannot open");
    std::vector<unsigned char> data;
    unsigned char chunk[1 << 16];
    int n;
    while ((n = gzread(gz, chunk, sizeof(chunk))) > 0) data.insert(data.end(), chunk, chunk + n);
    gzclose(gz);
    if (data.size() < 348) fail(in + ": too short for NIfTI-1");
    std::int32_t sizeofHdr;
    std::memcpy(&sizeofHdr, data.data(), 4);
    if (sizeofHdr != 348) fail(in + ": not little-endian NIfTI-1");
    std::int16_t dim[8], datatype, bitpix;
    float pixdim[8], voxOffset, slope, inter;
    std::memcpy(dim, data.data() + 40, 16);
    std::memcpy(&datatype, data.data() + 70, 2);
    std::memcpy(&bitpix, data.data() + 72, 2);
    std::memcpy(pixdim, data.data() + 76, 32);
    std::memcpy(&voxOffset, data.data() + 108, 4);
    std::memcpy(&slope, data.data() + 112, 4);
    std::memcpy(&inter, data.data() + 116, 4);
    const int nx = dim[1], ny = dim[2], nz = dim[3];
    const size_t count = size_t(nx) * size_t(ny) * size_t(nz);
    const size_t offset = size_t(voxOffset);
    if (offset + count * size_t(bitpix / 8) > data.size()) fail(in + ": truncated samples");
    const unsigned char* p = data.data() + offset;
    auto sample = [&](size_t i) -> double {
        switch (datatype) {
        case 2: return p[i];
        case 256: return reinterpret_cast<const std::int8_t*>(p)[i];
        case 4: { std::int16_t v; std::memcpy(&v, p + 2 * i, 2); return v; }
        case 512: { std::uint16_t v; std::memcpy(&v, p + 2 * i, 2); return v; }
        case 8: { std::int32_t v; std::memcpy(&v, p + 4 * i, 4); return v; }
        case 16: { float v; std::memcpy(&v, p + 4 * i, 4); return v; }
        case 64: { double v; std::memcpy(&v, p + 8 * i, 8); return v; }
        default: fail(in + ": unsupported NIfTI datatype " + std::to_string(datatype));
        }
    };
    const bool scale = slope != 0.0f && !(slope == 1.0f && inter == 0.0f);
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(0.0f);
    const openvdb::Vec3d spacing(stride * (pixdim[1] > 0 ? pixdim[1] : 1),
                                 stride * (pixdim[2] > 0 ? pixdim[2] : 1),
                                 stride * (pixdim[3] > 0 ? pixdim[3] : 1));
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(1.0);
    xform->preScale(spacing);
    grid->setTransform(xform);
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    auto acc = grid->getAccessor();
    for (int z = 0; z < nz; z += stride)
        for (int y = 0; y < ny; y += stride)
            for (int x = 0; x < nx; x += stride) {
                double v = sample((size_t(z) * size_t(ny) + size_t(y)) * size_t(nx) + size_t(x));
                if (scale) v = v * slope + inter;
                acc.setValueOn(openvdb::Coord(x / stride, y / stride, z / stride), float(v));
            }
    const fs::path tmp = out.string() + ".tmp";
    openvdb::io::File file(tmp.string());
    file.setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    file.write({grid});
    file.close();
    fs::rename(tmp, out);
    std::cout << "  " << out.filename().string() << ": " << (nx + stride - 1) / stride << " x "
              << (ny + stride - 1) / stride << " x " << (nz + stride - 1) / stride << " fog, spacing " << spacing << ", datatype " << datatype << "\n";
}

struct Entry {
    std::string name, group, path;
    size_t triangles;
    Box box;
};

} // namespace

int main(int argc, char** argv)
{
    try {
        fs::path outDir = std::getenv("BENCH_MESHES") ? std::getenv("BENCH_MESHES") : "bench-meshes";
        fs::path data = std::getenv("LEVELFORGE_SHARED_DATA") ? std::getenv("LEVELFORGE_SHARED_DATA")
                                                              : "../shared/data";
        bool force = false;
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            if (a == "--out" && i + 1 < argc) outDir = argv[++i];
            else if (a == "--data" && i + 1 < argc) data = argv[++i];
            else if (a == "--force") force = true;
            else {
                std::cerr << "usage: levelforge_bench_meshes [--out DIR] [--data DIR] [--force]\n";
                return 2;
            }
        }
        fs::create_directories(outDir);
        const fs::path watertight = data / "meshes" / "watertight", cad = data / "meshes" / "cad";
        std::vector<Entry> entries;
        auto need = [&](const fs::path& p) { return force || !fs::exists(p); };
        auto entry = [&](const std::string& name, const std::string& group, const fs::path& path,
                         const Mesh& m, const Box* box = nullptr) {
            entries.push_back({name, group, fs::absolute(path).string(), m.f.size(),
                               box ? *box : boxOfReferenced(m)});
        };
        // A generated mesh: made (and written) only when its file is absent, else read back.
        auto generated = [&](const std::string& name, const std::string& group, auto make,
                             const Box* box = nullptr) {
            const fs::path path = outDir / (name + ".obj");
            Mesh m;
            if (need(path)) {
                m = make();
                writeObj(m, path);
                std::cout << "  wrote " << path.filename().string() << ": " << m.f.size()
                          << " triangles, " << m.v.size() << " vertices\n";
            } else {
                m = readObj(path.string());
            }
            entry(name, group, path, m, box);
            return m;
        };

        std::cout << "levelforge_bench_meshes: " << outDir.string() << "\n";
        // The shared watertight set: OBJ and STL as they are, OFF converted to OBJ.
        std::vector<fs::path> files;
        if (fs::is_directory(watertight))
            for (const auto& e : fs::directory_iterator(watertight)) files.push_back(e.path());
        std::sort(files.begin(), files.end());
        Mesh armadillo;
        for (const fs::path& f : files) {
            const std::string ext = f.extension().string(), stem = f.stem().string();
            if (ext == ".obj") {
                Mesh m = readObj(f.string());
                entry(stem, "watertight", f, m);
                if (stem == "armadillo_100k") armadillo = std::move(m);
            } else if (ext == ".off") {
                const Mesh m = readOff(f.string());
                const fs::path obj = outDir / (stem + ".obj");
                if (need(obj)) writeObj(m, obj);
                entry(stem, "watertight", obj, m);
            } else if (ext == ".stl") {
                const auto [n, box] = scanStl(f.string());
                entries.push_back({stem, "watertight", fs::absolute(f).string(), n, box});
            }
        }
        if (armadillo.f.empty()) fail(watertight.string() + "/armadillo_100k.obj: not found");
        const Box armadilloBox = boxOfReferenced(armadillo);

        // Loop x1 and x2: x2 continues from x1 when it has to be made.
        Mesh loop1 = generated("armadillo_loop1", "loop", [&] { return loop(armadillo, 1); });
        generated("armadillo_loop2", "loop", [&] { return loop(loop1, 1); });
        loop1 = Mesh();
        generated("sliver_sphere", "degenerate", [] { return sliverSphere(6000, 4); });
        generated("vertex_fan", "degenerate", [] { return vertexFan(6000); });
        generated("armadillo_stray", "stray", [&] { return withStray(armadillo, 1000, false); },
                  &armadilloBox);
        generated("armadillo_1e30", "stray", [&] { return withStray(armadillo, 1000, true); },
                  &armadilloBox);

        files.clear();
        if (fs::is_directory(cad))
            for (const auto& e : fs::directory_iterator(cad))
                if (e.path().extension() == ".stl") files.push_back(e.path());
        std::sort(files.begin(), files.end());
        for (const fs::path& f : files) {
            const auto [n, box] = scanStl(f.string());
            entries.push_back({f.stem().string(), "cad", fs::absolute(f).string(), n, box});
        }

        const fs::path nifti = data / "volumes" / "ch2bet.nii.gz";
        if (fs::exists(nifti)) {
            openvdb::initialize();
            for (int stride : {1, 2}) {
                const std::string name = stride == 1 ? "ch2bet" : "ch2bet_half";
                const fs::path fog = outDir / (name + "_fog.vdb");
                if (need(fog)) niftiToFog(nifti.string(), fog, stride);
                entries.push_back({name, "volume", fs::absolute(fog).string(), 0, Box()});
            }
        }

        const fs::path manifest = outDir / "manifest.tsv";
        std::ofstream out(manifest.string() + ".tmp");
        out << "# name\tgroup\tpath\ttriangles\txmin\tymin\tzmin\txmax\tymax\tzmax\n";
        out.precision(9);
        for (const Entry& e : entries) {
            out << e.name << '\t' << e.group << '\t' << e.path << '\t' << e.triangles;
            for (int k = 0; k < 3; ++k) out << '\t' << (e.triangles ? e.box.lo[k] : 0.0);
            for (int k = 0; k < 3; ++k) out << '\t' << (e.triangles ? e.box.hi[k] : 0.0);
            out << '\n';
        }
        out.close();
        fs::rename(manifest.string() + ".tmp", manifest);
        std::cout << "levelforge_bench_meshes: " << entries.size() << " entries in "
                  << manifest.string() << "\n";
        return 0;
    } catch (const std::exception& e) {
        std::cerr << "levelforge_bench_meshes: error: " << e.what() << "\n";
        return 1;
    }
}
