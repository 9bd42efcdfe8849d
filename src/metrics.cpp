// Image error metrics (see gdr/metrics.h).

#include "gdr/metrics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "gdr/io/png.h"

namespace gdr {
namespace {

/// Shape and finiteness checks shared by every metric.
void check_pair(const Image& img, const Image& ref, const char* metric) {
    if (!img.same_shape(ref))
        throw ParameterError(fmt::format("{}: image is {}x{}x{} but reference is {}x{}x{}", metric, img.width(),
                                         img.height(), img.channels(), ref.width(), ref.height(), ref.channels()));
    if (img.empty()) throw ParameterError(std::string(metric) + ": images are empty");
    require_finite(img, std::string(metric) + ": image");
    require_finite(ref, std::string(metric) + ": reference");
}

/// Mean over all values of f(x, r), accumulated in double for 4k-sized images.
template <class F>
double mean_of(const Image& img, const Image& ref, F f) {
    const auto& x = img.values();
    const auto& r = ref.values();
    double sum = 0;
    for (size_t i = 0; i < x.size(); ++i) sum += f(double(x[i]), double(r[i]));
    return sum / double(x.size());
}

/// Normalised 1D Gaussian taps (radius 5, sigma 1.5); 11x11 = outer product.
std::vector<double> gaussian_taps() {
    std::vector<double> t(11);
    double s = 0;
    for (int i = 0; i < 11; ++i) s += t[i] = std::exp(-double((i - 5) * (i - 5)) / (2 * 1.5 * 1.5));
    for (auto& v : t) v /= s;
    return t;
}

/// Gaussian blur of a w x h plane, truncated at the border and renormalised
/// by the in-image weight (separable, so each pass normalises on its own).
std::vector<double> blur(const std::vector<double>& in, int w, int h, const std::vector<double>& taps) {
    // One 1-D pass along rows (step 1) or columns (step w); `n` samples per line.
    const auto pass = [&](const std::vector<double>& src, std::vector<double>& dst, int lines, int n, size_t line_step,
                          size_t step) {
        for (int l = 0; l < lines; ++l)
            for (int i = 0; i < n; ++i) {
                double s = 0, ws = 0;
                for (int k = -5; k <= 5; ++k) {
                    const int j = i + k;
                    if (j < 0 || j >= n) continue;
                    s += taps[k + 5] * src[l * line_step + size_t(j) * step];
                    ws += taps[k + 5];
                }
                dst[l * line_step + size_t(i) * step] = s / ws;
            }
    };
    std::vector<double> tmp(in.size()), out(in.size());
    pass(in, tmp, h, w, size_t(w), 1);
    pass(tmp, out, w, h, 1, size_t(w));
    return out;
}

/// Mean of each channel over all pixels, in double.
std::vector<double> channel_means(const Image& img) {
    const int c = img.channels();
    std::vector<double> m(size_t(c), 0.0);
    for (size_t p = 0; p < img.pixel_count(); ++p)
        for (int k = 0; k < c; ++k) m[size_t(k)] += img.data()[p * c + k];
    for (double& v : m) v /= double(img.pixel_count());
    return m;
}

/// "R", "G", "B", "A" for colour images, "Y" for grey, the index otherwise.
std::string channel_name(int channels, int k) {
    if (channels == 1) return "Y";
    if (channels >= 3) return std::string(1, "RGBA"[k]);
    return std::to_string(k);
}

}  // namespace

double mse(const Image& img, const Image& ref) {
    check_pair(img, ref, "mse");
    return mean_of(img, ref, [](double x, double r) { return (x - r) * (x - r); });
}

double mae(const Image& img, const Image& ref) {
    check_pair(img, ref, "mae");
    return mean_of(img, ref, [](double x, double r) { return std::abs(x - r); });
}

double relmse(const Image& img, const Image& ref, const RelMseOptions& opt) {
    check_pair(img, ref, "relmse");
    if (!(opt.eps > 0.f)) throw ParameterError("relmse: eps must be positive, got " + std::to_string(opt.eps));
    const int c = img.channels();
    const float* x = img.data();
    const float* r = ref.data();
    double sum = 0;
    for (size_t p = 0; p < img.pixel_count(); ++p) {
        double grey = 0;
        for (int k = 0; k < c; ++k) grey += r[p * c + k];
        grey /= c;
        for (int k = 0; k < c; ++k) {
            const double rv = r[p * c + k], d = double(x[p * c + k]) - rv;
            const double den = (opt.grey_denominator ? grey * grey : rv * rv) + double(opt.eps);
            sum += d * d / den;
        }
    }
    return sum / double(img.values().size());
}

double temporal_relmse(const std::vector<Image>& imgs, const std::vector<Image>& refs, float eps) {
    if (imgs.size() != refs.size())
        throw ParameterError(fmt::format("temporal_relmse: {} images but {} references", imgs.size(), refs.size()));
    if (imgs.size() < 2) throw ParameterError("temporal_relmse: needs at least two frames");
    if (!(eps > 0.f)) throw ParameterError("temporal_relmse: eps must be positive, got " + std::to_string(eps));
    for (size_t k = 0; k < imgs.size(); ++k) {
        check_pair(imgs[k], refs[k], "temporal_relmse");
        if (!imgs[k].same_shape(imgs[0]))
            throw ParameterError(fmt::format("temporal_relmse: frame {} differs in shape from frame 0", k));
    }
    double sum = 0.0;
    for (size_t k = 0; k + 1 < imgs.size(); ++k) {
        const auto &x0 = imgs[k].values(), &x1 = imgs[k + 1].values(), &r0 = refs[k].values(), &r1 = refs[k + 1].values();
        for (size_t i = 0; i < x0.size(); ++i) {
            const double d = (double(x1[i]) - double(x0[i])) - (double(r1[i]) - double(r0[i]));
            const double m = 0.5 * (double(r1[i]) + double(r0[i]));
            sum += d * d / (m * m + double(eps));
        }
    }
    return sum / (double(imgs.size() - 1) * double(imgs[0].values().size()));
}

double ssim(const Image& img, const Image& ref, const SsimOptions& opt) {
    check_pair(img, ref, "ssim");
    const int w = img.width(), h = img.height(), c = img.channels();
    const size_t n = img.pixel_count();
    const double C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;  // (K L)^2 with L = 1
    const auto taps = gaussian_taps();
    auto map = [&](float v) { return double(opt.srgb ? linear_to_srgb(v) : std::clamp(v, 0.f, 1.f)); };

    double total = 0;
    std::vector<double> a(n), b(n), aa(n), bb(n), ab(n);
    for (int k = 0; k < c; ++k) {
        for (size_t p = 0; p < n; ++p) {
            a[p] = map(img.data()[p * c + k]);
            b[p] = map(ref.data()[p * c + k]);
            aa[p] = a[p] * a[p], bb[p] = b[p] * b[p], ab[p] = a[p] * b[p];
        }
        const auto mu_a = blur(a, w, h, taps), mu_b = blur(b, w, h, taps);
        const auto e_aa = blur(aa, w, h, taps), e_bb = blur(bb, w, h, taps), e_ab = blur(ab, w, h, taps);
        for (size_t p = 0; p < n; ++p) {
            const double ma = mu_a[p], mb = mu_b[p];
            const double va = e_aa[p] - ma * ma, vb = e_bb[p] - mb * mb, cov = e_ab[p] - ma * mb;
            total += ((2 * ma * mb + C1) * (2 * cov + C2)) / ((ma * ma + mb * mb + C1) * (va + vb + C2));
        }
    }
    return total / double(n * c);
}

std::string compare_report(const Image& img, const Image& ref) {
    check_pair(img, ref, "compare");
    auto mean = [](const Image& im) {
        double s = 0;
        for (float v : im.values()) s += v;
        return s / double(im.values().size());
    };
    std::string out;
    out += fmt::format("size:          {}x{}, {} channels\n", img.width(), img.height(), img.channels());
    out += fmt::format("mean:          {:.6g} (reference {:.6g}; over pixels and channels)\n", mean(img), mean(ref));
    // A mean that is off in one channel only (a colour-space or white-balance
    // slip, a missing emitter colour) hides in the all-channel mean.
    const auto mi = channel_means(img), mr = channel_means(ref);
    for (int k = 0; k < img.channels(); ++k) {
        const std::string ratio = mr[k] != 0.0 ? fmt::format("{:.6g}", mi[k] / mr[k]) : "n/a (reference mean is 0)";
        out += fmt::format("{:<15}{:.6g} (reference {:.6g}; ratio {})\n", fmt::format("mean {}:", channel_name(img.channels(), k)),
                           mi[k], mr[k], ratio);
    }
    out += fmt::format("MSE:           {:.6g} (mean of (x-r)^2 over pixels and channels)\n", mse(img, ref));
    out += fmt::format("relMSE:        {:.6g} (mean of (x-r)^2/(r^2+0.01) per channel; thesis errata)\n",
                       relmse(img, ref, RelMseOptions::thesis()));
    out += fmt::format("relMSE grey:   {:.6g} (mean of (x-r)^2/(mean_c(r)^2+0.001); neural convention)\n",
                       relmse(img, ref, RelMseOptions::neural()));
    out += fmt::format("MAE:           {:.6g} (mean of |x-r| over pixels and channels)\n", mae(img, ref));
    out += fmt::format("SSIM:          {:.6f} (Gaussian 11x11 sigma 1.5, per channel on linear values clamped to "
                       "[0,1], L=1)\n",
                       ssim(img, ref));
    out += fmt::format("SSIM sRGB:     {:.6f} (same, on sRGB-encoded clamped values)\n",
                       ssim(img, ref, SsimOptions{true}));
    return out;
}

Image box_downsample(const Image& img, int factor) {
    if (factor < 1) throw ParameterError("box_downsample: factor must be >= 1, got " + std::to_string(factor));
    if (img.empty()) throw ParameterError("box_downsample: image is empty");
    if (img.width() % factor != 0 || img.height() % factor != 0)
        throw ParameterError(fmt::format("box_downsample: {}x{} is not divisible by {} in both dimensions", img.width(),
                                         img.height(), factor));
    const int w = img.width() / factor, h = img.height() / factor, c = img.channels();
    Image out(w, h, c);
    // Double sums: a constant block comes out exact and the mean is kept to float rounding.
    std::vector<double> sum(size_t(c), 0.0);
    const double n = double(factor) * double(factor);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            std::fill(sum.begin(), sum.end(), 0.0);
            for (int dy = 0; dy < factor; ++dy)
                for (int dx = 0; dx < factor; ++dx)
                    for (int k = 0; k < c; ++k) sum[size_t(k)] += img.at(x * factor + dx, y * factor + dy, k);
            for (int k = 0; k < c; ++k) out.at(x, y, k) = float(sum[size_t(k)] / n);
        }
    return out;
}

}  // namespace gdr
