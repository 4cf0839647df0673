// SPDX-License-Identifier: Apache-2.0
// The main road's band leaves on a Vulkan device: for every voxel of a leaf (8^3 voxels, cell
// space: voxel centre = origin + index + 0.5), the closest of the leaf's candidate triangles
// within the band limit (its index; the CPU evaluates that one triangle again for the closest
// point and the sign). The GPU twin of the per-voxel search of MeshToLevelSet.cc.
//
// Exactness: the squared distance is closestPointOnTriangle()'s (core/TriangleDistance.h), term
// for term, in double precision; every result is `precise` (SPIR-V NoContraction: no fused
// multiply-add), so on a device with IEEE double arithmetic the values are bit-identical to the
// CPU's. Candidates come sorted by triangle index and a later candidate wins only when strictly
// closer, so ties go to the smaller index whatever the dispatch order.
#version 450

layout(local_size_x = 128) in;

layout(std430, binding = 0) readonly buffer Corners { double corners[]; };  // 9 per triangle
layout(std430, binding = 1) readonly buffer Leaves { int leaves[]; };        // 8 per leaf: x y z first count - - -
layout(std430, binding = 2) readonly buffer Candidates { uint cands[]; };   // ascending per leaf
layout(std430, binding = 3) buffer OutTri { uint outTri[]; };     // 512 per leaf, ~0u: none
layout(std430, binding = 4) buffer OutD2 { double outD2[]; };     // 512 per leaf, see main()
layout(std430, binding = 5) readonly buffer TriNormals { double triN[]; };  // 12 per triangle: face, e01, e12, e20
layout(std430, binding = 6) readonly buffer VertexNormals { double vertN[]; }; // 3 per vertex
layout(std430, binding = 7) readonly buffer TriVertices { uint triV[]; };   // 3 per triangle

layout(push_constant) uniform Push
{
    double limit2;   // squared band limit (cells): only closer triangles count
    uint leafCount;  // leaves in this batch
    uint groupsX;    // workgroups along x (leaf = y * groupsX + x)
    uint signs;      // 1: pseudonormal signs in outD2 (bindings 5-7 hold the normals)
    uint candBegin;  // this dispatch's window of each leaf's candidates: [candBegin, candEnd);
    uint candEnd;    // later windows start from the state the earlier ones wrote
    uint last;       // 1: the last window (write the final, signed result)
} pc;

// Windows: CPU implementations (lavapipe) cut loops after 65535 iterations per invocation, so a
// leaf with many candidates is searched in several dispatches; a GPU gets one window. Every
// loop below runs at most once per candidate (the four voxels of an invocation are unrolled).

const uint kChunk = 128u;
shared double sCorners[kChunk * 9u];
shared uint sTri[kChunk];

double dot3(dvec3 u, dvec3 v)
{
    precise double r = u.x * v.x + u.y * v.y + u.z * v.z;
    return r;
}

// |p - q|^2 for q the closest point of triangle abc, with q and its feature (TriangleFeature:
// 0 face, 1-3 vertices, 4 edge 01, 5 edge 12, 6 edge 20), as closestPointOnTriangle() computes them.
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

dvec3 cornerOf(uint t, uint k)
{
    const uint o = t * 9u + 3u * k;
    return dvec3(corners[o], corners[o + 1u], corners[o + 2u]);
}

void closer(dvec3 p, dvec3 a, dvec3 b, dvec3 c, uint t, inout double best, inout uint bestTri)
{
    dvec3 q;
    uint f;
    const double d = closestPoint(p, a, b, c, q, f);
    if (d < best) { // candidates ascend: ties keep the smaller index
        best = d;
        bestTri = t;
    }
}

// The final value of one voxel: its squared distance, negated (sign bit set, also for 0) where the
// pseudonormal of the closest feature says inside: (p - q) . n < 0, as LazyPseudoNormals::isInside().
double finalValue(dvec3 p, double best, uint t)
{
    if (t == 0xffffffffu || pc.signs != 1u) return best;
    dvec3 q;
    uint f;
    const double d = closestPoint(p, cornerOf(t, 0u), cornerOf(t, 1u), cornerOf(t, 2u), q, f);
    dvec3 n;
    if (f == 0u || f >= 4u) {
        const uint o = t * 12u + (f == 0u ? 0u : 3u * (f - 3u));
        n = dvec3(triN[o], triN[o + 1u], triN[o + 2u]);
    } else {
        const uint o = triV[t * 3u + (f - 1u)] * 3u;
        n = dvec3(vertN[o], vertN[o + 1u], vertN[o + 2u]);
    }
    precise dvec3 e = p - q;
    precise double s = dot3(e, n);
    return s < 0.0 ? -d : d;
}

dvec3 voxelCentre(ivec3 origin, uint v)
{
    return dvec3(origin + ivec3(int(v >> 6), int((v >> 3) & 7u), int(v & 7u))) + dvec3(0.5);
}

void main()
{
    const uint leaf = gl_WorkGroupID.y * pc.groupsX + gl_WorkGroupID.x;
    if (leaf >= pc.leafCount) return; // uniform across the workgroup
    const uint lid = gl_LocalInvocationID.x;
    const int base = int(leaf) * 8;
    const ivec3 origin = ivec3(leaves[base], leaves[base + 1], leaves[base + 2]);
    const uint first = uint(leaves[base + 3]);
    const uint count = uint(leaves[base + 4]);
    const uint o0 = leaf * 512u + lid, o1 = o0 + 128u, o2 = o0 + 256u, o3 = o0 + 384u;
    const dvec3 p0 = voxelCentre(origin, lid), p1 = voxelCentre(origin, lid + 128u);
    const dvec3 p2 = voxelCentre(origin, lid + 256u), p3 = voxelCentre(origin, lid + 384u);
    double b0 = pc.limit2, b1 = pc.limit2, b2 = pc.limit2, b3 = pc.limit2;
    uint t0 = 0xffffffffu, t1 = 0xffffffffu, t2 = 0xffffffffu, t3 = 0xffffffffu;
    if (pc.candBegin > 0u) { // the state of the earlier windows
        b0 = outD2[o0]; b1 = outD2[o1]; b2 = outD2[o2]; b3 = outD2[o3];
        t0 = outTri[o0]; t1 = outTri[o1]; t2 = outTri[o2]; t3 = outTri[o3];
    }
    const uint begin = min(count, pc.candBegin), end = min(count, pc.candEnd);
    for (uint c0 = begin; c0 < end; c0 += kChunk) {
        const uint n = min(kChunk, end - c0);
        barrier();
        if (lid < n) {
            const uint t = cands[first + c0 + lid];
            sTri[lid] = t;
            const uint src = t * 9u, dst = lid * 9u;
            sCorners[dst] = corners[src]; sCorners[dst + 1u] = corners[src + 1u]; sCorners[dst + 2u] = corners[src + 2u];
            sCorners[dst + 3u] = corners[src + 3u]; sCorners[dst + 4u] = corners[src + 4u]; sCorners[dst + 5u] = corners[src + 5u];
            sCorners[dst + 6u] = corners[src + 6u]; sCorners[dst + 7u] = corners[src + 7u]; sCorners[dst + 8u] = corners[src + 8u];
        }
        barrier();
        for (uint i = 0u; i < n; ++i) {
            const uint o = i * 9u;
            const dvec3 a = dvec3(sCorners[o], sCorners[o + 1u], sCorners[o + 2u]);
            const dvec3 b = dvec3(sCorners[o + 3u], sCorners[o + 4u], sCorners[o + 5u]);
            const dvec3 c = dvec3(sCorners[o + 6u], sCorners[o + 7u], sCorners[o + 8u]);
            const uint t = sTri[i];
            closer(p0, a, b, c, t, b0, t0);
            closer(p1, a, b, c, t, b1, t1);
            closer(p2, a, b, c, t, b2, t2);
            closer(p3, a, b, c, t, b3, t3);
        }
    }
    outTri[o0] = t0; outTri[o1] = t1; outTri[o2] = t2; outTri[o3] = t3;
    if (pc.last == 1u) {
        outD2[o0] = finalValue(p0, b0, t0); outD2[o1] = finalValue(p1, b1, t1);
        outD2[o2] = finalValue(p2, b2, t2); outD2[o3] = finalValue(p3, b3, t3);
    } else {
        outD2[o0] = b0; outD2[o1] = b1; outD2[o2] = b2; outD2[o3] = b3;
    }
}
