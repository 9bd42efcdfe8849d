#include "gdr/eval/plot.h"

#include <stb/stb_easy_font.h>
#include <stb/stb_image_write.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>

#include "gdr/core/error.h"
#include "gdr/io/png.h"

namespace gdr::eval {

Canvas::Canvas(int width, int height, Rgb8 bg) : w_(width), h_(height) {
    if (width < 0 || height < 0) throw ParameterError("Canvas: negative size");
    px_.resize(size_t(width) * height * 3);
    for (size_t i = 0; i < px_.size(); i += 3) px_[i] = bg.r, px_[i + 1] = bg.g, px_[i + 2] = bg.b;
}

void Canvas::set(int x, int y, Rgb8 c) {
    if (x < 0 || y < 0 || x >= w_ || y >= h_) return;
    uint8_t* p = &px_[(size_t(y) * w_ + x) * 3];
    p[0] = c.r, p[1] = c.g, p[2] = c.b;
}

Rgb8 Canvas::get(int x, int y) const {
    const uint8_t* p = &px_[(size_t(y) * w_ + x) * 3];
    return {p[0], p[1], p[2]};
}

void Canvas::fill_rect(int x0, int y0, int x1, int y1, Rgb8 c) {
    x0 = std::max(x0, 0), y0 = std::max(y0, 0), x1 = std::min(x1, w_), y1 = std::min(y1, h_);
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) set(x, y, c);
}

void Canvas::line(double x0, double y0, double x1, double y1, Rgb8 c, int thickness, int dash) {
    const double len = std::hypot(x1 - x0, y1 - y0);
    const int steps = std::max(1, int(std::ceil(len * 2)));
    const int lo = -(thickness - 1) / 2, hi = thickness / 2;
    for (int i = 0; i <= steps; ++i) {
        const double t = double(i) / steps;
        if (dash > 0 && int(t * len / dash) % 2 == 1) continue;
        const int x = int(std::lround(x0 + t * (x1 - x0))), y = int(std::lround(y0 + t * (y1 - y0)));
        for (int dy = lo; dy <= hi; ++dy)
            for (int dx = lo; dx <= hi; ++dx) set(x + dx, y + dy, c);
    }
}

namespace {
// stb_easy_font emits axis-aligned quads: 4 vertices of (x, y, z float, rgba bytes).
struct FontVertex {
    float x, y, z;
    unsigned char rgba[4];
};
}  // namespace

void Canvas::text(int x, int y, const std::string& s, Rgb8 c, int scale) {
    std::vector<char> buf(s.begin(), s.end());
    buf.push_back('\0');
    static thread_local std::vector<FontVertex> verts(4 * 4096);
    const int quads = stb_easy_font_print(0.f, 0.f, buf.data(), nullptr, verts.data(), int(verts.size() * sizeof(FontVertex)));
    for (int q = 0; q < quads; ++q) {
        const FontVertex* v = &verts[size_t(q) * 4];
        float xmin = v[0].x, xmax = v[0].x, ymin = v[0].y, ymax = v[0].y;
        for (int k = 1; k < 4; ++k)
            xmin = std::min(xmin, v[k].x), xmax = std::max(xmax, v[k].x), ymin = std::min(ymin, v[k].y),
            ymax = std::max(ymax, v[k].y);
        fill_rect(x + int(xmin) * scale, y + int(ymin) * scale, x + int(xmax) * scale, y + int(ymax) * scale, c);
    }
}

int Canvas::text_width(const std::string& s, int scale) {
    std::vector<char> buf(s.begin(), s.end());
    buf.push_back('\0');
    return stb_easy_font_width(buf.data()) * scale;
}

int Canvas::text_height(int scale) { return 10 * scale; }

void Canvas::blit(const Canvas& src, int x, int y) {
    for (int j = 0; j < src.h_; ++j)
        for (int i = 0; i < src.w_; ++i) set(x + i, y + j, src.get(i, j));
}

void Canvas::write_png(const std::string& path) const {
    const std::filesystem::path p(path);
    if (p.has_parent_path()) std::filesystem::create_directories(p.parent_path());
    if (!stbi_write_png(path.c_str(), w_, h_, 3, px_.data(), w_ * 3))
        throw RuntimeFailure(path + ": cannot write PNG");
}

Canvas tonemap(const Image& img, float scale) {
    Canvas c(img.width(), img.height());
    auto enc = [&](float v) {
        const float s = linear_to_srgb(std::clamp(v * scale, 0.f, 1.f));
        return uint8_t(std::lround(s * 255.f));
    };
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x) {
            const Color v = img.rgb(x, y);
            c.set(x, y, {enc(v.r), enc(v.g), enc(v.b)});
        }
    return c;
}

float auto_exposure(const Image& img, double percentile) {
    std::vector<float> lum;
    lum.reserve(img.pixel_count());
    for (int y = 0; y < img.height(); ++y)
        for (int x = 0; x < img.width(); ++x) {
            const Color v = img.rgb(x, y);
            lum.push_back(0.2126f * v.r + 0.7152f * v.g + 0.0722f * v.b);
        }
    if (lum.empty()) return 1.f;
    const size_t k = std::min(lum.size() - 1, size_t(percentile * double(lum.size())));
    std::nth_element(lum.begin(), lum.begin() + long(k), lum.end());
    return lum[k] > 0.f ? 1.f / lum[k] : 1.f;
}

namespace {

// Tick label: plain for moderate magnitudes, else mantissa e exponent.
std::string tick_label(double v) {
    char b[32];
    const double a = std::abs(v);
    if (a >= 0.01 && a < 10000) std::snprintf(b, sizeof b, "%g", v);
    else {
        const int e = int(std::floor(std::log10(a) + 1e-9));
        const double m = v / std::pow(10.0, e);
        if (std::abs(m - 1.0) < 1e-6) std::snprintf(b, sizeof b, "1e%d", e);
        else std::snprintf(b, sizeof b, "%ge%d", std::round(m * 10) / 10, e);
    }
    return b;
}

// Ticks at 1, 2, 5 x 10^k (or only decades when the range spans many).
std::vector<double> log_ticks(double lo, double hi) {
    std::vector<double> t;
    const bool dense = std::log10(hi / lo) < 2.5;
    for (int e = int(std::floor(std::log10(lo))) - 1; e <= int(std::ceil(std::log10(hi))) + 1; ++e)
        for (double m : {1.0, 2.0, 5.0}) {
            if (!dense && m != 1.0) continue;
            const double v = m * std::pow(10.0, e);
            if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) t.push_back(v);
        }
    return t;
}

}  // namespace

Canvas draw_loglog(const LogLogPlot& plot, int W, int H) {
    Canvas c(W, H);
    const Rgb8 black{0, 0, 0}, grid{225, 225, 225}, grey{140, 140, 140};
    double xlo = std::numeric_limits<double>::infinity(), xhi = 0, ylo = xlo, yhi = 0;
    for (const Series& s : plot.series)
        for (const CurvePoint& p : s.points)
            if (p.seconds > 0 && p.error > 0)
                xlo = std::min(xlo, p.seconds), xhi = std::max(xhi, p.seconds), ylo = std::min(ylo, p.error),
                yhi = std::max(yhi, p.error);
    if (plot.hline > 0) ylo = std::min(ylo, plot.hline), yhi = std::max(yhi, plot.hline);
    if (!(xhi > 0)) xlo = 1, xhi = 10, ylo = 1, yhi = 10;
    // Pad by a fraction of the log range so end points do not sit on the frame.
    auto pad = [](double& lo, double& hi) {
        double l = std::log10(lo), h = std::log10(hi);
        if (h - l < 0.3) l -= 0.15, h += 0.15;
        const double m = 0.06 * (h - l);
        lo = std::pow(10.0, l - m), hi = std::pow(10.0, h + m);
    };
    pad(xlo, xhi);
    pad(ylo, yhi);
    const int L = 70, R = W - 20, T = 52, B = H - 50;
    auto X = [&](double v) { return L + (std::log10(v) - std::log10(xlo)) / (std::log10(xhi) - std::log10(xlo)) * (R - L); };
    auto Y = [&](double v) { return B - (std::log10(v) - std::log10(ylo)) / (std::log10(yhi) - std::log10(ylo)) * (B - T); };
    std::vector<double> xt = log_ticks(xlo, xhi);
    if (!plot.xticks.empty()) {
        xt.clear();
        for (double t : plot.xticks)
            if (t >= xlo && t <= xhi) xt.push_back(t);
    }
    for (double t : xt) {
        const int x = int(std::lround(X(t)));
        c.line(x, T, x, B, grid);
        c.line(x, B, x, B + 4, black);
        const std::string s = tick_label(t);
        c.text(x - Canvas::text_width(s) / 2, B + 7, s, black);
    }
    for (double t : log_ticks(ylo, yhi)) {
        const int y = int(std::lround(Y(t)));
        c.line(L, y, R, y, grid);
        c.line(L - 4, y, L, y, black);
        const std::string s = tick_label(t);
        c.text(L - 7 - Canvas::text_width(s), y - 4, s, black);
    }
    if (plot.hline > 0) {
        const double y = Y(plot.hline);
        c.line(L, y, R, y, grey, 1, 4);
        if (!plot.hline_label.empty()) c.text(L + 6, int(y) + 3, plot.hline_label, grey);
    }
    c.line(L, T, L, B, black);
    c.line(L, B, R, B, black);
    c.line(R, T, R, B, black);
    c.line(L, T, R, T, black);
    for (const Series& s : plot.series) {
        std::vector<CurvePoint> p;
        for (const CurvePoint& q : s.points)
            if (q.seconds > 0 && q.error > 0) p.push_back(q);
        std::sort(p.begin(), p.end(), [](const CurvePoint& a, const CurvePoint& b) { return a.seconds < b.seconds; });
        for (size_t i = 1; i < p.size(); ++i)
            c.line(X(p[i - 1].seconds), Y(p[i - 1].error), X(p[i].seconds), Y(p[i].error), s.color, 2, s.dashed ? 6 : 0);
        for (const CurvePoint& q : p) {
            const int x = int(std::lround(X(q.seconds))), y = int(std::lround(Y(q.error)));
            c.fill_rect(x - 3, y - 3, x + 4, y + 4, s.color);
        }
    }
    // Legend at the top right, inside the frame (curves fall to the lower right).
    int ly = T + 8;
    int lw = 0;
    for (const Series& s : plot.series) lw = std::max(lw, Canvas::text_width(s.label));
    const int lx = R - lw - 46;
    c.fill_rect(lx - 6, ly - 5, R - 6, ly + int(plot.series.size()) * 16 + 1, {255, 255, 255});
    for (const Series& s : plot.series) {
        c.line(lx, ly + 4, lx + 28, ly + 4, s.color, 2, s.dashed ? 6 : 0);
        c.text(lx + 34, ly, s.label, black);
        ly += 16;
    }
    c.text(L, 8, plot.title, black, 2);
    c.text((L + R) / 2 - Canvas::text_width(plot.xlabel) / 2, H - 20, plot.xlabel, black);
    // No rotated text in this font: the y label sits above the axis.
    c.text(std::max(2, L - Canvas::text_width(plot.ylabel) / 2), T - 14, plot.ylabel, black);
    return c;
}

}  // namespace gdr::eval
