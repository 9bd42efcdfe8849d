// Pearson chi-square goodness-of-fit tests of sampling routines against their
// pdfs (in the spirit of Nori's chi2test and Mitsuba's chi2 module; written
// from the statistics, not from their code).
//
// spherical_chi2(): draws N directions from a sampler, histograms them over
// cells of (cos theta, phi), integrates the claimed solid-angle pdf over each
// cell (d omega = d cos theta d phi) and compares. The cell edges adapt to the
// distribution: they are quantiles of an independent pilot run (so sharp
// glossy lobes get many cells) merged with a coarse uniform grid (so no cell is
// so large that the pdf integration could miss a feature), with an edge at the
// horizon where reflection/transmission pdfs are discontinuous. Samples the
// routine rejects form one more cell whose expected share is 1 - integral(pdf),
// which also tests the pdf's normalisation. Cells with small expected counts
// are pooled. The significance of each test is Sidak-corrected so that the
// whole suite of at most kChi2SuiteTests tests has a family-wise false-failure
// rate of kChi2SuiteSignificance.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "gdr/core/math.h"
#include "gdr/core/sampler.h"

namespace gdr::test {

/// Family-wise significance of all chi-square tests of the suite together.
inline constexpr double kChi2SuiteSignificance = 0.01;
/// Upper bound on the number of chi-square tests in the whole test suite
/// (BSDFs, warps, lights, ...). Over-estimating keeps the family-wise rate
/// below kChi2SuiteSignificance; raise it when adding more tests.
inline constexpr int kChi2SuiteTests = 200;

/// Per-test significance with the Sidak correction: 1 - (1 - alpha)^(1/n).
inline double sidak_significance(double family_alpha, int num_tests) {
    return 1.0 - std::pow(1.0 - family_alpha, 1.0 / double(std::max(num_tests, 1)));
}

/// Per-test significance for this suite.
inline double suite_significance() { return sidak_significance(kChi2SuiteSignificance, kChi2SuiteTests); }

/// Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a),
/// the survival function of chi2(2a) at 2x. Series for x < a + 1, continued
/// fraction (modified Lentz) otherwise; both converge fast in their regions.
inline double gamma_q(double a, double x) {
    if (x <= 0.0) return 1.0;
    const double log_prefactor = a * std::log(x) - x - std::lgamma(a);
    if (x < a + 1.0) {
        double term = 1.0 / a, sum = term;
        for (int n = 1; n < 10000; ++n) {
            term *= x / (a + n);
            sum += term;
            if (std::abs(term) < std::abs(sum) * 1e-15) break;
        }
        return std::max(0.0, 1.0 - sum * std::exp(log_prefactor));
    }
    const double tiny = 1e-300;
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 10000; ++i) {
        const double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::abs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::abs(c) < tiny) c = tiny;
        d = 1.0 / d;
        const double delta = d * c;
        h *= delta;
        if (std::abs(delta - 1.0) < 1e-15) break;
    }
    return std::exp(log_prefactor) * h;
}

/// Outcome of one chi-square test.
struct Chi2Result {
    bool passed = false;       ///< p_value >= significance and no sample fell where the pdf is zero.
    double statistic = 0;      ///< Pearson's sum (O - E)^2 / E after pooling.
    int dof = 0;               ///< Degrees of freedom (pooled cells - 1).
    double p_value = 0;        ///< Probability of a statistic at least this large if the sampler matches the pdf.
    double significance = 0;   ///< Per-test threshold used.
    double pdf_integral = 0;   ///< Integral of the pdf over the domain (1 for a sampler that never rejects).
    int cells = 0;             ///< Cells before pooling.
    std::string message;       ///< Human-readable summary, including the worst cells on failure.
};

/// Chi-square test of observed counts against expected counts (same length).
/// Cells with expected < min_expected are pooled into one (and that pool into
/// the smallest regular cell if it is still too small). A cell with zero
/// expected count but observed samples fails outright: the sampler produced
/// values the pdf says are impossible.
inline Chi2Result chi2_from_counts(const std::vector<double>& observed, const std::vector<double>& expected,
                                   double significance, double min_expected = 5.0) {
    Chi2Result r;
    r.significance = significance;
    r.cells = int(observed.size());
    std::ostringstream msg;
    for (size_t i = 0; i < observed.size(); ++i)
        if (expected[i] <= 0.0 && observed[i] > 0.0) {
            msg << "cell " << i << " has " << observed[i] << " samples but the pdf integrates to 0 there";
            r.message = msg.str();
            return r;
        }
    std::vector<size_t> order(observed.size());
    std::iota(order.begin(), order.end(), size_t(0));
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return expected[a] < expected[b]; });
    double pool_o = 0, pool_e = 0;
    size_t first_regular = 0;
    while (first_regular < order.size() && expected[order[first_regular]] < min_expected) {
        pool_o += observed[order[first_regular]];
        pool_e += expected[order[first_regular]];
        ++first_regular;
    }
    if (pool_e < min_expected && first_regular < order.size()) {  // fold the small pool into a real cell
        pool_o += observed[order[first_regular]];
        pool_e += expected[order[first_regular]];
        ++first_regular;
    }
    struct Cell {
        double o, e, contrib;
        size_t index;
    };
    std::vector<Cell> cells;
    if (pool_e > 0.0) cells.push_back({pool_o, pool_e, sqr(pool_o - pool_e) / pool_e, size_t(-1)});
    for (size_t k = first_regular; k < order.size(); ++k) {
        const size_t i = order[k];
        cells.push_back({observed[i], expected[i], sqr(observed[i] - expected[i]) / expected[i], i});
    }
    for (const Cell& c : cells) r.statistic += c.contrib;
    r.dof = int(cells.size()) - 1;
    if (r.dof < 1) {
        msg << "too few cells with enough expected samples (" << cells.size() << ")";
        r.message = msg.str();
        return r;
    }
    r.p_value = gamma_q(0.5 * r.dof, 0.5 * r.statistic);
    r.passed = r.p_value >= significance;
    msg << "chi2 = " << r.statistic << ", dof = " << r.dof << ", p = " << r.p_value << " (threshold "
        << significance << ", " << r.cells << " cells)";
    if (!r.passed) {
        std::sort(cells.begin(), cells.end(), [](const Cell& a, const Cell& b) { return a.contrib > b.contrib; });
        msg << "; worst cells (index: observed vs expected):";
        for (size_t k = 0; k < std::min<size_t>(5, cells.size()); ++k)
            msg << " [" << (cells[k].index == size_t(-1) ? std::string("pool") : std::to_string(cells[k].index))
                << ": " << cells[k].o << " vs " << cells[k].e << "]";
    }
    r.message = msg.str();
    return r;
}

/// Adaptive Simpson quadrature of f on [a, b] to absolute tolerance eps
/// (relative tolerance rel to the whole-interval estimate), starting from
/// `panels` equal panels so narrow features are not skipped.
template <class F>
double adaptive_simpson(const F& f, double a, double b, double eps, double rel = 1e-6, int panels = 2,
                        int max_depth = 14) {
    struct Rec {
        const F& f;
        int max_depth;
        double step(double a, double fa, double m, double fm, double b, double fb, double whole, double eps,
                    int depth) const {
            const double lm = 0.5 * (a + m), rm = 0.5 * (m + b);
            const double flm = f(lm), frm = f(rm);
            const double left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
            const double right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
            const double delta = left + right - whole;
            if (depth >= max_depth || std::abs(delta) <= 15.0 * eps) return left + right + delta / 15.0;
            return step(a, fa, lm, flm, m, fm, left, 0.5 * eps, depth + 1) +
                   step(m, fm, rm, frm, b, fb, right, 0.5 * eps, depth + 1);
        }
    } rec{f, max_depth};
    double total = 0;
    const double h = (b - a) / panels;
    std::vector<double> pieces;
    for (int p = 0; p < panels; ++p) {
        const double x0 = a + p * h, x1 = (p + 1 == panels) ? b : a + (p + 1) * h, xm = 0.5 * (x0 + x1);
        const double f0 = f(x0), fm = f(xm), f1 = f(x1);
        const double whole = (x1 - x0) / 6.0 * (f0 + 4.0 * fm + f1);
        total += rec.step(x0, f0, xm, fm, x1, f1, whole, std::max(eps / panels, rel * std::abs(whole)), 0);
    }
    return total;
}

/// Settings of spherical_chi2.
struct SphericalChi2Options {
    int64_t samples = 500000;      ///< Directions histogrammed (1e5..1e6).
    int pilot_samples = 20000;     ///< Independent directions that place the adaptive cell edges.
    int cos_bins = 16;             ///< Adaptive cells along cos theta (split between the hemispheres that have samples).
    int phi_bins = 24;             ///< Adaptive cells along phi.
    int uniform_cos = 8;           ///< Coarse uniform edges along cos theta merged into the adaptive ones.
    int uniform_phi = 8;           ///< Coarse uniform edges along phi merged into the adaptive ones.
    uint64_t seed = 1;             ///< Seed of the sample streams (fixed: deterministic tests).
    double significance = suite_significance();  ///< Per-test threshold (Sidak-corrected).
    double min_expected = 5.0;     ///< Cells expecting fewer samples are pooled.
    int64_t max_pdf_evaluations = 5000000;   ///< Quadrature budget; exceeding it fails the test.
};

/// Direction on the unit sphere from (cos theta, phi).
inline Vec3 direction_from(double cos_theta, double phi) {
    const double s = std::sqrt(std::max(0.0, 1.0 - cos_theta * cos_theta));
    return Vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(cos_theta));
}

/// Chi-square test of a direction sampler against its solid-angle pdf.
/// sample(Sampler&) -> std::optional<Vec3> draws one unit direction (nullopt =
/// rejected sample); pdf(Vec3) -> density in 1/sr of producing that direction.
template <class SampleFn, class PdfFn>
Chi2Result spherical_chi2(SampleFn&& sample, PdfFn&& pdf, const SphericalChi2Options& opt = {}) {
    constexpr double two_pi = 2.0 * 3.14159265358979323846;
    auto coords = [&](const Vec3& w) {
        const double c = std::clamp(double(w.z), -1.0, 1.0);
        double phi = std::atan2(double(w.y), double(w.x));
        if (phi < 0.0) phi += two_pi;
        return std::pair<double, double>(c, std::min(phi, two_pi));
    };

    // 1. Cell edges from an independent pilot run (its own seed: the edges do
    //    not depend on the data the statistic is computed from).
    std::vector<double> up, down, phis;
    for (int i = 0; i < opt.pilot_samples; ++i) {
        Sampler s(SampleKey{opt.seed ^ 0x5eed5eed5eedull, 1u, 0u, uint32_t(i)});
        if (auto w = sample(s)) {
            const auto [c, phi] = coords(*w);
            (c >= 0.0 ? up : down).push_back(c);
            phis.push_back(phi);
        }
    }
    auto quantile_edges = [](std::vector<double> v, int bins, std::vector<double>& edges) {
        if (v.empty() || bins < 1) return;
        std::sort(v.begin(), v.end());
        for (int k = 1; k < bins; ++k) edges.push_back(v[std::min(v.size() - 1, size_t(double(k) / bins * v.size()))]);
    };
    std::vector<double> ce = {-1.0, 0.0, 1.0}, pe = {0.0, two_pi};
    const double n_pilot = double(up.size() + down.size());
    if (n_pilot > 0) {
        // Each hemisphere gets cells in proportion to its share, at least 2 if it has samples.
        const int bins_up = up.empty() ? 0 : std::max(2, int(std::lround(opt.cos_bins * up.size() / n_pilot)));
        const int bins_down = down.empty() ? 0 : std::max(2, int(std::lround(opt.cos_bins * down.size() / n_pilot)));
        quantile_edges(up, bins_up, ce);
        quantile_edges(down, bins_down, ce);
        quantile_edges(phis, opt.phi_bins, pe);
    }
    for (int k = 1; k < opt.uniform_cos; ++k) ce.push_back(-1.0 + 2.0 * k / opt.uniform_cos);
    for (int k = 1; k < opt.uniform_phi; ++k) pe.push_back(two_pi * k / opt.uniform_phi);
    auto tidy = [](std::vector<double>& e) {
        std::sort(e.begin(), e.end());
        std::vector<double> out;
        for (double x : e)
            if (out.empty() || x - out.back() > 1e-6) out.push_back(x);
        e.swap(out);
    };
    tidy(ce);
    tidy(pe);
    ce.front() = -1.0, ce.back() = 1.0, pe.front() = 0.0, pe.back() = two_pi;
    const size_t nc = ce.size() - 1, np = pe.size() - 1;

    // 2. Histogram; the last cell counts rejected samples.
    std::vector<double> observed(nc * np + 1, 0.0);
    std::string bad;
    for (int64_t i = 0; i < opt.samples; ++i) {
        Sampler s(SampleKey{opt.seed, 0u, uint32_t(i >> 32), uint32_t(i)});
        const std::optional<Vec3> w = sample(s);
        if (!w) {
            observed.back() += 1.0;
            continue;
        }
        const float len = glm::length(*w);
        if (!(std::abs(len - 1.f) < 1e-3f)) {
            if (bad.empty()) bad = "sample " + std::to_string(i) + " is not a unit vector (length " + std::to_string(len) + ")";
            continue;
        }
        const auto [c, phi] = coords(*w);
        const size_t ic = std::min<size_t>(nc - 1, size_t(std::upper_bound(ce.begin(), ce.end(), c) - ce.begin()) - 1);
        const size_t ip = std::min<size_t>(np - 1, size_t(std::upper_bound(pe.begin(), pe.end(), phi) - pe.begin()) - 1);
        observed[ic * np + ip] += 1.0;
    }
    if (!bad.empty()) {
        Chi2Result r;
        r.message = bad;
        return r;
    }

    // 3. Expected counts: the pdf integrated over each cell (nested adaptive Simpson).
    const double n = double(opt.samples);
    const double eps = 1e-3 / n;  // absolute error of a cell's probability: << one sample
    std::vector<double> expected(nc * np + 1, 0.0);
    double integral = 0.0;
    // A non-finite pdf fails the test; an evaluation budget bounds the time
    // quadrature can spend on a pdf too rough to converge.
    int64_t evaluations = 0;
    std::string pdf_error;
    auto density = [&](double c, double phi) -> double {
        if (!pdf_error.empty()) return 0.0;
        if (++evaluations > opt.max_pdf_evaluations) {
            pdf_error = "pdf quadrature did not converge within " + std::to_string(opt.max_pdf_evaluations) +
                        " evaluations (discontinuous or noisy pdf?)";
            return 0.0;
        }
        const Vec3 w = direction_from(c, phi);
        const double v = double(pdf(w));
        if (!std::isfinite(v) || v < 0.0) {
            std::ostringstream e;
            e << "pdf is " << v << " at (" << w.x << ", " << w.y << ", " << w.z << ")";
            pdf_error = e.str();
            return 0.0;
        }
        return v;
    };
    for (size_t ic = 0; ic < nc; ++ic)
        for (size_t ip = 0; ip < np; ++ip) {
            const double p0 = pe[ip], p1 = pe[ip + 1];
            auto over_phi = [&](double c) {
                return adaptive_simpson([&](double phi) { return density(c, phi); }, p0, p1, eps, 1e-6, 2, 12);
            };
            const double prob = adaptive_simpson(over_phi, ce[ic], ce[ic + 1], eps, 1e-6, 2, 12);
            expected[ic * np + ip] = prob * n;
            integral += prob;
        }
    expected.back() = std::max(0.0, 1.0 - integral) * n;

    if (!pdf_error.empty()) {
        Chi2Result r;
        r.message = pdf_error;
        return r;
    }
    Chi2Result r = chi2_from_counts(observed, expected, opt.significance, opt.min_expected);
    r.pdf_integral = integral;
    if (integral > 1.0 + 1e-3) {
        r.passed = false;
        r.message = "pdf integrates to " + std::to_string(integral) + " > 1; " + r.message;
    }
    return r;
}

}  // namespace gdr::test
