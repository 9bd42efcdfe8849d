// Mitsuba's sky, sun and sunsky emitters: the Hosek-Wilkie model against the
// paper's formula evaluated here by hand from the published coefficients, the
// baked map's irradiance against resolution and against the sun's analytic
// power, where sunDirection puts the sun, and the solar position algorithm.
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>

#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/io/scene_file.h"
#include "gdr/scene/environment.h"
#include "gdr/scene/sky.h"

using namespace gdr;
using namespace gdr::test;

namespace {

constexpr double kPiD = 3.14159265358979323846;

// Irradiance (scene units) on a plane facing +y from the map's texels above
// the horizon: sum of radiance times cos(theta) times the texel's solid angle.
Color horizontal_irradiance(const Image& m) {
    const int w = m.width(), h = m.height();
    glm::dvec3 e(0.0);
    for (int y = 0; y < h / 2; ++y) {
        const double t0 = kPiD * y / h, t1 = kPiD * (y + 1) / h;
        // Exact integral of cos(theta) sin(theta) over the row, times the column width.
        const double w_cos = 2 * kPiD / w * 0.5 * (std::sin(t1) * std::sin(t1) - std::sin(t0) * std::sin(t0));
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) e[c] += m.at(x, y, c) * w_cos;
    }
    return Color(e);
}

}  // namespace

TEST_CASE("sky: the Hosek-Wilkie model matches the paper's formula by hand", "[sky]") {
    // Turbidity 3, albedo 0, the sun at the zenith: the Bezier in elevation is
    // its last control point, so the red channel's nine parameters are the
    // published row (albedo 0, turbidity 3, control point 6) as is:
    // A B C D E F G I H, and its overall radiance L_M = 5.907387.
    const double A = -1.073560, B = -2.077964e-1, C = 1.492052, D = 1.626322e1, E = -5.015304, F = -4.059889e-1,
                 G = 2.659782e-1, I = 6.395380e-1, H = 5.634436e-1, LM = 5.907387;
    const auto by_hand = [&](double theta, double gamma) {
        const double chi = (1 + std::cos(gamma) * std::cos(gamma)) / std::pow(1 + H * H - 2 * H * std::cos(gamma), 1.5);
        return (1 + A * std::exp(B / (std::cos(theta) + 0.01))) *
               (C + D * std::exp(E * gamma) + F * std::cos(gamma) * std::cos(gamma) + G * chi + I * std::sqrt(std::cos(theta))) *
               LM / 106.856980;
    };
    const HosekWilkieSky sky(3.0, Color(0.f), kPiD / 2);
    // The zenith (looking at the sun) and 85 degrees down, near the horizon.
    // Wrong variant: H in place of I as the zenith term's coefficient in
    // radiance() gave 0.169409 for 0.169940 at the zenith, 0.090012 for 0.091097 at 85 degrees.
    for (const double theta : {0.0, 85.0 * kPiD / 180}) {
        CAPTURE(theta, sky.radiance(0, theta, theta), by_hand(theta, theta));
        CHECK(sky.radiance(0, theta, theta) == Approx(by_hand(theta, theta)).epsilon(1e-9));
    }
    // Inside the elevation range (x = cbrt(e / (pi/2)) = 1/2) and between
    // turbidities 3 and 4: parameter A is the mean of the two quintic Beziers
    // over the published control points.
    const double a3[6] = {-1.135338, -1.132780, -1.167176, -1.042529, -1.061598, -1.073560};
    const double a4[6] = {-1.172794, -1.238374, -1.176923, -1.003284, -1.060017, -1.081141};
    const double w[6] = {1, 5, 10, 10, 5, 1};
    double bz3 = 0, bz4 = 0;
    for (int i = 0; i < 6; ++i) {
        const double b = w[i] * std::pow(0.5, 5);
        bz3 += b * a3[i];
        bz4 += b * a4[i];
    }
    // Wrong variant: the Bezier in e / (pi/2) without the cube root gave A = -1.165430 for -1.106653.
    const HosekWilkieSky mid(3.5, Color(0.f), kPiD / 2 * 0.125);
    CHECK(mid.params(0)[0] == Approx(0.5 * (bz3 + bz4)).epsilon(1e-9));
    CHECK_THROWS_AS(HosekWilkieSky(11.0, Color(0.f), 0.5), ParameterError);
    CHECK_THROWS_AS(HosekWilkieSky(3.0, Color(1.5f), 0.5), ParameterError);
}

TEST_CASE("sky: the baked map's irradiance is stable to resolution and the sun carries its power", "[sky]") {
    SkyParams p;
    p.turbidity = 3.0;
    p.sun_dir = glm::normalize(Vec3(0.88698f, 0.288862f, 0.360313f));
    p.sun_scale = 0.f;
    p.resolution = 256;
    const Color sky256 = horizontal_irradiance(bake_sky(p));
    p.resolution = 512;
    const Color sky512 = horizontal_irradiance(bake_sky(p));
    CAPTURE(sky256.r, sky256.g, sky256.b, sky512.r, sky512.g, sky512.b);
    for (int c = 0; c < 3; ++c) CHECK(sky256[c] == Approx(sky512[c]).epsilon(0.01));
    CHECK(sky512.b > sky512.r);  // a blue sky
    // The sun alone: its irradiance is the true sun's radiance times its solid
    // angle times cos(theta), whatever the disk's scale and the resolution.
    // Wrong variant: dividing each sample by a texel of a fixed 512-wide map
    // made the 256-wide map's sun 1.977 times its analytic irradiance (0.988 right).
    p.sky_scale = 0.f;
    p.sun_scale = 1.f;
    const Color l_sun = sun_radiance(std::acos(double(p.sun_dir.y)), p.turbidity);
    const double omega = 2 * kPiD * (1 - std::cos(kSunAngularRadius));
    for (const int res : {256, 512})
        for (const float radius : {1.f, 4.f, 18.8f}) {
            p.resolution = res;
            p.sun_radius_scale = radius;
            const Color e = horizontal_irradiance(bake_sky(p));
            CAPTURE(res, radius, e.r, l_sun.r * omega * p.sun_dir.y);
            for (int c = 0; c < 3; ++c) CHECK(e[c] == Approx(l_sun[c] * omega * p.sun_dir.y).epsilon(0.02));
        }
    // The sun is whiter than the sky and reddens towards the horizon.
    const Color high = sun_radiance(0.2, 3.0), low = sun_radiance(1.5, 3.0);
    CHECK(high.b / high.r > low.b / low.r);
    CHECK(sun_radiance(1.7, 3.0) == Color(0.f));  // below the horizon's air mass
}

TEST_CASE("sky: Mitsuba's sunsky puts the sun at sunDirection, in world space", "[sky][mitsuba]") {
    OutDir dir("sky");
    const auto scene = [&](const std::string& emitter) {
        std::ofstream(dir("scene.xml")) << R"(<scene version="0.6.0"><sensor type="perspective"><float name="fov" value="40"/>
          <transform name="toWorld"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
          <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
          <shape type="rectangle"/>)" << emitter
                                        << "</scene>\n";
        return dir("scene.xml");
    };
    const Vec3 sun = glm::normalize(Vec3(0.6f, 0.5f, -0.62f));
    // A quarter turn about y as toWorld: sunDirection is a world direction all the same.
    const SceneFile sf = load_scene_file(scene(R"(<emitter type="sunsky">
        <transform name="toWorld"><rotate y="1" angle="90"/></transform>
        <vector name="sunDirection" x="0.6" y="0.5" z="-0.62"/><float name="sunRadiusScale" value="4"/></emitter>)"));
    const Environment& env = *sf.scene->environment();
    const float at_sun = luminance(env.eval(sun));
    // Wrong variant: taking sunDirection to the emitter's frame by to_world
    // instead of its inverse left 0.058 at the sun and put 894 (the disk) 180
    // degrees away about y.
    for (const Vec3& off : {Vec3(0.f, 1.f, 0.f), Vec3(-sun.x, sun.y, -sun.z), Vec3(sun.z, sun.y, -sun.x)}) {
        CAPTURE(at_sun, luminance(env.eval(glm::normalize(off))));
        CHECK(at_sun > 100.f * luminance(env.eval(glm::normalize(off))));
    }
    // Outside the disk (4 x 0.268 degrees = 1.07 degrees) the sky is as dim again.
    const Vec3 beside = glm::normalize(sun + 0.05f * glm::normalize(glm::cross(sun, Vec3(0.f, 1.f, 0.f))));
    CHECK(at_sun > 100.f * luminance(env.eval(beside)));
    // The sky alone has no disk; the sun alone no sky.
    const SceneFile sky_only = load_scene_file(scene(R"(<emitter type="sky"><vector name="sunDirection" x="0.6" y="0.5" z="-0.62"/></emitter>)"));
    CHECK(luminance(sky_only.scene->environment()->eval(sun)) < 1.f);
    const SceneFile sun_only = load_scene_file(scene(R"(<emitter type="sun"><vector name="sunDirection" x="0.6" y="0.5" z="-0.62"/></emitter>)"));
    CHECK(luminance(sun_only.scene->environment()->eval(Vec3(0.f, 1.f, 0.f))) == 0.f);
    // Both a direction and a time: an error naming the key.
    const auto error = [&](const std::string& e) {
        try {
            load_scene_file(scene(e));
        } catch (const InputError& x) {
            return std::string(x.what());
        }
        return std::string();
    };
    CHECK_THAT(error(R"(<emitter type="sunsky"><vector name="sunDirection" x="0" y="1" z="0"/><float name="hour" value="9"/></emitter>)"),
               Catch::Contains("'hour'") && Catch::Contains("sunDirection"));
    CHECK_THAT(error(R"(<emitter type="sunsky"><float name="turbidity" value="12"/></emitter>)"), Catch::Contains("turbidity"));
    CHECK_THAT(error(R"(<emitter type="sunsky"><integer name="month" value="13"/></emitter>)"), Catch::Contains("calendar"));
}

TEST_CASE("sky: the solar position at a date, time and place", "[sky]") {
    // 21 June 2010, 12:00 UTC at 45 degrees north on the prime meridian: solar
    // noon within two minutes (equation of time), so the sun is due south
    // (local +z; azimuth 0 is -z, north) at zenith angle 45 - 23.44 degrees.
    // Wrong variant: the declination's sign flipped gave a zenith angle of 68.44 degrees (21.57 right).
    const Vec3 d = sun_direction_at(2010, 6, 21, 12, 0, 0, 45.0, 0.0, 0.0);
    const double zenith = std::acos(double(d.y)) * 180 / kPiD;
    CAPTURE(d.x, d.y, d.z, zenith);
    CHECK(zenith == Approx(45.0 - 23.44).margin(0.6));
    CHECK(d.z > 0.3f);
    CHECK(std::abs(d.x) < 0.02f);
    // The same instant given as 21:00 in Tokyo's time zone (UTC+9).
    const Vec3 t = sun_direction_at(2010, 6, 21, 21, 0, 0, 45.0, 0.0, 9.0);
    CHECK(glm::length(t - d) < 1e-5f);
    // Six hours later the sun has set at 45 degrees north (sunset near 19:40 solar time).
    CHECK(sun_direction_at(2010, 6, 21, 20, 30, 0, 45.0, 0.0, 0.0).y < 0.f);
}

TEST_CASE("sky: stretch and extend reach below the horizon as Mitsuba defines them", "[sky]") {
    SkyParams p;
    p.sun_dir = glm::normalize(Vec3(0.5f, 0.6f, -0.3f));
    p.sun_scale = 0.f;
    p.resolution = 64;
    const HosekWilkieSky model(p.turbidity, p.albedo, kPiD / 2 - std::acos(double(p.sun_dir.y)));
    const glm::dvec3 sun = glm::normalize(glm::dvec3(p.sun_dir));
    // The texel centre of row y, column x in the lat-long convention, and the model's radiance there.
    const auto centre = [&](int x, int y) {
        const double th = kPiD * (y + 0.5) / 32, ph = 2 * kPiD * (x + 0.5) / 64;
        return glm::dvec3(std::sin(th) * std::sin(ph), std::cos(th), -std::sin(th) * std::cos(ph));
    };
    const auto expected = [&](const glm::dvec3& d, double stretch, int c) {
        // At zenith angle theta / stretch with the same azimuth; gamma from the true sun.
        const double theta = std::acos(d.y) / stretch, h = std::hypot(d.x, d.z);
        const glm::dvec3 dm(std::sin(theta) * d.x / h, std::cos(theta), std::sin(theta) * d.z / h);
        return model.radiance(c, theta, std::acos(std::clamp(glm::dot(dm, sun), -1.0, 1.0)));
    };
    const Image plain = bake_sky(p);
    p.stretch = 1.5f;
    const Image stretched = bake_sky(p);
    for (int y : {3, 10, 17, 20, 23}) {
        const glm::dvec3 d = centre(9, y);
        INFO("row " << y << ", zenith angle " << std::acos(d.y) * 180 / kPiD);
        // Row 17 and below lie under the horizon: black unstretched, the
        // model at theta / 1.5 when stretched (to 135 degrees: rows < 24).
        if (d.y <= 0.0) CHECK(plain.at(9, y, 2) == 0.f);
        else CHECK(plain.at(9, y, 2) == Approx(expected(d, 1.0, 2)).epsilon(1e-4));
        CHECK(stretched.at(9, y, 2) == Approx(expected(d, 1.5, 2)).epsilon(1e-4));
        CHECK(stretched.at(9, y, 2) > 0.f);
    }
    // Beyond 1.5 x 90 degrees black again; `extend` keeps the horizon's
    // radiance there, faded by smoothstep towards the nadir.
    CHECK(stretched.at(9, 29, 2) == 0.f);
    p.extend = true;
    const Image extended = bake_sky(p);
    const glm::dvec3 d29 = centre(9, 29);
    const double t = 2.0 - 2.0 * std::acos(d29.y) / kPiD, fade = t * t * (3 - 2 * t);
    const double th_h = kPiD / 2 - 1e-4, hh = std::hypot(d29.x, d29.z);
    const glm::dvec3 dh(std::sin(th_h) * d29.x / hh, std::cos(th_h), std::sin(th_h) * d29.z / hh);
    CHECK(extended.at(9, 29, 2) == Approx(model.radiance(2, th_h, std::acos(glm::dot(dh, sun))) * fade).epsilon(1e-4));
    CHECK(extended.at(9, 3, 2) == Approx(stretched.at(9, 3, 2)).epsilon(1e-6));  // above the horizon no fade
    p.stretch = 2.5f;
    CHECK_THROWS_AS(bake_sky(p), ParameterError);
}

TEST_CASE("sky: a stretched sun is drawn lower, and sunRadiusScale 0 makes it a directional light", "[sky][mitsuba]") {
    SkyParams p;
    p.sun_dir = glm::normalize(Vec3(0.3f, 0.8f, 0.2f));
    p.stretch = 1.4f;
    const Vec3 drawn = drawn_sun_direction(p);
    CHECK(std::acos(drawn.y) == Approx(1.4 * std::acos(double(p.sun_dir.y))).epsilon(1e-5));
    CHECK(drawn.x / drawn.z == Approx(p.sun_dir.x / p.sun_dir.z).epsilon(1e-5));  // same azimuth
    // The directional sun carries the disk's power: radiance times the true solid angle.
    const double omega = 2 * kPiD * (1 - std::cos(kSunAngularRadius));
    const Color l = sun_radiance(std::acos(double(p.sun_dir.y)), p.turbidity);
    CHECK(sun_irradiance(p).g == Approx(l.g * omega).epsilon(1e-5));
    OutDir dir("sky-directional");
    std::ofstream(dir("scene.xml")) << R"(<scene version="0.6.0"><sensor type="perspective"><float name="fov" value="40"/>
      <transform name="toWorld"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
      <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
      <shape type="rectangle"/><emitter type="sunsky"><vector name="sunDirection" x="0.3" y="0.8" z="0.2"/>
      <float name="sunRadiusScale" value="0"/><float name="sunScale" value="2"/></emitter></scene>)";
    const SceneFile sf = load_scene_file(dir("scene.xml"));
    REQUIRE(sf.scene->delta_lights().size() == 1);
    const DeltaLight& sun = sf.scene->delta_lights()[0];
    CHECK(sun.kind == DeltaLight::Kind::Directional);
    CHECK(glm::dot(sun.direction, -glm::normalize(Vec3(0.3f, 0.8f, 0.2f))) == Approx(1.f).epsilon(1e-5));
    CHECK(sun.intensity.g == Approx(2.0 * l.g * omega).epsilon(1e-4));
    // The map holds the sky alone: no disk at the sun.
    REQUIRE(sf.scene->environment());
    CHECK(luminance(sf.scene->environment()->eval(glm::normalize(Vec3(0.3f, 0.8f, 0.2f)))) < 1.f);
}
