#include "gdr/scene/environment.h"

#include <algorithm>
#include <cmath>

#include <glm/matrix.hpp>

#include "gdr/core/error.h"
#include "gdr/scene/warp.h"

namespace gdr {

namespace {

constexpr double kPiD = 3.14159265358979323846;

// Index i with cdf[i] <= x < cdf[i + 1] among the n cells of a cdf of n + 1
// entries (cdf[0] = 0, cdf[n] = 1), skipping cells of zero width.
int find_cell(const double* cdf, int n, double x) {
    const double* it = std::upper_bound(cdf, cdf + n + 1, x);
    int i = int(it - cdf) - 1;
    i = std::clamp(i, 0, n - 1);
    // upper_bound lands after runs of equal entries, so a zero-width cell
    // (a black texel) is never chosen unless x is exactly 1 at the end.
    while (i > 0 && !(cdf[i + 1] > cdf[i])) --i;
    return i;
}

}  // namespace

std::shared_ptr<Environment> Environment::constant(const Color& radiance) {
    if (!is_finite(radiance) || radiance.r < 0.f || radiance.g < 0.f || radiance.b < 0.f)
        throw InputError("constant environment: radiance must be finite and non-negative");
    std::shared_ptr<Environment> e(new Environment());
    e->constant_ = radiance;
    e->luminance_integral_ = 4.0 * kPiD * double(luminance(radiance));
    return e;
}

std::shared_ptr<Environment> Environment::from_map(const Image& map, const glm::mat3& to_world, float scale,
                                                   const std::string& origin) {
    if (map.width() < 1 || map.height() < 1) throw InputError(origin + ": the environment map is empty");
    if (!std::isfinite(scale) || !(scale >= 0.f))
        throw InputError(origin + ": the environment's scale must be finite and non-negative");
    // A direction's density must not change under to_world: only rotations
    // (and reflections) keep solid angle.
    const glm::mat3 mtm = glm::transpose(to_world) * to_world;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            if (!(std::abs(mtm[i][j] - (i == j ? 1.f : 0.f)) < 1e-3f))
                throw InputError(origin + ": the environment's to_world must be a rotation (orthonormal), not a "
                                          "scale or shear");
    std::shared_ptr<Environment> e(new Environment());
    const int w = map.width(), h = map.height();
    e->map_ = Image(w, h, 3);
    e->to_world_ = to_world;
    e->to_local_ = glm::transpose(to_world);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const Color c = map.rgb(x, y) * scale;
            if (!is_finite(c) || c.r < 0.f || c.g < 0.f || c.b < 0.f)
                throw InputError(origin + ": environment map texel (" + std::to_string(x) + ", " + std::to_string(y) +
                                 ") is negative or not finite");
            e->map_.set_rgb(x, y, c);
        }
    e->weight_.resize(size_t(w) * h);
    e->row_cdf_.assign(size_t(h) + 1, 0.0);
    e->col_cdf_.assign(size_t(h) * (w + 1), 0.0);
    // The integral of the bilinear interpolant over one cell, per axis: a
    // texel's value weighs 3/4, each neighbour's 1/8 (u wraps, v clamps,
    // as lookup() does). A cell where the radiance is anywhere non-zero
    // thus has a non-zero weight, so sampling covers every direction that
    // carries light.
    constexpr double k[3] = {0.125, 0.75, 0.125};
    double lum_int = 0.0;
    for (int y = 0; y < h; ++y) {
        const double th0 = kPiD * y / h, th1 = kPiD * (y + 1) / h;
        // Weight by sin(theta) of the row centre: the solid angle of a cell
        // of the (u, v) square is proportional to it.
        const double sin_c = std::sin(0.5 * (th0 + th1));
        const double cell_sr = 2.0 * kPiD / w * (std::cos(th0) - std::cos(th1));
        double* cdf = &e->col_cdf_[size_t(y) * (w + 1)];
        double row = 0.0;
        for (int x = 0; x < w; ++x) {
            double lum = 0.0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int sx = (x + dx + w) % w, sy = std::clamp(y + dy, 0, h - 1);
                    lum += k[dx + 1] * k[dy + 1] * std::max(0.0, double(luminance(e->map_.rgb(sx, sy))));
                }
            lum_int += lum * cell_sr;
            const double wt = lum * sin_c;
            e->weight_[size_t(y) * w + x] = float(wt);
            row += wt;
            cdf[x + 1] = row;
        }
        for (int x = 1; x <= w; ++x) cdf[x] = row > 0.0 ? cdf[x] / row : double(x) / w;
        e->row_cdf_[y + 1] = e->row_cdf_[y] + row;
    }
    e->weight_sum_ = e->row_cdf_[h];
    if (!(e->weight_sum_ > 0.0)) throw InputError(origin + ": the environment map is black (it emits nothing)");
    for (int y = 1; y <= h; ++y) e->row_cdf_[y] /= e->weight_sum_;
    e->row_cdf_[h] = 1.0;
    e->luminance_integral_ = lum_int;
    return e;
}

Vec2 Environment::direction_to_uv(const Vec3& w) const {
    const Vec3 d = to_local_ * w;
    float u = std::atan2(d.x, -d.z) * (0.5f * kInvPi);
    if (u < 0.f) u += 1.f;
    const float v = std::acos(std::clamp(d.y, -1.f, 1.f)) * kInvPi;
    return {std::min(u, std::nextafter(1.f, 0.f)), v};
}

Vec3 Environment::uv_to_direction(const Vec2& uv) const {
    const float phi = 2.f * kPi * uv.x, theta = kPi * uv.y;
    const float st = std::sin(theta);
    const Vec3 d(st * std::sin(phi), std::cos(theta), -st * std::cos(phi));
    return glm::normalize(to_world_ * d);
}

int Environment::texel(const Vec2& uv, int& x, int& y) const {
    x = std::clamp(int(uv.x * float(map_.width())), 0, map_.width() - 1);
    y = std::clamp(int(uv.y * float(map_.height())), 0, map_.height() - 1);
    return y * map_.width() + x;
}

Color Environment::lookup(const Vec2& uv) const {
    const int w = map_.width(), h = map_.height();
    // Texel (x, y) is the value at its centre ((x + 0.5) / W, (y + 0.5) / H).
    const float fx = uv.x * float(w) - 0.5f, fy = uv.y * float(h) - 0.5f;
    const float x0f = std::floor(fx), y0f = std::floor(fy);
    const float tx = fx - x0f, ty = fy - y0f;
    const int x0 = ((int(x0f) % w) + w) % w, x1 = (x0 + 1) % w;
    const int y0 = std::clamp(int(y0f), 0, h - 1), y1 = std::clamp(int(y0f) + 1, 0, h - 1);
    // As a + (b - a) t: where neighbouring texels are equal the value is theirs exactly.
    const Color top = map_.rgb(x0, y0) + (map_.rgb(x1, y0) - map_.rgb(x0, y0)) * tx;
    const Color bottom = map_.rgb(x0, y1) + (map_.rgb(x1, y1) - map_.rgb(x0, y1)) * tx;
    return glm::max(top + (bottom - top) * ty, Color(0.f));
}

Color Environment::eval(const Vec3& w) const {
    if (map_.empty()) return constant_;
    return lookup(direction_to_uv(w));
}

float Environment::pdf(const Vec3& w) const {
    if (map_.empty()) return warp::uniform_sphere_pdf();
    const Vec3 d = to_local_ * w;
    const float sin_theta = std::sqrt(d.x * d.x + d.z * d.z);
    if (!(sin_theta > 0.f)) return 0.f;
    int x, y;
    const int i = texel(direction_to_uv(w), x, y);
    // Density in (u, v) is weight / mean weight; d omega = 2 pi^2 sin(theta) du dv.
    const double p_uv = double(weight_[i]) * double(map_.width()) * double(map_.height()) / weight_sum_;
    return float(p_uv / (2.0 * kPiD * kPiD * double(sin_theta)));
}

EnvironmentSample Environment::sample(const Vec2& u) const {
    EnvironmentSample s;
    if (map_.empty()) {
        s.wi = warp::square_to_uniform_sphere(u);
        s.radiance = constant_;
        s.pdf_w = warp::uniform_sphere_pdf();
        return s;
    }
    const int w = map_.width(), h = map_.height();
    const int y = find_cell(row_cdf_.data(), h, double(u.y));
    const double r0 = row_cdf_[y], r1 = row_cdf_[y + 1];
    const double fy = r1 > r0 ? (double(u.y) - r0) / (r1 - r0) : 0.5;
    const double* cdf = &col_cdf_[size_t(y) * (w + 1)];
    const int x = find_cell(cdf, w, double(u.x));
    const double c0 = cdf[x], c1 = cdf[x + 1];
    const double fx = c1 > c0 ? (double(u.x) - c0) / (c1 - c0) : 0.5;
    // Keep the point inside its texel despite rounding, so that eval() and
    // pdf() of the direction find this same texel.
    const float uu = std::clamp(float((x + std::clamp(fx, 0.0, 1.0)) / w), (x + 1e-4f) / w, (x + 1.f - 1e-4f) / w);
    const float vv = std::clamp(float((y + std::clamp(fy, 0.0, 1.0)) / h), (y + 1e-4f) / h, (y + 1.f - 1e-4f) / h);
    s.wi = uv_to_direction(Vec2(uu, vv));
    s.radiance = eval(s.wi);  // exactly what eval() gives the direction (not the rounded (uu, vv))
    const double p_uv = double(weight_[size_t(y) * w + x]) * double(w) * double(h) / weight_sum_;
    const float sin_theta = std::sin(kPi * vv);
    s.pdf_w = sin_theta > 0.f ? float(p_uv / (2.0 * kPiD * kPiD * double(sin_theta))) : 0.f;
    return s;
}

}  // namespace gdr
