// SPDX-License-Identifier: Apache-2.0
// T4 scan conversion's dense slabs on a Vulkan device: the GPU twin of CpuSlabBackend::fill()
// (scan/DenseSlab.h). One invocation per voxel of a slab, over the slab's cross-sections on the
// voxel's plane: coverage by the exact scanline span of the convex polygon (1e-7 voxel
// tolerance), then the closest point of the item's triangle (world units), its feature and the
// pseudonormal sign. Double precision, every result `precise` (no fused multiply-add), term for
// term as the CPU; ties go to the smaller triangle index. Output: the closest triangle and its
// squared distance with the inside sign in the sign bit (the CPU takes the square root).
#version 450

layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Corners { double corners[]; };   // 9 per triangle, world
layout(std430, binding = 1) readonly buffer Normals { double normals[]; };   // 21 per triangle (7 features)
layout(std430, binding = 2) readonly buffer ItemXY { double itemXY[]; };     // 32 per item: x[16], y[16]
layout(std430, binding = 3) readonly buffer ItemInfo { int itemInfo[]; };    // 8 per item: tri z count iy0 iy1 - - -
layout(std430, binding = 4) readonly buffer SlabInfo { int slabInfo[]; };    // 8 per slab: x0 y0 z0 dx dy dz ranges voxels
layout(std430, binding = 5) readonly buffer Ranges { uint ranges[]; };       // 2 per (slab, plane): first item, count
layout(std430, binding = 6) readonly buffer Groups { uint groups[]; };       // 2 per workgroup: slab, first voxel
layout(std430, binding = 7) buffer OutTri { uint outTri[]; };
layout(std430, binding = 8) buffer OutD2 { double outD2[]; };
layout(std430, binding = 9) buffer Raster { uint raster[]; };                // per slab: (voxel, item) evaluations

layout(push_constant) uniform Push
{
    double h;          // voxel size: voxel centre = index * h
    uint groupCount;   // workgroups in this dispatch
    uint groupsX;      // workgroups along x
    uint itemBegin;    // this dispatch's window of each plane's items: [itemBegin, itemEnd); later
    uint itemEnd;      // windows start from the state the earlier ones wrote (CPU implementations
                       // such as lavapipe cut loops after 65535 iterations per invocation)
} pc;

shared uint sCount;

double dot3(dvec3 u, dvec3 v)
{
    precise double r = u.x * v.x + u.y * v.y + u.z * v.z;
    return r;
}

// closestPointOnTriangle() (core/TriangleDistance.h): |p - q|^2, q, feature (TriangleFeature)
double closestPoint(dvec3 p, dvec3 a, dvec3 b, dvec3 c, out dvec3 qOut, out uint feature)
{
    precise dvec3 ab = b - a;
    precise dvec3 ac = c - a;
    precise dvec3 ap = p - a;
    precise double d1 = dot3(ab, ap);
    precise double d2 = dot3(ac, ap);
    precise dvec3 q;
    if (d1 <= 0.0 && d2 <= 0.0) {
        q = a;
        feature = 1u;
    } else {
        precise dvec3 bp = p - b;
        precise double d3 = dot3(ab, bp);
        precise double d4 = dot3(ac, bp);
        if (d3 >= 0.0 && d4 <= d3) {
            q = b;
            feature = 2u;
        } else {
            precise double vc = d1 * d4 - d3 * d2;
            if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
                precise double v = d1 / (d1 - d3);
                q = a + ab * v;
                feature = 4u;
            } else {
                precise dvec3 cp = p - c;
                precise double d5 = dot3(ab, cp);
                precise double d6 = dot3(ac, cp);
                if (d6 >= 0.0 && d5 <= d6) {
                    q = c;
                    feature = 3u;
                } else {
                    precise double vb = d5 * d2 - d1 * d6;
                    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
                        precise double w = d2 / (d2 - d6);
                        q = a + ac * w;
                        feature = 6u;
                    } else {
                        precise double va = d3 * d6 - d5 * d4;
                        precise double e43 = d4 - d3;
                        precise double e56 = d5 - d6;
                        if (va <= 0.0 && e43 >= 0.0 && e56 >= 0.0) {
                            precise double w = e43 / (e43 + e56);
                            precise dvec3 bc = c - b;
                            q = b + bc * w;
                            feature = 5u;
                        } else {
                            precise double denom = 1.0 / (va + vb + vc);
                            precise double v = vb * denom;
                            precise double w = vc * denom;
                            precise dvec3 s = a + ab * v;
                            q = s + ac * w;
                            feature = 0u;
                        }
                    }
                }
            }
        }
    }
    qOut = q;
    precise dvec3 e = p - q;
    precise double r = e.x * e.x + e.y * e.y + e.z * e.z;
    return r;
}

dvec3 corner(uint t, uint k)
{
    const uint o = t * 9u + 3u * k;
    return dvec3(corners[o], corners[o + 1u], corners[o + 2u]);
}

void main()
{
    const uint wg = gl_WorkGroupID.y * pc.groupsX + gl_WorkGroupID.x;
    if (wg >= pc.groupCount) return; // uniform across the workgroup
    const uint lid = gl_LocalInvocationID.x;
    const uint slab = groups[2u * wg];
    const uint v = groups[2u * wg + 1u] + lid;
    const int so = int(slab) * 8;
    const int dx = slabInfo[so + 3], dy = slabInfo[so + 4], dz = slabInfo[so + 5];
    const bool valid = v < uint(dx * dy * dz);
    if (lid == 0u) sCount = 0u;
    barrier();
    if (valid) {
        const int iz = int(v % uint(dz));
        const int iy = int((v / uint(dz)) % uint(dy));
        const int ix = int(v / uint(dz * dy));
        const int x = slabInfo[so] + ix, y = slabInfo[so + 1] + iy, z = slabInfo[so + 2] + iz;
        const uint r = uint(slabInfo[so + 6]) + 2u * uint(iz);
        const uint first = ranges[r], count = ranges[r + 1u];
        const double tol = 1e-7;
        const double yd = double(y), xd = double(x);
        precise dvec3 p = dvec3(double(x) * pc.h, double(y) * pc.h, double(z) * pc.h);
        const uint at = uint(slabInfo[so + 7]) + v;
        double best = packDouble2x32(uvec2(0u, 0x7ff00000u)); // +inf
        uint bestTri = 0xffffffffu;
        bool inside = false;
        if (pc.itemBegin > 0u) { // the state of the earlier windows
            bestTri = outTri[at];
            const double b = outD2[at];
            inside = (unpackDouble2x32(b).y & 0x80000000u) != 0u;
            best = abs(b);
        }
        uint evaluated = 0u;
        const uint wBegin = first + min(count, pc.itemBegin), wEnd = first + min(count, pc.itemEnd);
        for (uint i = wBegin; i < wEnd; ++i) {
            const int io = int(i) * 8;
            if (y < itemInfo[io + 3] || y > itemInfo[io + 4]) continue;
            const uint n = uint(itemInfo[io + 2]);
            // crossSectionSpan(): the closed x-interval of the polygon on row y
            double xl = packDouble2x32(uvec2(0u, 0x7ff00000u)), xr = -xl;
            const uint xo = i * 32u;
            for (uint k = 0u; k < n; ++k) {
                const uint j = (k + 1u) % n;
                const double ax = itemXY[xo + k], ay = itemXY[xo + 16u + k];
                const double bx = itemXY[xo + j], by = itemXY[xo + 16u + j];
                // std::min / std::max, exactly (GLSL's min and max leave NaN operands undefined)
                const double lo = by < ay ? by : ay, hi = ay < by ? by : ay;
                precise double loT = lo - tol;
                precise double hiT = hi + tol;
                if (yd < loT || yd > hiT) continue;
                precise double span = hi - lo;
                if (span <= 1e-12) { // std::min({xl, ax, bx}), std::max({xr, ax, bx})
                    xl = ax < xl ? ax : xl;
                    xl = bx < xl ? bx : xl;
                    xr = xr < ax ? ax : xr;
                    xr = xr < bx ? bx : xr;
                    continue;
                }
                precise double num = yd - ay;
                precise double den = by - ay;
                precise double q = num / den;
                const double t = q < 0.0 ? 0.0 : (1.0 < q ? 1.0 : q);
                precise double dxab = bx - ax;
                precise double xs = ax + t * dxab;
                xl = xs < xl ? xs : xl;
                xr = xr < xs ? xs : xr;
            }
            if (!(xl <= xr)) continue;
            precise double xlT = xl - tol;
            precise double xrT = xr + tol;
            if (xd < ceil(xlT) || xd > floor(xrT)) continue;
            ++evaluated;
            const uint t = uint(itemInfo[io]);
            dvec3 cp;
            uint f;
            const double d2 = closestPoint(p, corner(t, 0u), corner(t, 1u), corner(t, 2u), cp, f);
            if (d2 < best || (d2 == best && t < bestTri)) {
                best = d2;
                bestTri = t;
                const uint no = t * 21u + 3u * f;
                precise dvec3 e = p - cp;
                precise double s = dot3(e, dvec3(normals[no], normals[no + 1u], normals[no + 2u]));
                inside = s < 0.0;
            }
        }
        outTri[at] = bestTri;
        outD2[at] = inside ? -best : best;
        atomicAdd(sCount, evaluated);
    }
    barrier();
    if (lid == 0u && sCount != 0u) atomicAdd(raster[slab], sCount);
}
