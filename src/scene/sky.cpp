#include "gdr/scene/sky.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <fmt/format.h>

#include "gdr/core/error.h"

namespace gdr {

namespace {

#include "sky_data/hosek_wilkie_rgb.inc"

const double* const kRGB[3] = {kHosekRGB1, kHosekRGB2, kHosekRGB3};
const double* const kRGBRad[3] = {kHosekRGBRad1, kHosekRGBRad2, kHosekRGBRad3};

constexpr double kPiD = 3.14159265358979323846;
// Integral of the CIE 1931 y-bar over wavelength (nm): Mitsuba's divisor of the model.
constexpr double kCieYIntegral = 106.856980;

// The paper's quintic Bezier in the cube root of the normalised solar
// elevation, over the six control points of one (albedo, turbidity) block of
// `stride` values, for value `k` of the block.
double bezier(const double* block, int stride, int k, double x) {
    const double w[6] = {std::pow(1 - x, 5),           5 * std::pow(1 - x, 4) * x, 10 * std::pow(1 - x, 3) * x * x,
                         10 * std::pow(1 - x, 2) * x * x * x, 5 * (1 - x) * std::pow(x, 4), std::pow(x, 5)};
    double s = 0.0;
    for (int i = 0; i < 6; ++i) s += w[i] * block[i * stride + k];
    return s;
}

// Bilinear blend in albedo and in (integer) turbidity of the Bezier value.
double cook(const double* data, int stride, int k, double turbidity, double albedo, double x) {
    const int t0 = std::clamp(int(turbidity), 1, 10);
    const double tr = std::clamp(turbidity - t0, 0.0, 1.0);
    const int t1 = std::min(t0 + 1, 10);
    const int block = 6 * stride;
    const auto at = [&](int alb, int t) { return bezier(data + (alb * 10 + (t - 1)) * block, stride, k, x); };
    return (1 - albedo) * ((1 - tr) * at(0, t0) + tr * at(0, t1)) + albedo * ((1 - tr) * at(1, t0) + tr * at(1, t1));
}

}  // namespace

HosekWilkieSky::HosekWilkieSky(double turbidity, const Color& albedo, double solar_elevation) {
    if (!(turbidity >= 1.0 && turbidity <= 10.0))
        throw ParameterError(fmt::format("sky: turbidity {} is outside the model's range [1, 10]", turbidity));
    for (int c = 0; c < 3; ++c)
        if (!(albedo[c] >= 0.f && albedo[c] <= 1.f))
            throw ParameterError(fmt::format("sky: albedo {} is outside [0, 1]", albedo[c]));
    const double e = std::clamp(solar_elevation, 0.0, kPiD / 2);
    const double x = std::cbrt(e / (kPiD / 2));
    for (int c = 0; c < 3; ++c) {
        for (int k = 0; k < 9; ++k) config_[c][k] = cook(kRGB[c], 9, k, turbidity, albedo[c], x);
        overall_[c] = cook(kRGBRad[c], 1, 0, turbidity, albedo[c], x);
    }
}

double HosekWilkieSky::radiance(int ch, double theta, double gamma) const {
    // F(theta, gamma) of the paper's equation (the extended Perez form):
    // (1 + A e^{B / (cos theta + 0.01)}) (C + D e^{E gamma} + F cos^2 gamma
    //   + G chi(H, gamma) + I sqrt(cos theta)), chi(g, a) = (1 + cos^2 a) / (1 + g^2 - 2 g cos a)^{3/2}.
    const auto& p = config_[ch];
    const double ct = std::cos(theta), cg = std::cos(gamma);
    const double chi = (1.0 + cg * cg) / std::pow(1.0 + p[8] * p[8] - 2.0 * p[8] * cg, 1.5);
    const double f = (1.0 + p[0] * std::exp(p[1] / (ct + 0.01))) *
                     (p[2] + p[3] * std::exp(p[4] * gamma) + p[5] * cg * cg + p[6] * chi + p[7] * std::sqrt(std::max(ct, 0.0)));
    return f * overall_[ch] / kCieYIntegral;
}

namespace {

// Extraterrestrial solar spectral radiance, 380..750 nm every 10 nm, from
// Preetham, Shirley and Smits (1999), W/(m^2 sr nm).
constexpr double kSolar[38] = {16559.0, 16233.7, 21127.5, 25888.2, 25829.1, 24232.3, 26760.5, 29658.3,
                               30545.4, 30057.5, 30663.7, 28830.4, 28712.1, 27825.0, 27100.6, 27233.6,
                               26361.3, 25503.8, 25060.2, 25311.6, 25355.9, 25134.2, 24631.5, 24173.2,
                               23685.3, 23212.1, 22827.7, 22339.8, 21970.2, 21526.7, 21097.9, 20728.3,
                               20240.4, 19870.8, 19427.2, 19072.4, 18628.9, 18259.2};

// Absorption coefficients (1/cm) of ozone and of water vapour against
// wavelength (nm), from M. Iqbal, "An Introduction to Solar Radiation" (1983),
// as Preetham, Shirley and Smits use them.
constexpr double kOzoneL[64] = {300, 305, 310, 315, 320, 325, 330, 335, 340, 345, 350, 355, 445, 450, 455, 460,
                                465, 470, 475, 480, 485, 490, 495, 500, 505, 510, 515, 520, 525, 530, 535, 540,
                                545, 550, 555, 560, 565, 570, 575, 580, 585, 590, 595, 600, 605, 610, 620, 630,
                                640, 650, 660, 670, 680, 690, 700, 710, 720, 730, 740, 750, 760, 770, 780, 790};
constexpr double kOzoneK[64] = {10.0, 4.8,  2.7,  1.35, .8,   .380, .160, .075, .04,  .019, .007, .0,   .003,
                                .003, .004, .006, .008, .009, .012, .014, .017, .021, .025, .03,  .035, .04,
                                .045, .048, .057, .063, .07,  .075, .08,  .085, .095, .103, .110, .12,  .122,
                                .12,  .118, .115, .12,  .125, .130, .12,  .105, .09,  .079, .067, .057, .048,
                                .036, .028, .023, .018, .014, .011, .010, .009, .007, .004, .0,   .0};
constexpr double kWaterL[13] = {689, 690, 700, 710, 720, 730, 740, 750, 760, 770, 780, 790, 800};
constexpr double kWaterK[13] = {0, 0.160e-1, 0.240e-1, 0.125e-1, 0.100e+1, 0.870, 0.610e-1,
                                0.100e-2, 0.100e-4, 0.100e-4, 0.600e-3, 0.175e-1, 0.360e-1};

// Linear interpolation in a table, zero outside it.
template <int N>
double table(const double (&x)[N], const double (&y)[N], double l) {
    if (l < x[0] || l > x[N - 1]) return 0.0;
    int i = 0;
    while (i + 2 < N && l > x[i + 1]) ++i;
    return y[i] + (l - x[i]) / (x[i + 1] - x[i]) * (y[i + 1] - y[i]);
}

// Piecewise Gaussian of the analytic CIE fit.
double g(double l, double mu, double s1, double s2) {
    const double t = (l - mu) / (l < mu ? s1 : s2);
    return std::exp(-0.5 * t * t);
}

}  // namespace

Color sun_radiance(double theta, double turbidity) {
    const double deg = theta * 180.0 / kPiD;
    if (deg >= 93.885) return Color(0.f);
    // Relative optical air mass (Kasten's formula, as Preetham et al. use it).
    const double m = 1.0 / (std::cos(theta) + 0.15 * std::pow(93.885 - deg, -1.253));
    const double beta = 0.04608365822050 * turbidity - 0.04586025928522;  // Angstrom turbidity
    double X = 0, Y = 0, Z = 0;
    for (int i = 0; i <= 370; ++i) {  // 380..750 nm at 1 nm, the spectrum interpolated linearly
        const double l = 380.0 + i, f = i / 10.0;
        const int k = std::min(int(f), 36);
        const double s = kSolar[k] + (f - k) * (kSolar[k + 1] - kSolar[k]);
        const double um = l / 1000.0;
        const double tau_r = std::exp(-m * 0.008735 * std::pow(um, -4.08));
        const double tau_a = std::exp(-m * beta * std::pow(um, -1.3));
        const double tau_o = std::exp(-m * table(kOzoneL, kOzoneK, l) * 0.35);  // 0.35 cm of ozone
        const double kwa = table(kWaterL, kWaterK, l) * 2.0 * m;                  // 2 cm of precipitable water
        const double tau_wa = std::exp(-0.2385 * kwa / std::pow(1.0 + 20.07 * kwa, 0.45));
        const double v = s * tau_r * tau_a * tau_o * tau_wa * (i == 0 || i == 370 ? 0.5 : 1.0);  // trapezoid weights
        X += v * (1.056 * g(l, 599.8, 37.9, 31.0) + 0.362 * g(l, 442.0, 16.0, 26.7) - 0.065 * g(l, 501.1, 20.4, 26.2));
        Y += v * (0.821 * g(l, 568.8, 46.9, 40.5) + 0.286 * g(l, 530.9, 16.3, 31.1));
        Z += v * (1.217 * g(l, 437.0, 11.8, 36.0) + 0.681 * g(l, 459.0, 26.0, 13.8));
    }
    X /= kCieYIntegral, Y /= kCieYIntegral, Z /= kCieYIntegral;
    const double r = 3.240479 * X - 1.537150 * Y - 0.498535 * Z;
    const double gg = -0.969256 * X + 1.875991 * Y + 0.041556 * Z;
    const double b = 0.055648 * X - 0.204043 * Y + 1.057311 * Z;
    return Color(float(std::max(r, 0.0)), float(std::max(gg, 0.0)), float(std::max(b, 0.0)));
}

namespace {

// The true sun direction, normalised; throws on a zero or non-finite one.
glm::dvec3 true_sun(const SkyParams& p) {
    const double len = glm::length(glm::dvec3(p.sun_dir));
    if (!(len > 0.0) || !std::isfinite(len)) throw ParameterError("sky: the sun direction must be a non-zero vector");
    return glm::dvec3(p.sun_dir) / len;
}

// A unit direction (+y up) of zenith angle theta and the azimuth of `like`
// (any direction not along the y axis; along it, azimuth 0, towards -z).
glm::dvec3 at_zenith(double theta, const glm::dvec3& like) {
    const double h = std::hypot(like.x, like.z);
    const double sx = h > 1e-12 ? like.x / h : 0.0, sz = h > 1e-12 ? like.z / h : -1.0;
    return {std::sin(theta) * sx, std::cos(theta), std::sin(theta) * sz};
}

// Hermite smoothstep of x over [0, 1].
double smoothstep01(double x) {
    const double t = std::clamp(x, 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

}  // namespace

Vec3 drawn_sun_direction(const SkyParams& p) {
    const glm::dvec3 sun = true_sun(p);
    const double theta = std::acos(std::clamp(sun.y, -1.0, 1.0));
    return Vec3(at_zenith(std::min(theta * double(p.stretch), kPiD), sun));
}

Color sun_irradiance(const SkyParams& p) {
    const double sun_theta = std::acos(std::clamp(true_sun(p).y, -1.0, 1.0));
    const double omega_sun = 2 * kPiD * (1 - std::cos(kSunAngularRadius));
    return sun_radiance(sun_theta, p.turbidity) * float(omega_sun) * p.sun_scale;
}

Image bake_sky(const SkyParams& p) {
    if (p.resolution < 4 || p.resolution % 2 != 0 || p.resolution > 16384)
        throw ParameterError(fmt::format("sky: resolution {} must be even and in [4, 16384]", p.resolution));
    if (!(p.sky_scale >= 0.f) || !(p.sun_scale >= 0.f) || !std::isfinite(p.sky_scale) || !std::isfinite(p.sun_scale))
        throw ParameterError("sky: the sky and sun scales must be finite and non-negative");
    if (!(p.sun_radius_scale >= 0.f) || !std::isfinite(p.sun_radius_scale))
        throw ParameterError(fmt::format("sky: sunRadiusScale {} must be >= 0 (0: a directional sun)", p.sun_radius_scale));
    if (!(p.stretch >= 1.f && p.stretch <= 2.f))
        throw ParameterError(fmt::format("sky: stretch {} must be in [1, 2]", p.stretch));
    const glm::dvec3 sun = true_sun(p);
    const double sun_theta = std::acos(std::clamp(sun.y, -1.0, 1.0));
    const int w = p.resolution, h = p.resolution / 2;
    Image map(w, h, 3, 0.f);
    const auto dir = [&](double u, double v) {  // the lat-long convention of environment.h
        const double th = kPiD * v, ph = 2 * kPiD * u;
        return glm::dvec3(std::sin(th) * std::sin(ph), std::cos(th), -std::sin(th) * std::cos(ph));
    };
    if (p.sky_scale > 0.f) {
        const HosekWilkieSky sky(p.turbidity, p.albedo, kPiD / 2 - sun_theta);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const glm::dvec3 d = dir((x + 0.5) / w, (y + 0.5) / h);
                const double theta = std::acos(std::clamp(d.y, -1.0, 1.0));
                // The model's zenith angle; at or below its horizon black, or
                // (extend) the radiance just above it.
                double model_theta = theta / p.stretch;
                if (std::cos(model_theta) <= 0.0) {
                    if (!p.extend) continue;
                    model_theta = kPiD / 2 - 1e-4;
                }
                const glm::dvec3 dm = at_zenith(model_theta, d);
                const double gamma = std::acos(std::clamp(glm::dot(dm, sun), -1.0, 1.0));
                const double fade = p.extend ? smoothstep01(2.0 - 2.0 * theta / kPiD) : 1.0;
                for (int c = 0; c < 3; ++c)
                    map.at(x, y, c) = float(std::max(0.0, sky.radiance(c, model_theta, gamma)) * fade * p.sky_scale);
            }
    }
    if (p.sun_scale > 0.f && p.sun_radius_scale > 0.f) {
        // The disk carries the true sun's radiance times its true solid angle,
        // spread evenly over a cone sunRadiusScale times wider, by stratified
        // samples of the cone each deposited over its texel's exact solid angle.
        const Color l_sun = sun_radiance(sun_theta, p.turbidity) * p.sun_scale;
        const glm::dvec3 drawn = glm::dvec3(drawn_sun_direction(p));
        const double omega_sun = 2 * kPiD * (1 - std::cos(kSunAngularRadius));
        const double cos_max = std::cos(std::min(kSunAngularRadius * p.sun_radius_scale, kPiD));
        const double covered = 0.5 * (1 - cos_max);
        const int n = std::max(32, int(std::ceil(std::sqrt(std::max(100.0, covered * 1000.0 * w * h)))));
        const glm::dvec3 t = std::abs(drawn.x) > 0.9 ? glm::dvec3(0, 1, 0) : glm::dvec3(1, 0, 0);
        const glm::dvec3 b1 = glm::normalize(glm::cross(drawn, t)), b2 = glm::cross(drawn, b1);
        const double per = omega_sun / (double(n) * n);
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < n; ++j) {
                const double ct = 1 - (i + 0.5) / n * (1 - cos_max), st = std::sqrt(std::max(0.0, 1 - ct * ct));
                const double ph = 2 * kPiD * (j + 0.5) / n;
                const glm::dvec3 d = drawn * ct + (b1 * std::cos(ph) + b2 * std::sin(ph)) * st;
                double u = std::atan2(d.x, -d.z) / (2 * kPiD);
                if (u < 0) u += 1;
                const double v = std::acos(std::clamp(d.y, -1.0, 1.0)) / kPiD;
                const int x = std::min(int(u * w), w - 1), y = std::min(int(v * h), h - 1);
                const double texel_sa = 2 * kPiD / w * (std::cos(kPiD * y / h) - std::cos(kPiD * (y + 1) / h));
                for (int c = 0; c < 3; ++c) map.at(x, y, c) += float(l_sun[c] * per / texel_sa);
            }
    }
    return map;
}

Vec3 sun_direction_at(int year, int month, int day, double hour, double minute, double second, double latitude,
                      double longitude, double timezone) {
    // Universal time in decimal hours, and days since JD 2451545.0 (noon, 1 January 2000).
    const double ut = hour - timezone + (minute + second / 60.0) / 60.0;
    const long a1 = (month - 14) / 12;
    const long jdn = (1461L * (year + 4800 + a1)) / 4 + (367L * (month - 2 - 12 * a1)) / 12 -
                     (3L * ((year + 4900 + a1) / 100)) / 4 + day - 32075;
    const double n = double(jdn) - 0.5 + ut / 24.0 - 2451545.0;
    // Ecliptic coordinates.
    const double omega = 2.1429 - 0.0010394594 * n;
    const double mean_lon = 4.8950630 + 0.017202791698 * n;
    const double anomaly = 6.2400600 + 0.0172019699 * n;
    const double ecl_lon = mean_lon + 0.03341607 * std::sin(anomaly) + 0.00034894 * std::sin(2 * anomaly) - 0.0001134 -
                           0.0000203 * std::sin(omega);
    const double ecl_obl = 0.4090928 - 6.2140e-9 * n + 0.0000396 * std::cos(omega);
    // Celestial coordinates.
    double ra = std::atan2(std::cos(ecl_obl) * std::sin(ecl_lon), std::cos(ecl_lon));
    if (ra < 0) ra += 2 * kPiD;
    const double dec = std::asin(std::sin(ecl_obl) * std::sin(ecl_lon));
    // Local coordinates.
    const double gmst = 6.6974243242 + 0.0657098283 * n + ut;
    const double lmst = (gmst * 15 + longitude) * kPiD / 180.0;
    const double lat = latitude * kPiD / 180.0;
    const double ha = lmst - ra;
    double zenith = std::acos(std::clamp(std::cos(lat) * std::cos(ha) * std::cos(dec) + std::sin(dec) * std::sin(lat), -1.0, 1.0));
    double azimuth = std::atan2(-std::sin(ha), std::tan(dec) * std::cos(lat) - std::sin(lat) * std::cos(ha));
    if (azimuth < 0) azimuth += 2 * kPiD;
    zenith += (6371.01 / 149597890.0) * std::sin(zenith);  // parallax: earth mean radius over one AU
    return Vec3(float(std::sin(azimuth) * std::sin(zenith)), float(std::cos(zenith)),
                float(-std::cos(azimuth) * std::sin(zenith)));
}

}  // namespace gdr
