// Lockstep path tracing. Each vertex has three stages: (A) per path, the ray
// cast, emission, and either the scalar scattering step (a vertex that is not
// an untextured Lambertian) or the light sample, gathered into
// structure-of-arrays lanes; (B) per four paths, the Lambertian shading
// arithmetic in vector registers; (C) per path, the shadow ray, roulette and
// the paths that end leaving the lanes. Stage B repeats scatter()'s
// operations in its order, so images are bit-identical to the scalar kernel
// (the vectorised select, square root and division round as the scalar ones).
#ifdef GDR_SIMD  // x86 only (SSE); without it pt always takes the scalar kernel
#include "pt_lockstep.h"

#include <cstring>
#include <string>

#include <xmmintrin.h>

#include "gdr/core/error.h"
#include "gdr/path/vertex.h"
#include "gdr/path/dims.h"

namespace gdr::detail {
namespace {

using f4 = float __attribute__((vector_size(16)));
using i4 = int32_t __attribute__((vector_size(16)));

inline f4 load(const float* p) {
    f4 v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline void store(float* p, f4 v) { std::memcpy(p, &v, sizeof v); }
inline i4 load(const int32_t* p) {
    i4 v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline void store(int32_t* p, i4 v) { std::memcpy(p, &v, sizeof v); }
inline f4 abs4(f4 x) { return (f4)((i4)x & 0x7fffffff); }
inline f4 sqrt4(f4 x) { return (f4)_mm_sqrt_ps((__m128)x); }

constexpr int N = kLockstepLanes;
static_assert(N % 4 == 0);

// The lanes: slots [0, live) hold the paths still running, in no order.
struct Lanes {
    // The ray to the next vertex, the throughput (unitless RGB) and the pdf
    // (1/sr) of the direction that ray was sampled with.
    alignas(16) float o[3][N], d[3][N], beta[3][N], prev_pdf[N];
    bool prev_delta[N], aux_done[N];  // as PathState's
    float u_light[N], u_lobe[N];      // the next vertex's emitter and lobe numbers, drawn a vertex ahead
    int path[N];                      // index into the caller's arrays
    bool scattered[N];                // the scalar step ran at this vertex, and the path goes on
    // Stage A's gathering: the vertex (position, geometric normal, shading
    // frame, f in 1/sr, direction numbers) and its light sample (point,
    // normal, radiance, area pdf in 1/m^2).
    alignas(16) float p[3][N], ng[3][N], fs[3][N], ft[3][N], fn[3][N], f[3][N], u[2][N];
    alignas(16) float lp[3][N], ln[3][N], le[3][N], lpdf[N];
    alignas(16) int32_t shade[N], lit[N];  // all ones: the vertex scatters; its light sample emits towards it
    // Stage B's results: the light connection (its contribution if the
    // shadow segment so -> so + sv is clear), whether the path continues,
    // with which throughput, pdf and ray.
    alignas(16) float c[3][N], so[3][N], sv[3][N], nbeta[3][N], pdf[N], no[3][N], nd[3][N];
    alignas(16) int32_t connect[N], cont[N];

    /// Moves the path in slot `from` to slot `to`: what a path carries
    /// between vertices (the rest is rebuilt at every vertex).
    void move_path(int from, int to) {
        for (int c = 0; c < 3; ++c) o[c][to] = o[c][from], d[c][to] = d[c][from], beta[c][to] = beta[c][from];
        prev_pdf[to] = prev_pdf[from], prev_delta[to] = prev_delta[from], aux_done[to] = aux_done[from];
        u_light[to] = u_light[from], u_lobe[to] = u_lobe[from];
        path[to] = path[from];
    }
};

// offset_ray_origin()'s offset length at p: 1e-4 max(1, |p.x|, |p.y|, |p.z|),
// with std::max's (a < b) ? b : a, so that the bits match.
inline f4 offset_scale(f4 px, f4 py, f4 pz) {
    const f4 ax = abs4(px), ay = abs4(py), az = abs4(pz);
    const f4 m1 = ay < az ? az : ay;
    const f4 m2 = ax < m1 ? m1 : ax;
    const f4 one = {1.f, 1.f, 1.f, 1.f};
    return 1e-4f * (1.f < m2 ? m2 : one);
}

// Stage B for slots g..g+3.
inline void shade4(Lanes& L, int g) {
    const f4 zero = {0.f, 0.f, 0.f, 0.f};
    const f4 sx = load(L.fs[0] + g), sy = load(L.fs[1] + g), sz = load(L.fs[2] + g);
    const f4 tx = load(L.ft[0] + g), ty = load(L.ft[1] + g), tz = load(L.ft[2] + g);
    const f4 nx = load(L.fn[0] + g), ny = load(L.fn[1] + g), nz = load(L.fn[2] + g);
    // Only the cosines of wo and of the light direction are needed
    // (Frame::to_local's z): a Lambertian lobe depends on nothing else.
    const f4 woz = (-load(L.d[0] + g) * nx + -load(L.d[1] + g) * ny) + -load(L.d[2] + g) * nz;
    const i4 shade = load(L.shade + g);

    // Cosine-weighted direction (warp::square_to_cosine_hemisphere).
    const f4 a = 2.f * load(L.u[0] + g) - 1.f, b = 2.f * load(L.u[1] + g) - 1.f;
    const i4 horizontal = abs4(a) > abs4(b);
    const f4 r = horizontal ? a : b, q = horizontal ? b : a;
    const f4 x = (kPi / 4.f) * (q / r);
    const f4 x2 = x * x, x4 = x2 * x2;
    const f4 sn = x * ((1.f + x2 * (-1.f / 6.f)) + x4 * ((1.f / 120.f + x2 * (-1.f / 5040.f)) + x4 * (1.f / 362880.f)));
    const f4 cs = (1.f + x2 * -0.5f) +
                  x4 * ((1.f / 24.f + x2 * (-1.f / 720.f)) + x4 * (1.f / 40320.f + x2 * (-1.f / 3628800.f)));
    const i4 centre = r == 0.f;
    const f4 wix = centre ? zero : r * (horizontal ? cs : sn);
    const f4 wiy = centre ? zero : r * (horizontal ? sn : cs);
    const f4 z2 = (1.f - wix * wix) - wiy * wiy;
    f4 wiz = sqrt4(0.f < z2 ? z2 : zero);
    const i4 sampled = (woz != 0.f) & (wiz > 0.f);
    const f4 pdf = wiz * kInvPi;
    wiz = woz < 0.f ? -wiz : wiz;  // two-sided: to wo's side

    const f4 fr = load(L.f[0] + g), fg = load(L.f[1] + g), fb = load(L.f[2] + g);
    const f4 br = load(L.beta[0] + g), bg = load(L.beta[1] + g), bb = load(L.beta[2] + g);
    const f4 px = load(L.p[0] + g), py = load(L.p[1] + g), pz = load(L.p[2] + g);

    // The light connection.
    const f4 dx = load(L.lp[0] + g) - px, dy = load(L.lp[1] + g) - py, dz = load(L.lp[2] + g) - pz;
    const f4 dist2 = (dx * dx + dy * dy) + dz * dz;
    const f4 dist = sqrt4(dist2);
    const f4 wwx = dx / dist, wwy = dy / dist, wwz = dz / dist;
    const f4 wlz = (wwx * nx + wwy * ny) + wwz * nz;
    const i4 connect = shade & load(L.lit + g) & (dist2 > 0.f) & (woz * wlz > 0.f);
    const f4 cos_l = (load(L.ln[0] + g) * -wwx + load(L.ln[1] + g) * -wwy) + load(L.ln[2] + g) * -wwz;
    const f4 pdf_l = cos_l > 0.f ? load(L.lpdf + g) * dist * dist / cos_l : zero;
    const f4 pdf_b = abs4(wlz) * kInvPi;
    const f4 a2 = pdf_l * pdf_l, b2 = pdf_b * pdf_b;
    const f4 w = a2 > 0.f ? a2 / (a2 + b2) : zero;  // power heuristic
    const f4 cw = w / pdf_l, cl = abs4(wlz);
    store(L.c[0] + g, ((br * fr) * cl) * load(L.le[0] + g) * cw);
    store(L.c[1] + g, ((bg * fg) * cl) * load(L.le[1] + g) * cw);
    store(L.c[2] + g, ((bb * fb) * cl) * load(L.le[2] + g) * cw);
    store(L.connect + g, connect);

    // The continuation: throughput, direction (Frame::to_world) and origin
    // (offset_ray_origin).
    const i4 cont = shade & sampled & (pdf > 0.f);
    const f4 k = abs4(wiz) / pdf;
    store(L.nbeta[0] + g, br * (fr * k));
    store(L.nbeta[1] + g, bg * (fg * k));
    store(L.nbeta[2] + g, bb * (fb * k));
    store(L.pdf + g, pdf);
    const f4 ox = (sx * wix + tx * wiy) + nx * wiz;
    const f4 oy = (sy * wix + ty * wiy) + ny * wiz;
    const f4 oz = (sz * wix + tz * wiy) + nz * wiz;
    const f4 scale = offset_scale(px, py, pz);
    const f4 gx = load(L.ng[0] + g), gy = load(L.ng[1] + g), gz = load(L.ng[2] + g);
    const f4 side = ((gx * ox + gy * oy) + gz * oz) >= 0.f ? scale : -scale;
    // The shadow segment (Scene::visible's offsets of both ends).
    {
        const f4 near = ((gx * dx + gy * dy) + gz * dz) >= 0.f ? scale : -scale;
        const f4 sox = px + near * gx, soy = py + near * gy, soz = pz + near * gz;
        const f4 lx = load(L.lp[0] + g), ly = load(L.lp[1] + g), lz = load(L.lp[2] + g);
        const f4 mx = load(L.ln[0] + g), my = load(L.ln[1] + g), mz = load(L.ln[2] + g);
        const f4 lscale = offset_scale(lx, ly, lz);
        const f4 far = ((mx * -dx + my * -dy) + mz * -dz) >= 0.f ? lscale : -lscale;
        store(L.so[0] + g, sox);
        store(L.so[1] + g, soy);
        store(L.so[2] + g, soz);
        store(L.sv[0] + g, (lx + far * mx) - sox);
        store(L.sv[1] + g, (ly + far * my) - soy);
        store(L.sv[2] + g, (lz + far * mz) - soz);
    }
    store(L.no[0] + g, px + side * gx);
    store(L.no[1] + g, py + side * gy);
    store(L.no[2] + g, pz + side * gz);
    store(L.nd[0] + g, ox);
    store(L.nd[1] + g, oy);
    store(L.nd[2] + g, oz);
    store(L.cont + g, cont);
}

}  // namespace

void trace_lockstep_paths(const Scene& scene, const Ray* rays, SurfaceInteraction* si, const bool* hit,
                          Sampler* const* samplers, int m, const PathOptions& opt, PathResult* results) {
    if (!opt.nee || !scene.has_lights() || m < 0 || m > N)
        throw RuntimeFailure("trace_lockstep_paths: needs NEE, a scene with emitters and at most " + std::to_string(N) +
                             " paths");
    // Slots that do not shade (past `live`, or whose path ends at this
    // vertex) are computed too, four at a time, and ignored: they start as
    // zeros, and later hold a path's finite numbers, so that no lane
    // computes with denormals. Stage B's outputs need no start.
    Lanes L;
    const size_t state = m < N ? 0 : offsetof(Lanes, p);
    std::memset(reinterpret_cast<char*>(&L) + state, 0, offsetof(Lanes, c) - state);
    int live = m;
    for (int i = 0; i < m; ++i) {
        results[i] = PathResult();
        L.path[i] = i;
        const PathState st;
        for (int c = 0; c < 3; ++c) L.o[c][i] = rays[i].o[c], L.d[c][i] = rays[i].d[c], L.beta[c][i] = st.beta[c];
        L.prev_pdf[i] = st.prev_pdf_w, L.prev_delta[i] = st.prev_delta, L.aux_done[i] = st.aux_done;
        const Vec2 u_sel = samplers[i]->at2(dims::vertex(1) + dims::kLightSelect);
        L.u_light[i] = u_sel.x, L.u_lobe[i] = u_sel.y;
    }
    // Light-sample prefetching: the alias-table bucket of a path's next
    // emitter (which holds both emitters it may pick) as its number is drawn
    // in stage C, a vertex ahead. On veach-mis (11,904 emitters) this saves
    // about 5% of the CPU time; drawing the numbers in stage A instead of C
    // cost 1-2% more.
    const bool prefetch = opt.nee && scene.light_prefetch_pays();

    for (int depth = 1; live > 0; ++depth) {
        const uint32_t block = dims::vertex(depth);
        // Stage A.
        for (int s = 0; s < live; ++s) {
            PathResult& res = results[L.path[s]];
            Sampler& sampler = *samplers[L.path[s]];
            const Vec2 u_sel(L.u_light[s], L.u_lobe[s]);
            L.shade[s] = 0;
            L.scattered[s] = false;
            ++res.rays;
            Ray ray{Vec3(L.o[0][s], L.o[1][s], L.o[2][s]), Vec3(L.d[0][s], L.d[1][s], L.d[2][s]), 0.f, kInf};
            SurfaceInteraction& h = si[s];
            if (depth == 1 ? !hit[s] : !scene.intersect(ray, h)) continue;
            if (depth == 1) res.depth = h.t;
            const Vec3 wo_world = -ray.d;
            PathState st{Color(L.beta[0][s], L.beta[1][s], L.beta[2][s]), L.prev_delta[s], L.prev_pdf[s],
                         L.aux_done[s]};
            add_emission(scene, h, wo_world, st, opt, res);
            if (opt.max_depth > 0 && depth >= opt.max_depth) continue;
            const Material& mat = *h.material;
            if (!mat.lambertian) {
                if (!scatter(scene, h, wo_world, sampler, opt, depth, u_sel, st, res, ray)) continue;
                L.scattered[s] = true;
                for (int c = 0; c < 3; ++c) L.beta[c][s] = st.beta[c], L.o[c][s] = ray.o[c], L.d[c][s] = ray.d[c];
                L.prev_pdf[s] = st.prev_pdf_w, L.prev_delta[s] = st.prev_delta, L.aux_done[s] = st.aux_done;
                continue;
            }
            if (!st.aux_done) {  // a Lambertian vertex is never pure delta
                res.albedo = mat.bsdf->albedo(h.uv);
                res.normal = h.frame.n;
                L.aux_done[s] = true;
            }
            if (mat.black) continue;
            L.shade[s] = -1;
            const Vec2 u_dir = sampler.at2(block + dims::kBsdfDir);
            const LightSample ls = scene.sample_light(h.p, u_sel.x, sampler.at2(block + dims::kLightPoint));
            for (int c = 0; c < 3; ++c) {
                L.p[c][s] = h.p[c], L.ng[c][s] = h.ng[c];
                L.fs[c][s] = h.frame.s[c], L.ft[c][s] = h.frame.t[c], L.fn[c][s] = h.frame.n[c];
                L.f[c][s] = mat.lambertian_f[c];
                L.lp[c][s] = ls.p[c], L.ln[c][s] = ls.n[c], L.le[c][s] = ls.radiance[c];
            }
            L.u[0][s] = u_dir.x, L.u[1][s] = u_dir.y;
            L.lpdf[s] = ls.pdf_a;
            L.lit[s] = is_black(ls.radiance) ? 0 : -1;
        }
        // Stage B.
        for (int g = 0; g < live; g += 4)
            if (L.shade[g] | L.shade[g + 1] | L.shade[g + 2] | L.shade[g + 3]) shade4(L, g);
        // Stage C, from the last slot down: an ended path's slot takes the
        // last live one, which has been seen already.
        for (int s = live - 1; s >= 0; --s) {
            PathResult& res = results[L.path[s]];
            bool cont = L.scattered[s];
            if (L.shade[s]) {
                if (L.connect[s]) {
                    ++res.rays;
                    const Vec3 o(L.so[0][s], L.so[1][s], L.so[2][s]), v(L.sv[0][s], L.sv[1][s], L.sv[2][s]);
                    if (scene.segment_clear(o, v)) res.radiance += Color(L.c[0][s], L.c[1][s], L.c[2][s]);
                }
                if (L.cont[s]) {
                    Color beta(L.nbeta[0][s], L.nbeta[1][s], L.nbeta[2][s]);
                    cont = true;
                    if (depth >= opt.rr_depth) {
                        const float q = roulette_survival(beta);
                        if (samplers[L.path[s]]->at(block + dims::kRoulette) >= q) cont = false;
                        beta /= q;
                    }
                    for (int c = 0; c < 3; ++c) L.beta[c][s] = beta[c], L.o[c][s] = L.no[c][s], L.d[c][s] = L.nd[c][s];
                    L.prev_pdf[s] = L.pdf[s], L.prev_delta[s] = false;
                }
            }
            if (cont) {
                const Vec2 u_next = samplers[L.path[s]]->at2(dims::vertex(depth + 1) + dims::kLightSelect);
                L.u_light[s] = u_next.x, L.u_lobe[s] = u_next.y;
                if (prefetch) scene.prefetch_light(u_next.x);
                continue;
            }
            const int last = --live;
            if (s == last) continue;
            L.move_path(last, s);
        }
    }
}

}  // namespace gdr::detail
#endif  // GDR_SIMD
