// Exact screened Poisson solve through a 2-D DCT-II built on real FFTs.
//
// With forward differences and the last row dropped, Dx^T Dx is the Neumann
// 1-D Laplacian whose eigenvectors are the DCT-II basis cos(pi k (2n+1) / 2N)
// with eigenvalues 2 - 2 cos(pi k / N). So (a I + b L) x = rhs is solved by
// X = DCT(rhs) / (a + b (l1[k1] + l2[k2])), x = DCT^-1(X).
//
// The DCT-II is computed with Makhoul's (1980) method: reorder each dimension
// (even samples ascending, then odd ones descending), take a 2-D real DFT V,
// and Y[k1,k2] = 2 Re{ w1^k1 [ w2^k2 V[k1,k2] + w2^-k2 V[k1,N2-k2] ] } with
// w = exp(-i pi / 2N) (Y is FFTW's REDFT10 scaling). Inverting per dimension
// (V[k] = w^-k (Y[k] - i Y[N-k]) / 2, Y[N] = 0) gives
//   V[k1,k2] = 1/4 w1^-k1 w2^-k2 [ Y[k1,k2] - Y[N1-k1,N2-k2] - i (Y[N1-k1,k2] + Y[k1,N2-k2]) ].
// Both maps only couple the entries {k1, N1-k1} x {k2, N2-k2}, which the
// half spectrum of a real FFT stores in one column at rows k1 and N1-k1, so
// the whole "transform, divide, transform back" in the DCT domain becomes a
// local operation on the DFT spectrum, done per column between the forward
// and inverse column FFTs while the column block is in cache.
//
// Passes (each split into blocks run by TBB): gather + row r2c FFTs; per
// block of columns: forward c2c FFT, spectral divide, inverse c2c FFT; row
// c2r FFTs + scatter. Plans are cached per size; FFTW's planner is not
// thread-safe, so all planning happens under one mutex.

#include "gdr/reconstruct/poisson.h"

#include <fftw3.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

#include "gdr/core/error.h"

namespace gdr {
namespace {

constexpr int kRowBlock = 16;  // rows per task; a multiple of 16 keeps every block 64-byte aligned
constexpr int kColBlock = 16;  // complex columns per task (128 bytes wide: two cache lines)

size_t pad16(size_t n) { return (n + 15) / 16 * 16; }

/// Position in the input of entry m of Makhoul's reordering.
int makhoul_source(int m, int n) { return m < (n + 1) / 2 ? 2 * m : 2 * (n - 1 - m) + 1; }

std::mutex& planner_mutex() {
    static std::mutex m;
    return m;
}

/// Everything that depends on the size only; shared by all solvers of that size.
struct SizePlans {
    int w = 0, h = 0, wc = 0;
    size_t real_plane = 0, cplx_plane = 0;  // padded plane strides (elements)
    std::vector<int> src_x, src_y;          // Makhoul reordering
    std::vector<std::complex<float>> tw1, tw2;  // exp(-i pi k / 2N)
    std::vector<float> l1, l2;                  // 2 - 2 cos(pi k / N)
    std::vector<float> c2, s2, l2r;             // cos / sin(pi k2 / 2 N2), l2[N2 - k2]
    // Plans for a full block and for the tail block (nullptr if no tail).
    fftwf_plan row_fwd = nullptr, row_fwd_tail = nullptr, row_inv = nullptr, row_inv_tail = nullptr;
    fftwf_plan col_fwd = nullptr, col_fwd_tail = nullptr, col_inv = nullptr, col_inv_tail = nullptr;
    int row_block = 0, row_tail = 0, col_block = 0, col_tail = 0;
};

fftwf_plan plan_rows(int w, int count, int wc, bool forward, float* real, fftwf_complex* cplx) {
    if (count == 0) return nullptr;
    int n[1] = {w};
    fftwf_plan p = forward
                       ? fftwf_plan_many_dft_r2c(1, n, count, real, nullptr, 1, w, cplx, nullptr, 1, wc, FFTW_ESTIMATE)
                       : fftwf_plan_many_dft_c2r(1, n, count, cplx, nullptr, 1, wc, real, nullptr, 1, w, FFTW_ESTIMATE);
    if (!p) throw RuntimeFailure("FFTW could not plan row transforms of length " + std::to_string(w));
    return p;
}

fftwf_plan plan_cols(int h, int count, int wc, int sign, fftwf_complex* cplx) {
    if (count == 0) return nullptr;
    int n[1] = {h};
    fftwf_plan p = fftwf_plan_many_dft(1, n, count, cplx, nullptr, wc, 1, cplx, nullptr, wc, 1, sign, FFTW_ESTIMATE);
    if (!p) throw RuntimeFailure("FFTW could not plan column transforms of length " + std::to_string(h));
    return p;
}

/// The cached plans for one size (created on first use).
const SizePlans& plans_for(int w, int h) {
    static std::map<std::pair<int, int>, std::unique_ptr<SizePlans>> cache;
    std::lock_guard<std::mutex> lock(planner_mutex());
    auto& slot = cache[{w, h}];
    if (slot) return *slot;
    auto s = std::make_unique<SizePlans>();
    s->w = w, s->h = h, s->wc = w / 2 + 1;
    s->real_plane = pad16(size_t(w) * h);
    s->cplx_plane = pad16(size_t(s->wc) * h);
    s->src_x.resize(w), s->src_y.resize(h);
    for (int m = 0; m < w; ++m) s->src_x[m] = makhoul_source(m, w);
    for (int m = 0; m < h; ++m) s->src_y[m] = makhoul_source(m, h);
    const double pi = 3.14159265358979323846;
    for (int k = 0; k < h; ++k) {
        s->tw1.emplace_back(float(std::cos(pi * k / (2.0 * h))), float(-std::sin(pi * k / (2.0 * h))));
        s->l1.push_back(float(2.0 - 2.0 * std::cos(pi * k / h)));
    }
    for (int k = 0; k < w; ++k) {
        s->tw2.emplace_back(float(std::cos(pi * k / (2.0 * w))), float(-std::sin(pi * k / (2.0 * w))));
        s->l2.push_back(float(2.0 - 2.0 * std::cos(pi * k / w)));
    }
    for (int k = 0; k < w; ++k) {
        s->c2.push_back(s->tw2[k].real()), s->s2.push_back(-s->tw2[k].imag());
        s->l2r.push_back(s->l2[(w - k) % w]);
    }
    s->row_block = std::min(h, kRowBlock), s->row_tail = h % s->row_block;
    s->col_block = std::min(s->wc, kColBlock), s->col_tail = s->wc % s->col_block;
    // Plan on scratch arrays of the solver's layout (FFTW_ESTIMATE never
    // touches them); executions use other arrays with the same alignment.
    float* real = fftwf_alloc_real(s->real_plane);
    fftwf_complex* cplx = fftwf_alloc_complex(s->cplx_plane);
    if (!real || !cplx) throw RuntimeFailure("FFTW could not allocate scratch memory");
    try {
        s->row_fwd = plan_rows(w, s->row_block, s->wc, true, real, cplx);
        s->row_fwd_tail = plan_rows(w, s->row_tail, s->wc, true, real, cplx);
        s->row_inv = plan_rows(w, s->row_block, s->wc, false, real, cplx);
        s->row_inv_tail = plan_rows(w, s->row_tail, s->wc, false, real, cplx);
        s->col_fwd = plan_cols(h, s->col_block, s->wc, FFTW_FORWARD, cplx);
        s->col_fwd_tail = plan_cols(h, s->col_tail, s->wc, FFTW_FORWARD, cplx);
        s->col_inv = plan_cols(h, s->col_block, s->wc, FFTW_BACKWARD, cplx);
        s->col_inv_tail = plan_cols(h, s->col_tail, s->wc, FFTW_BACKWARD, cplx);
    } catch (...) {
        fftwf_free(real), fftwf_free(cplx);
        throw;
    }
    fftwf_free(real), fftwf_free(cplx);
    slot = std::move(s);
    return *slot;
}

/// The spectral divide for the generic entries (rows k1 and m = N1 - k1 with
/// k1 != 0, N1 / 2; columns k2 != 0, N2 / 2) of two spectrum rows, in plain
/// float arithmetic so it vectorises: the DCT coefficients Y of the four
/// entries {k1, m} x {k2, N2 - k2} from the two stored values, divided by the
/// eigenvalues, and mapped back (see the file comment). With m = N1 - k1,
/// w1^m = -i conj(w1^k1) up to the factor used below (cos and sin swap).
void divide_generic(int k2_begin, int k2_end, float* __restrict Sk, float* __restrict Sm, float c1, float s1,
                    float l1k, float l1m, const float* __restrict c2, const float* __restrict s2,
                    const float* __restrict l2, const float* __restrict l2r, float fa, float fb, float scale) {
    for (int k2 = k2_begin; k2 < k2_end; ++k2) {
        const float kr = Sk[2 * k2], ki = Sk[2 * k2 + 1], mr = Sm[2 * k2], mi = Sm[2 * k2 + 1];
        const float c = c2[k2], s = s2[k2];
        const float pr = c * kr + s * ki, pi = c * ki - s * kr;  // w2^k2 V[k1,k2]
        const float qr = c * mr + s * mi, qi = c * mi - s * mr;  // w2^k2 V[m,k2]
        const float xak = 2.f * (c1 * (pr + qr) + s1 * (pi - qi)) / (fa + fb * (l1k + l2[k2]));
        const float xbk = -2.f * (c1 * (pi + qi) - s1 * (pr - qr)) / (fa + fb * (l1k + l2r[k2]));
        const float xam = 2.f * (s1 * (qr + pr) + c1 * (qi - pi)) / (fa + fb * (l1m + l2[k2]));
        const float xbm = -2.f * (s1 * (qi + pi) - c1 * (qr - pr)) / (fa + fb * (l1m + l2r[k2]));
        const float zkr = xak - xbm, zki = -(xam + xbk), zmr = xam - xbk, zmi = -(xak + xbm);
        const float ur = scale * (c1 * c - s1 * s), ui = scale * (c1 * s + s1 * c);  // conj(w1^k1 w2^k2)
        const float vr = scale * (s1 * c - c1 * s), vi = scale * (s1 * s + c1 * c);  // conj(w1^m w2^k2)
        Sk[2 * k2] = ur * zkr - ui * zki, Sk[2 * k2 + 1] = ur * zki + ui * zkr;
        Sm[2 * k2] = vr * zmr - vi * zmi, Sm[2 * k2 + 1] = vr * zmi + vi * zmr;
    }
}

}  // namespace

struct DctSolver::Impl {
    const SizePlans* plans = nullptr;
    float* real = nullptr;          // reordered input / output planes
    fftwf_complex* cplx = nullptr;  // half spectra
    int capacity = 0;               // channels the scratch holds

    ~Impl() {
        fftwf_free(real);
        fftwf_free(cplx);
    }
    void reserve(int channels) {
        if (channels <= capacity) return;
        fftwf_free(real), fftwf_free(cplx);
        real = fftwf_alloc_real(plans->real_plane * channels);
        cplx = fftwf_alloc_complex(plans->cplx_plane * channels);
        if (!real || !cplx) throw RuntimeFailure("DctSolver: out of memory");
        capacity = channels;
    }
};

DctSolver::DctSolver(int width, int height) : impl_(std::make_unique<Impl>()) {
    if (width < 1 || height < 1)
        throw ParameterError("DctSolver: bad size " + std::to_string(width) + "x" + std::to_string(height));
    impl_->plans = &plans_for(width, height);
}

DctSolver::~DctSolver() = default;

int DctSolver::width() const { return impl_->plans->w; }
int DctSolver::height() const { return impl_->plans->h; }

void DctSolver::solve(const float* rhs, float* x, int channels, double a, double b, bool interleaved,
                      bool* all_finite) {
    if (channels < 1) throw ParameterError("DctSolver::solve: no channels");
    if (!(a >= 0) || !(b >= 0) || !std::isfinite(a) || !std::isfinite(b))
        throw ParameterError("DctSolver::solve: coefficients must be finite and non-negative");
    const SizePlans& s = *impl_->plans;
    impl_->reserve(channels);
    const int w = s.w, h = s.h, wc = s.wc;
    const size_t n = size_t(w) * h;
    float* real = impl_->real;
    fftwf_complex* cplx = impl_->cplx;

    const int row_blocks = (h + s.row_block - 1) / s.row_block;
    const int col_blocks = (wc + s.col_block - 1) / s.col_block;

    // 1. Gather in Makhoul order and transform the rows. A task takes a block
    // of rows of every channel, so interleaved input is read once.
    const size_t stride = interleaved ? size_t(channels) : 1;  // between neighbouring pixels of one channel
    auto element0 = [&](int c, int y) {  // offset of pixel (0, y) of channel c
        return interleaved ? size_t(y) * w * channels + c : c * n + size_t(y) * w;
    };
    tbb::parallel_for(0, row_blocks, [&](int task) {
        const int r0 = task * s.row_block;
        const int rows = std::min(s.row_block, h - r0);
        for (int c = 0; c < channels; ++c) {
            float* v = real + c * s.real_plane;
            for (int m1 = r0; m1 < r0 + rows; ++m1) {
                const float* in = rhs + element0(c, s.src_y[m1]);
                float* out = v + size_t(m1) * w;
                for (int m2 = 0; m2 < w; ++m2) out[m2] = in[size_t(s.src_x[m2]) * stride];
            }
            fftwf_execute_dft_r2c(rows == s.row_block ? s.row_fwd : s.row_fwd_tail, v + size_t(r0) * w,
                                  cplx + c * s.cplx_plane + size_t(r0) * wc);
        }
    });

    // 2. Per column block: forward column FFT, divide in the DCT domain, inverse column FFT.
    const float fa = float(a), fb = float(b);
    const float scale = float(1.0 / (4.0 * double(w) * double(h)));
    tbb::parallel_for(0, channels * col_blocks, [&](int task) {
        const int c = task / col_blocks, k0 = (task % col_blocks) * s.col_block;
        const int cols = std::min(s.col_block, wc - k0);
        fftwf_complex* S = cplx + c * s.cplx_plane;
        fftwf_execute_dft(cols == s.col_block ? s.col_fwd : s.col_fwd_tail, S + k0, S + k0);
        auto inv_lambda = [&](int k1, int k2) {
            const float l = fa + fb * (s.l1[k1] + s.l2[k2]);
            return l > 0.f ? 1.f / l : 0.f;  // a == 0: drop the constant component
        };
        // Columns 0 and N2 / 2 and rows 0 and N1 / 2 need the general
        // formulas; everything else goes through divide_generic.
        const int g0 = std::max(k0, 1), g1 = std::min(k0 + cols, w % 2 == 0 ? wc - 1 : wc);
        for (int k1 = 0; k1 <= h / 2; ++k1) {
            const int m = (h - k1) % h;  // partner row (N1 - k1 mod N1)
            const bool generic_row = k1 != 0 && m != k1;
            if (generic_row && g0 < g1)
                divide_generic(g0, g1, &S[size_t(k1) * wc][0], &S[size_t(m) * wc][0], s.tw1[k1].real(),
                               -s.tw1[k1].imag(), s.l1[k1], s.l1[m], s.c2.data(), s.s2.data(), s.l2.data(),
                               s.l2r.data(), fa, fb, scale);
            for (int k2 = k0; k2 < k0 + cols; ++k2) {
                if (generic_row && k2 >= g0 && k2 < g1) continue;
                const bool zero2 = k2 == 0;        // column N2 - k2 is "N2": outside, zero
                const bool self2 = 2 * k2 == w;    // column N2 - k2 is k2 itself
                const std::complex<float> t2 = s.tw2[k2];
                const std::complex<float> sk(S[size_t(k1) * wc + k2][0], S[size_t(k1) * wc + k2][1]);
                const std::complex<float> sm(S[size_t(m) * wc + k2][0], S[size_t(m) * wc + k2][1]);
                // X at (row, k2) and (row, N2 - k2) for rows k1 and m.
                float xk = 0, xkb = 0, xm = 0, xmb = 0;
                auto dct_pair = [&](int r, const std::complex<float>& vr, const std::complex<float>& vpartner,
                                    float& x_a, float& x_b) {
                    const std::complex<float> vb = (zero2 || self2) ? vr : std::conj(vpartner);
                    const std::complex<float> A = t2 * vr, B = std::conj(t2) * vb;
                    const std::complex<float> t1 = s.tw1[r];
                    x_a = 2.f * (t1 * (A + B)).real() * inv_lambda(r, k2);
                    if (zero2) x_b = 0.f;
                    else if (self2) x_b = x_a;
                    else x_b = -2.f * (t1 * (A - B)).imag() * inv_lambda(r, w - k2);
                };
                dct_pair(k1, sk, sm, xk, xkb);
                if (m != k1) dct_pair(m, sm, sk, xm, xmb);
                else xm = xk, xmb = xkb;
                // Back to the spectrum: row r's partner r_bar = N1 - r is zero when r == 0.
                auto spectrum = [&](int r, float x_a, float x_b, float xbar_a, float xbar_b) {
                    const std::complex<float> z(x_a - xbar_b, -(xbar_a + x_b));
                    return std::conj(s.tw1[r]) * std::conj(t2) * z * scale;
                };
                const bool k1_zero = k1 == 0;
                const std::complex<float> nk = spectrum(k1, xk, xkb, k1_zero ? 0.f : xm, k1_zero ? 0.f : xmb);
                S[size_t(k1) * wc + k2][0] = nk.real(), S[size_t(k1) * wc + k2][1] = nk.imag();
                if (m != k1) {
                    const std::complex<float> nm = spectrum(m, xm, xmb, xk, xkb);
                    S[size_t(m) * wc + k2][0] = nm.real(), S[size_t(m) * wc + k2][1] = nm.imag();
                }
            }
        }
        fftwf_execute_dft(cols == s.col_block ? s.col_inv : s.col_inv_tail, S + k0, S + k0);
    });

    // 3. Inverse row transforms and scatter back to natural order; the
    // exponent bits of the values are OR-ed on the way (NaN / Inf: all ones).
    std::vector<std::uint32_t> bad(all_finite ? row_blocks : 0, 0);
    tbb::parallel_for(0, row_blocks, [&](int task) {
        const int r0 = task * s.row_block;
        const int rows = std::min(s.row_block, h - r0);
        std::uint32_t any = 0;
        for (int c = 0; c < channels; ++c) {
            float* v = real + c * s.real_plane;
            fftwf_execute_dft_c2r(rows == s.row_block ? s.row_inv : s.row_inv_tail,
                                  cplx + c * s.cplx_plane + size_t(r0) * wc, v + size_t(r0) * w);
            for (int m1 = r0; m1 < r0 + rows; ++m1) {
                float* out = x + element0(c, s.src_y[m1]);
                const float* in = v + size_t(m1) * w;
                for (int m2 = 0; m2 < w; ++m2) out[size_t(s.src_x[m2]) * stride] = in[m2];
                if (all_finite)
                    for (int m2 = 0; m2 < w; ++m2)
                        any |= (std::bit_cast<std::uint32_t>(in[m2]) & 0x7f800000u) == 0x7f800000u;
            }
        }
        if (all_finite) bad[task] = any;
    });
    if (all_finite) *all_finite = std::find(bad.begin(), bad.end(), 1u) == bad.end();
}

}  // namespace gdr
