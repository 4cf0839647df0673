// SPDX-License-Identifier: Apache-2.0
// The dense exact Euclidean distance transform on a Vulkan device: one 1-D pass of
// P. F. Felzenszwalb and D. P. Huttenlocher, "Distance Transforms of Sampled Functions", Theory of
// Computing 8 (2012), Algorithm 1 (the lower envelope of the parabolas s2 (p - q)^2 + f(q)), one
// invocation per line. The GPU twin of Envelope::run() in src/volume/ExactDistanceTransform.cc
// (detail/LowerEnvelope.h): mode 0 is the x pass (f = 0 on feature voxels, +inf elsewhere),
// mode 1 the y pass, mode 2 the z pass (and the square root); passes 1 and 2 work in place on
// the float squared distances of the previous pass.
//
// Exactness: the same operations in the same order as the CPU, in double precision, every
// result `precise` (SPIR-V NoContraction: no fused multiply-add); the breakpoints compare with
// the same `<=` and `<`; results are rounded to float between passes as the CPU stores them.
// Division and sqrt are made correctly rounded here (divide(), squareRoot()), so on a device
// whose double +, -, * and conversions are IEEE round-to-nearest (Vulkan's rule for them) the
// distances are bit-identical to exactDistanceTransform()'s.
//
// Per-line scratch (the envelope's sites, their values and its breakpoints) lives in device
// buffers, element e of invocation t at e * lines + t (coalesced across a workgroup).
#version 450

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Mask { uint mask[]; }; // mode 0: feature bytes, 4 per word
layout(std430, binding = 1) buffer Field { float g[]; };           // squared distances (in place)
layout(std430, binding = 2) buffer Sites { int site[]; };          // scratch: n per line
layout(std430, binding = 3) buffer Values { float value[]; };      // scratch: n per line
layout(std430, binding = 4) buffer Breaks { double brk[]; };       // scratch: n + 1 per line

layout(push_constant) uniform Push
{
    double s2;      // the squared spacing of the axis (the parabolas' weight)
    uint n;         // samples per line
    uint lines;     // lines in this dispatch (also the scratch stride)
    uint firstLine; // the first line of this dispatch
    uint linesA;    // line L starts at (L % linesA) * strideA + (L / linesA) * strideB
    uint strideA;
    uint strideB;
    uint step;      // element stride along a line
    uint mode;      // 0: x pass from the mask; 1: in place; 2: in place, then the square root;
                    // + kPerturb (tests)
} pc;

// ---- correctly rounded division and square root from correctly rounded +, -, *
//
// Vulkan only promises double division and sqrt "at least as precise as single precision"; the
// CPU's are correctly rounded (IEEE 754). So the device's quotient (root) is checked with the
// exact remainder and moved to the correctly rounded one: T. J. Dekker, "A floating-point
// technique for extending the available precision", Numer. Math. 18 (1971): TwoProduct by
// Veltkamp's splitting gives p + e = x * y exactly; for a quotient q within an ulp of a / b the
// remainder a - q b = (a - p) - e is a double (Bohlender, Walter, Kornerup, Matula 1991), and q is
// the correctly rounded quotient iff that remainder lies within half the gap to q's neighbours
// times b (no exact ties exist). Far-off values first take a Newton step. On a device whose
// division and sqrt are already correctly rounded nothing moves (one check per call). Valid
// without overflow and underflow (|values| in [1e-290, 1e290]), as here.

const uint kPerturb = 16u; // test hook (mode bit): start from a quotient or root that is off

void twoProduct(double x, double y, out double p, out double e)
{
    precise double pp = x * y;
    precise double cx = 134217729.0 * x;
    precise double xh = cx - (cx - x);
    precise double xl = x - xh;
    precise double cy = 134217729.0 * y;
    precise double yh = cy - (cy - y);
    precise double yl = y - yh;
    precise double ee = ((xh * yh - pp) + xh * yl + xl * yh) + xl * yl;
    p = pp;
    e = ee;
}

// The next double towards +inf (x finite and non-zero).
double nextUp(double x)
{
    uvec2 w = unpackDouble2x32(x); // (low, high) words
    if (x > 0.0) {
        w.x += 1u;
        if (w.x == 0u) w.y += 1u;
    } else {
        if (w.x == 0u) w.y -= 1u;
        w.x -= 1u;
    }
    return packDouble2x32(w);
}

double nextDown(double x) { return -nextUp(-x); }

// Half the gaps from x (normal, |x| > 2^-960) to its neighbours above (.x) and below (.y): half
// an ulp, a quarter on the side towards zero when |x| is a power of two. From the bits alone.
dvec2 halfGaps(double x)
{
    const uvec2 w = unpackDouble2x32(x);
    const uint biased = (w.y >> 20u) & 0x7ffu;
    const double h = packDouble2x32(uvec2(0u, (biased - 53u) << 20u)); // 2^(exponent - 53)
    if (w.x != 0u || (w.y & 0xfffffu) != 0u) return dvec2(h);
    return x > 0.0 ? dvec2(h, 0.5 * h) : dvec2(0.5 * h, h);
}

// The test hook: 2 ulps off, or 2^-30 relative off (the Newton step), by the last bit.
double perturbed(double x)
{
    if ((pc.mode & kPerturb) == 0u || x == 0.0) return x;
    if ((unpackDouble2x32(x).x & 1u) == 0u) {
        precise double y = x * (1.0 + 1.0 / 1073741824.0);
        return y;
    }
    return nextUp(nextUp(x));
}

// a / b correctly rounded, for b > 0. The first pass of the loop is the whole cost when the
// device's quotient is already correctly rounded (the loop has a data-dependent exit, so no
// compiler unrolls its rare corrections into the common path).
double divide(double a, double b)
{
    precise double q0 = a / b;
    double q = perturbed(q0);
    if (a == 0.0 || q == 0.0) return q0;
    for (int it = 0;; ++it) {
        double p, e;
        twoProduct(q, b, p, e);
        precise double r = (a - p) - e; // a - q b, exact once q is within an ulp
        const dvec2 h = halfGaps(q);
        precise double hu = h.x * b;
        precise double hd = h.y * b;
        if ((r < hu && -r < hd) || it == 8) break;
        if (abs(r) > 8.0 * hu) {
            precise double qn = q + r / b; // far off: a Newton step
            q = qn;
        } else {
            q = r >= hu ? nextUp(q) : nextDown(q);
        }
    }
    return q;
}

// sqrt(x) correctly rounded, for x >= 0 finite: keep y iff -y (y - down) < x - y^2 <= y (up - y)
// (x - y^2 and those bounds are multiples of the squared gap, so the tie-free test is exact).
double squareRoot(double x)
{
    precise double y0 = sqrt(x);
    double y = perturbed(y0);
    if (!(x > 0.0) || y == 0.0) return y0;
    for (int it = 0;; ++it) {
        double p, e;
        twoProduct(y, y, p, e);
        precise double r = (x - p) - e; // x - y^2
        const dvec2 h = halfGaps(y);
        precise double tu = y * (2.0 * h.x);
        precise double td = y * (2.0 * h.y);
        if ((r <= tu && -r < td) || it == 8) break;
        if (abs(r) > 8.0 * tu) {
            precise double yn = y + r / (2.0 * y);
            y = yn;
        } else {
            y = r > tu ? nextUp(y) : nextDown(y);
        }
    }
    return y;
}

// ---- the lower envelope

// Where the parabola of site q (height hq at its apex q) starts to lie below the one of site a
// (value fa): Envelope::run()'s (hq - (fa + s2 a a)) / (2 s2 (q - a)), term for term.
double breakpoint(double hq, int q, int a, double fa)
{
    precise double ha = fa + pc.s2 * double(a) * double(a);
    precise double num = hq - ha;
    precise double den = 2.0 * pc.s2 * double(q - a);
    return divide(num, den);
}

void main()
{
    const uint t = gl_GlobalInvocationID.x;
    if (t >= pc.lines) return;
    const uint line = pc.firstLine + t;
    const uint base = (line % pc.linesA) * pc.strideA + (line / pc.linesA) * pc.strideB;
    const uint S = pc.lines;
    const double inf = packDouble2x32(uvec2(0u, 0x7ff00000u));
    const double s2 = pc.s2;
    const int n = int(pc.n);
    const uint pass = pc.mode & 3u;

    // the lower envelope of the finite samples, sites in increasing order
    int k = -1;
    for (int q = 0; q < n; ++q) {
        const uint at = base + uint(q) * pc.step;
        double fq;
        if (pass == 0u) {
            if (((mask[at >> 2u] >> ((at & 3u) * 8u)) & 0xffu) == 0u) continue;
            fq = 0.0;
        } else {
            fq = double(g[at]);
            if (!(fq < inf)) continue;
        }
        precise double hq = fq + s2 * double(q) * double(q);
        if (k < 0) {
            k = 0;
            site[t] = q;
            value[t] = float(fq);
            brk[t] = -inf;
            brk[S + t] = inf;
            continue;
        }
        double s = breakpoint(hq, q, site[uint(k) * S + t], double(value[uint(k) * S + t]));
        while (s <= brk[uint(k) * S + t]) {
            --k;
            s = breakpoint(hq, q, site[uint(k) * S + t], double(value[uint(k) * S + t]));
        }
        ++k;
        site[uint(k) * S + t] = q;
        value[uint(k) * S + t] = float(fq);
        brk[uint(k) * S + t] = s;
        brk[uint(k + 1) * S + t] = inf;
    }
    if (k < 0) {
        // no finite sample: the x pass writes +inf (the CPU's initial value); the other passes
        // leave the line as it is (already +inf everywhere)
        if (pass == 0u) {
            const float finf = uintBitsToFloat(0x7f800000u);
            for (int p = 0; p < n; ++p) g[base + uint(p) * pc.step] = finf;
        }
        return;
    }
    // evaluation at every sample, in place (the inputs were all read above)
    int c = 0;
    for (int p = 0; p < n; ++p) {
        while (brk[uint(c + 1) * S + t] < double(p)) ++c;
        precise double d = double(p - site[uint(c) * S + t]);
        precise double r = s2 * d * d + double(value[uint(c) * S + t]);
        if (pass == 2u) {
            g[base + uint(p) * pc.step] = float(squareRoot(r));
        } else {
            g[base + uint(p) * pc.step] = float(r);
        }
    }
}
