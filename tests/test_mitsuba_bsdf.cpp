// Mitsuba XML BSDFs and textures through the importer: phong, tinted
// dielectrics, Beckmann microfacets and textured conductor reflectance load
// strictly and build what Mitsuba defines; every built-in shift passes the
// validator on a scene of them.
#include <catch2/catch.hpp>

#include <fstream>
#include <string>

#include "block_stats.h"
#include "cli_test_util.h"
#include "gdr/core/error.h"
#include "gdr/io/mitsuba_xml.h"
#include "gdr/io/png.h"
#include "gdr/scene/bsdf.h"
#include "gdr/scene/scene.h"
#include "gdr/shift/validate.h"

using namespace gdr;
using namespace gdr::test;

namespace {

// A camera at z = 5 looking down -z at a unit square: the one shape of most scenes here.
const std::string kHead = R"(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film></sensor>
  <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
)";

/// Writes `body` as a scene with one rectangle carrying `bsdf` and loads it strictly.
struct BsdfScene {
    OutDir dir{"mitsuba-bsdf"};
    SceneFile load(const std::string& bsdf, const std::string& version = "3.0.0") const {
        const std::string file = dir("scene.xml");
        std::string head = kHead;
        head.replace(head.find("3.0.0"), 5, version);
        std::ofstream(file, std::ios::binary) << head << "<shape type=\"rectangle\">" << bsdf << "</shape>\n</scene>\n";
        return load_scene_file(file);
    }
    std::shared_ptr<Bsdf> bsdf(const std::string& text) const {
        const SceneFile sf = load(text);
        REQUIRE(sf.scene->materials().size() >= 1);
        return sf.scene->materials().back().bsdf;
    }
};

const Vec2 kUv(0.3f, 0.7f);

Vec3 dir(float theta_deg, float phi = 0.4f) {
    const float t = glm::radians(theta_deg);
    return {std::sin(t) * std::cos(phi), std::sin(t) * std::sin(phi), std::cos(t)};
}

bool close(const Color& a, const Color& b, float rel = 1e-4f) {
    for (int c = 0; c < 3; ++c)
        if (std::abs(a[c] - b[c]) > rel * std::max(std::abs(a[c]), std::abs(b[c])) + 1e-7f) return false;
    return true;
}

/// Every built-in shift passes the validator on `sf`'s scene (3000 base paths,
/// more than 1000 of them scattering), and every offset returns to its base path.
void validate_every_shift(const SceneFile& sf) {
    for (const char* name : {"half-vector", "reconnection", "replay", "replay-reconnect"}) {
        const ShiftReport rep = check_validated_shift(*sf.scene, name);
        CHECK(rep.reverse_ok == rep.reverse_checked);
    }
}

/// gpt's E[dx], E[dy] against the differences of pt's image, and its primal
/// against pt's, on a 24 x 24 box scene in 6 x 6 blocks over 16 runs a side,
/// for the shifts that take delta lobes (check_unbiased_gradients' bounds).
void check_gpt_unbiased_on_box(const SceneFile& sf) {
    const int block = 6, runs = 16;
    const std::vector<FrameBuffer> pt = render_runs(*sf.scene, "pt", Params(), 256, runs, 1000);
    for (const char* shift : {"half-vector", "replay", "replay-reconnect"}) {
        INFO("shift " << shift);
        const std::vector<FrameBuffer> g =
            render_runs(*sf.scene, "gpt", params({{"shift", shift}, {"reconstruct", "none"}}), 64, runs, 1);
        check_unbiased_gradients(gradient_z(pt, g, block));
    }
}

/// A closed box seen from inside, lit from its ceiling, `width` pixels
/// square: coated diffuse walls (a delta interface over a diffuse base: base
/// paths take either lobe, offsets must take the same), a coated rough
/// conductor sphere, a coated, absorbing Phong sphere, a coated glass
/// sphere (the glass's refraction through the layer on both sides) and a
/// diffuse sphere under a rough coating.
std::string coated_box(const OutDir& dir, int width) {
    const std::string file = dir("coated-box.xml");
    std::ofstream(file, std::ios::binary) << R"XML(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="90"/>
    <transform name="to_world"><lookat origin="0, 1, 0.97" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value=")XML" << width << R"XML("/><integer name="height" value=")XML" << width
                                          << R"XML("/></film></sensor>
  <bsdf type="coating" id="walls"><float name="int_ior" value="1.5"/>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.6, 0.5"/></bsdf></bsdf>
  <shape type="cube"><transform name="to_world"><scale value="1"/><translate y="1"/></transform><boolean name="flip_normals" value="true"/><ref id="walls"/></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.4"/><rotate x="1" angle="90"/><translate y="1.98"/></transform>
    <emitter type="area"><rgb name="radiance" value="10"/></emitter></shape>
  <shape type="sphere"><point name="center" x="0.4" y="0.4" z="0"/><float name="radius" value="0.35"/>
    <bsdf type="coating"><float name="int_ior" value="1.7"/><rgb name="sigma_a" value="0.1, 0.3, 0.6"/>
      <bsdf type="phong"><float name="exponent" value="40"/><rgb name="diffuse_reflectance" value="0.3"/></bsdf></bsdf></shape>
  <shape type="sphere"><point name="center" x="-0.4" y="0.4" z="-0.3"/><float name="radius" value="0.3"/>
    <bsdf type="coating"><bsdf type="roughconductor"><string name="material" value="Cu"/><float name="alpha" value="0.25"/></bsdf></bsdf></shape>
  <shape type="sphere"><point name="center" x="0.1" y="1.2" z="-0.5"/><float name="radius" value="0.25"/>
    <bsdf type="coating"><float name="int_ior" value="1.4"/><bsdf type="dielectric"><float name="int_ior" value="1.33"/></bsdf></bsdf></shape>
  <shape type="sphere"><point name="center" x="-0.5" y="1.4" z="0.1"/><float name="radius" value="0.2"/>
    <bsdf type="roughcoating"><float name="alpha" value="0.15"/><rgb name="sigma_a" value="0.3, 0.1, 0.05"/>
      <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf></bsdf></shape>
</scene>
)XML";
    return file;
}

/// A closed box lit from its ceiling, `width` pixels square: walls of a
/// diffuse base blended with a mirror by a checkerboard (a delta lobe beside
/// a smooth one, in varying shares), and a sphere mixing a rough conductor
/// with a diffuse lobe.
std::string blend_box(const OutDir& dir, int width) {
    const std::string file = dir("blend-box.xml");
    std::ofstream(file, std::ios::binary) << R"XML(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="90"/>
    <transform name="to_world"><lookat origin="0, 1, 0.97" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value=")XML" << width << R"XML("/><integer name="height" value=")XML" << width << R"XML("/></film></sensor>
  <bsdf type="blendbsdf" id="walls"><texture type="checkerboard" name="weight"><float name="color0" value="0.8"/><float name="color1" value="0.1"/>
    <transform name="to_uv"><scale x="4" y="4"/></transform></texture>
    <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.6, 0.5"/></bsdf><bsdf type="conductor"/></bsdf>
  <shape type="cube"><transform name="to_world"><scale value="1"/><translate y="1"/></transform><boolean name="flip_normals" value="true"/><ref id="walls"/></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.4"/><rotate x="1" angle="90"/><translate y="1.98"/></transform>
    <emitter type="area"><rgb name="radiance" value="10"/></emitter></shape>
  <shape type="sphere"><point name="center" x="0.4" y="0.4" z="0"/><float name="radius" value="0.35"/>
    <bsdf type="mixturebsdf"><string name="weights" value="0.4, 0.5"/>
      <bsdf type="roughconductor"><float name="alpha" value="0.2"/></bsdf><bsdf type="diffuse"/></bsdf></shape>
</scene>
)XML";
    return file;
}

}  // namespace

TEST_CASE("mitsuba bsdf: phong loads strictly with Mitsuba's parameters and defaults", "[mitsuba][phong]") {
    BsdfScene s;
    const auto b = s.bsdf(R"(<bsdf type="phong"><float name="exponent" value="40"/>
        <rgb name="diffuseReflectance" value="0.3, 0.2, 0.1"/><rgb name="specularReflectance" value="0.4"/></bsdf>)");
    const auto ref = make_phong(make_constant_texture(Color(0.3f, 0.2f, 0.1f)), make_constant_texture(Color(0.4f)), 40.f);
    const Vec3 wo = dir(30.f), wi = dir(28.f, 0.4f + kPi);
    CHECK(close(b->eval(wo, wi, kUv), ref->eval(wo, wi, kUv)));
    CHECK(b->pdf(wo, wi, kUv) == Approx(ref->pdf(wo, wi, kUv)));
    // Defaults: exponent 30, specular 0.2, diffuse 0.5.
    const auto d = s.bsdf(R"(<bsdf type="phong"/>)");
    const auto dref = make_phong(make_constant_texture(Color(0.5f)), make_constant_texture(Color(0.2f)), 30.f);
    CHECK(close(d->eval(wo, wi, kUv), dref->eval(wo, wi, kUv)));
    CHECK(d->min_roughness() == Approx(phong_to_alpha(30.f)));
    CHECK_THROWS_AS(s.load(R"(<bsdf type="phong"><float name="exponent" value="-1"/></bsdf>)"), InputError);
}

TEST_CASE("mitsuba bsdf: tinted dielectrics load strictly and tint their lobes", "[mitsuba][tint]") {
    BsdfScene s;
    for (const std::string type : {"dielectric", "thindielectric", "roughdielectric"}) {
        const auto b = s.bsdf("<bsdf type=\"" + type + R"("><rgb name="specular_reflectance" value="0.5, 0.6, 0.7"/>
            <rgb name="specularTransmittance" value="0.2, 0.4, 0.8"/></bsdf>)");
        // Normal incidence: reflection F ~ 0.04 weighted 0.5/0.6/0.7, transmission weighted 0.2/0.4/0.8.
        const Vec3 wo = dir(0.f);
        bool seen_r = false, seen_t = false;
        for (float ul : {0.001f, 0.999f}) {
            const auto smp = b->sample(wo, kUv, ul, Vec2(0.3f, 0.6f));
            if (!smp) continue;
            const Color w = smp->f * std::abs(smp->wi.z) / smp->pdf;
            INFO(type << ": weight " << w.r << " " << w.g << " " << w.b);
            if (smp->lobe & kReflection) {
                seen_r = true;
                CHECK(w.g / w.r == Approx(0.6f / 0.5f).epsilon(1e-3));
                CHECK(w.b / w.r == Approx(0.7f / 0.5f).epsilon(1e-3));
            } else {
                seen_t = true;
                CHECK(w.g / w.r == Approx(2.f).epsilon(1e-3));
                CHECK(w.b / w.r == Approx(4.f).epsilon(1e-3));
            }
        }
        CHECK(seen_t);
        if (type != "roughdielectric") CHECK(seen_r);
    }
}

TEST_CASE("mitsuba bsdf: Beckmann is Beckmann, GGX is GGX", "[mitsuba][beckmann]") {
    BsdfScene s;
    const Vec3 wo = dir(40.f), wi = dir(45.f, 0.4f + kPi + 0.2f);
    // Mitsuba's default distribution for rough BSDFs is Beckmann.
    const auto def = s.bsdf(R"(<bsdf type="roughconductor"><string name="material" value="none"/><float name="alpha" value="0.3"/></bsdf>)");
    const auto beck = make_rough_conductor(Color(1.f), 0.3f, MicrofacetType::Beckmann);
    const auto ggx = make_rough_conductor(Color(1.f), 0.3f, MicrofacetType::GGX);
    CHECK(close(def->eval(wo, wi, kUv), beck->eval(wo, wi, kUv)));
    CHECK_FALSE(close(def->eval(wo, wi, kUv), ggx->eval(wo, wi, kUv), 1e-2f));
    const SceneFile g = s.load(R"(<bsdf type="roughconductor"><string name="material" value="none"/>
        <string name="distribution" value="ggx"/><float name="alpha" value="0.3"/></bsdf>)");
    CHECK(close(g.scene->materials().back().bsdf->eval(wo, wi, kUv), ggx->eval(wo, wi, kUv)));
    for (const std::string& w : g.warnings) CHECK(w.find("GGX") == std::string::npos);
    // Rough plastic and glass take the distribution too (no warning either way).
    for (const std::string t : {"roughplastic", "roughdielectric"}) {
        const SceneFile sf = s.load("<bsdf type=\"" + t + "\"><float name=\"alpha\" value=\"0.2\"/></bsdf>");
        CHECK(sf.warnings.empty());
    }
}

TEST_CASE("mitsuba bsdf: a checkerboard on a rough conductor's specular_reflectance", "[mitsuba][texture]") {
    // Replacing such a texture by white made an interior 41% too bright: the
    // value must follow the texture per uv.
    BsdfScene s;
    const auto b = s.bsdf(R"(<bsdf type="roughconductor"><string name="material" value="none"/><float name="alpha" value="0.2"/>
        <texture name="specular_reflectance" type="checkerboard"><rgb name="color0" value="0.1"/><rgb name="color1" value="0.8"/>
        </texture></bsdf>)");
    const auto white = make_rough_conductor(Color(1.f), 0.2f, MicrofacetType::Beckmann);
    const Vec3 wo = dir(20.f), wi = dir(25.f, 0.4f + kPi);
    const float w = white->eval(wo, wi, kUv).g;
    // The checkerboard's two colours appear at uv in the two kinds of cells.
    const float a = b->eval(wo, wi, Vec2(0.25f, 0.25f)).g, c = b->eval(wo, wi, Vec2(0.75f, 0.25f)).g;
    CHECK(std::min(a, c) == Approx(0.1f * w).epsilon(1e-3));
    CHECK(std::max(a, c) == Approx(0.8f * w).epsilon(1e-3));
}

TEST_CASE("mitsuba bsdf: every built-in shift passes the validator on a Phong scene", "[mitsuba][shift][phong]") {
    // A closed box seen from inside, lit from its ceiling: Phong walls of a
    // broad lobe (exponent 5), a Phong sphere of a narrow one (exponent 200,
    // equivalent GGX alpha 0.1), a Beckmann conductor and tinted glass.
    OutDir dir{"mitsuba-bsdf-shift"};
    const std::string file = dir("phong.xml");
    std::ofstream(file, std::ios::binary) << R"XML(<scene version="3.0.0">
  <sensor type="perspective"><float name="fov" value="90"/>
    <transform name="to_world"><lookat origin="0, 1, 0.97" target="0, 1, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/></film></sensor>
  <bsdf type="phong" id="walls"><float name="exponent" value="5"/><rgb name="diffuse_reflectance" value="0.5"/>
    <rgb name="specular_reflectance" value="0.3"/></bsdf>
  <shape type="cube"><transform name="to_world"><scale value="1"/><translate y="1"/></transform><boolean name="flip_normals" value="true"/><ref id="walls"/></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.3"/><rotate x="1" angle="90"/><translate y="1.98"/></transform>
    <emitter type="area"><rgb name="radiance" value="15"/></emitter></shape>
  <shape type="sphere"><point name="center" x="0.4" y="0.4" z="0"/><float name="radius" value="0.35"/>
    <bsdf type="phong"><float name="exponent" value="200"/><rgb name="diffuse_reflectance" value="0.2, 0.3, 0.5"/>
      <rgb name="specular_reflectance" value="0.5"/></bsdf></shape>
  <shape type="sphere"><point name="center" x="-0.4" y="0.4" z="-0.3"/><float name="radius" value="0.3"/>
    <bsdf type="roughconductor"><string name="material" value="Au"/><float name="alpha" value="0.15"/></bsdf></shape>
  <shape type="rectangle"><transform name="to_world"><scale value="0.4"/><translate x="-0.2" y="1.0" z="0.4"/></transform>
    <bsdf type="thindielectric"><rgb name="specular_transmittance" value="0.9, 0.7, 0.5"/></bsdf></shape>
</scene>
)XML";
    validate_every_shift(load_scene_file(file));
}

TEST_CASE("mitsuba bsdf: ward and roughdiffuse load strictly as Mitsuba defines them", "[mitsuba][ward][oren-nayar]") {
    BsdfScene s;
    const Vec3 wo = dir(30.f), wi = dir(50.f, 0.4f + 2.f);
    // Mitsuba's ward defaults: balanced, alpha 0.1, kd 0.5, ks 0.2.
    const auto w = s.bsdf(R"(<bsdf type="ward"/>)");
    const auto wref = make_ward(make_constant_texture(Color(0.5f)), make_constant_texture(Color(0.2f)), 0.1f,
                                WardVariant::Balanced);
    CHECK(close(w->eval(wo, wi, kUv), wref->eval(wo, wi, kUv)));
    const auto wd = s.bsdf(R"(<bsdf type="ward"><string name="variant" value="ward-duer"/><float name="alphaU" value="0.3"/>
        <float name="alphaV" value="0.3"/><rgb name="specularReflectance" value="0.4"/></bsdf>)");
    const auto wdref = make_ward(make_constant_texture(Color(0.5f)), make_constant_texture(Color(0.4f)), 0.3f,
                                 WardVariant::WardDuer);
    CHECK(close(wd->eval(wo, wi, kUv), wdref->eval(wo, wi, kUv)));
    CHECK_THROWS_WITH(s.load(R"(<bsdf type="ward"><string name="variant" value="ashikhmin"/></bsdf>)"),
                      Catch::Contains("ashikhmin"));
    // roughdiffuse: alpha 0.2 by default, the full model unless use_fast_approx.
    const auto r = s.bsdf(R"(<bsdf type="roughdiffuse"><rgb name="reflectance" value="0.6"/></bsdf>)");
    CHECK(close(r->eval(wo, wi, kUv), make_oren_nayar(make_constant_texture(Color(0.6f)), 0.2f)->eval(wo, wi, kUv)));
    const auto rf = s.bsdf(R"(<bsdf type="roughdiffuse"><float name="alpha" value="0.7"/><boolean name="useFastApprox" value="true"/></bsdf>)");
    CHECK(close(rf->eval(wo, wi, kUv),
                make_oren_nayar(make_constant_texture(Color(0.5f)), 0.7f, true)->eval(wo, wi, kUv)));
    CHECK_FALSE(close(rf->eval(wo, wi, kUv), Color(0.5f * kInvPi), 1e-2f));
}

TEST_CASE("mitsuba bsdf: roughness on a smooth BSDF is ignored in 0.6 files, as Mitsuba 0.6 does", "[mitsuba]") {
    BsdfScene s;
    for (const std::string t : {"dielectric", "conductor", "plastic"}) {
        const SceneFile sf = s.load("<bsdf type=\"" + t + "\"><float name=\"alpha\" value=\"0.1\"/></bsdf>", "0.6.0");
        bool warned = false;
        for (const std::string& w : sf.warnings) warned = warned || w.find("'alpha' on a smooth") != std::string::npos;
        CHECK(warned);
        if (t != "plastic") CHECK(sf.scene->materials().back().bsdf->is_pure_delta());
        // Mitsuba 3 refuses the property, and so does a strict load of a 3.x file.
        CHECK_THROWS_AS(s.load("<bsdf type=\"" + t + "\"><float name=\"alpha\" value=\"0.1\"/></bsdf>"), InputError);
    }
}

TEST_CASE("mitsuba bsdf: bitmap gamma and the scale texture", "[mitsuba][texture]") {
    BsdfScene s;
    Image img(2, 2, 3, 0.f);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x) img.set_rgb(x, y, Color(0.3f));
    write_png_preview(s.dir("grey.png"), img);
    // The stored byte, and what gamma 2.2, sRGB and linear decode it to.
    const float byte = std::round(255.f * linear_to_srgb(0.3f)) / 255.f;
    const auto albedo = [&](const std::string& tex) {
        return s.bsdf("<bsdf type=\"diffuse\">" + tex + "</bsdf>")->albedo(kUv).g;
    };
    const std::string file = "<string name=\"filename\" value=\"" + s.dir("grey.png") + "\"/>";
    CHECK(albedo("<texture name=\"reflectance\" type=\"bitmap\">" + file + "<float name=\"gamma\" value=\"2.2\"/></texture>") ==
          Approx(std::pow(byte, 2.2f)).epsilon(1e-4));
    CHECK(albedo("<texture name=\"reflectance\" type=\"bitmap\">" + file + "<float name=\"gamma\" value=\"-1\"/></texture>") ==
          Approx(srgb_to_linear(byte)).epsilon(1e-4));
    CHECK(albedo("<texture name=\"reflectance\" type=\"bitmap\">" + file + "<float name=\"gamma\" value=\"1\"/></texture>") ==
          Approx(byte).epsilon(1e-4));
    CHECK_THROWS_AS(albedo("<texture name=\"reflectance\" type=\"bitmap\">" + file + "<float name=\"gamma\" value=\"0\"/></texture>"),
                    InputError);
    // scale: the nested texture times the factor, per channel.
    CHECK(albedo("<texture name=\"reflectance\" type=\"scale\"><rgb name=\"scale\" value=\"0.5, 1, 2\"/>"
                 "<texture type=\"bitmap\">" + file + "<boolean name=\"raw\" value=\"true\"/></texture></texture>") ==
          Approx(byte).epsilon(1e-4));
    const auto scaled = s.bsdf("<bsdf type=\"diffuse\"><texture name=\"reflectance\" type=\"scale\"><float name=\"scale\" value=\"0.5\"/>"
                               "<texture type=\"checkerboard\"><rgb name=\"color0\" value=\"0.8\"/><rgb name=\"color1\" value=\"0.4\"/></texture>"
                               "</texture></bsdf>");
    const float a = scaled->albedo(Vec2(0.25f, 0.25f)).g, b = scaled->albedo(Vec2(0.75f, 0.25f)).g;
    CHECK(std::min(a, b) == Approx(0.2f));
    CHECK(std::max(a, b) == Approx(0.4f));
    CHECK_THROWS_AS(s.load(R"(<bsdf type="diffuse"><texture name="reflectance" type="scale"><float name="scale" value="2"/></texture></bsdf>)"),
                    InputError);
}

TEST_CASE("mitsuba bsdf: coating loads strictly over reflective and transmitting BSDFs", "[mitsuba][coating]") {
    BsdfScene s;
    const auto b = s.bsdf(R"(<bsdf type="coating"><float name="intIOR" value="1.7"/><float name="thickness" value="2"/>
        <rgb name="sigmaA" value="0.1, 0.2, 0.3"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.4, 0.2"/></bsdf></bsdf>)");
    const auto ref = make_coating(make_lambertian(make_constant_texture(Color(0.6f, 0.4f, 0.2f))), 1.7f / 1.00028f,
                                  Color(0.2f, 0.4f, 0.6f));
    const Vec3 wo = dir(30.f), wi = dir(50.f, 2.f);
    CHECK(close(b->eval(wo, wi, kUv), ref->eval(wo, wi, kUv)));
    CHECK(b->pdf(wo, wi, kUv) == Approx(ref->pdf(wo, wi, kUv)));
    // Defaults: bk7 inside, air outside, no absorption.
    const auto d = s.bsdf(R"(<bsdf type="coating"><bsdf type="roughconductor"><string name="material" value="Au"/></bsdf></bsdf>)");
    CHECK(d->flags() & kSpecular);
    const Vec3 wr(-wo.x, -wo.y, wo.z);
    const auto dd = d->eval_delta(wo, wr, kUv);
    REQUIRE(dd);
    CHECK(dd->f.g * wr.z == Approx(fresnel_dielectric(wo.z, 1.5046f / 1.00028f)));
    // Over a glass too, as Mitsuba: the glass's refraction through the layer on both sides.
    const auto g = s.bsdf(R"(<bsdf type="coating"><float name="intIOR" value="1.5"/><bsdf type="dielectric"><float name="intIOR" value="1.33"/>
        <float name="extIOR" value="1"/></bsdf></bsdf>)");
    CHECK(g->flags() & kTransmission);
    CHECK(g->eta() == Approx(1.33f));
}

TEST_CASE("mitsuba bsdf: blendbsdf and mixturebsdf load strictly as Mitsuba defines them", "[mitsuba][mixture]") {
    BsdfScene s;
    const auto kd = make_lambertian(make_constant_texture(Color(0.6f, 0.4f, 0.2f)));
    const auto metal = make_rough_conductor(ConductorIor{Color(0.2f, 0.9f, 1.1f), Color(3.9f, 2.5f, 2.1f)}, 0.2f,
                                            MicrofacetType::Beckmann);
    const Vec3 wo = dir(30.f), wi = dir(45.f, 2.f);
    const std::string parts = R"(<bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.4, 0.2"/></bsdf>
        <bsdf type="roughconductor"><rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3.9, 2.5, 2.1"/>
        <float name="alpha" value="0.2"/></bsdf>)";
    const auto blend = s.bsdf(R"(<bsdf type="blendbsdf"><float name="weight" value="0.25"/>)" + parts + "</bsdf>");
    CHECK(close(blend->eval(wo, wi, kUv), 0.75f * kd->eval(wo, wi, kUv) + 0.25f * metal->eval(wo, wi, kUv)));
    // Weights summing above 1 are scaled to 1 (ensureEnergyConservation, on by default) ...
    const auto mix = s.bsdf(R"(<bsdf type="mixturebsdf"><string name="weights" value="0.9, 0.6"/>)" + parts + "</bsdf>");
    CHECK(close(mix->eval(wo, wi, kUv), 0.6f * kd->eval(wo, wi, kUv) + 0.4f * metal->eval(wo, wi, kUv)));
    // ... unless it is off.
    const auto raw = s.bsdf(R"(<bsdf type="mixturebsdf"><string name="weights" value="0.9 0.6"/>
        <boolean name="ensureEnergyConservation" value="false"/>)" + parts + "</bsdf>");
    CHECK(close(raw->eval(wo, wi, kUv), 0.9f * kd->eval(wo, wi, kUv) + 0.6f * metal->eval(wo, wi, kUv)));
    // A textured blend weight, read per uv (gdr's uv (0.75, 0.25) is Mitsuba's (0.75, 0.75): color0).
    const auto textured = s.bsdf(R"(<bsdf type="blendbsdf"><texture type="checkerboard" name="weight">
        <float name="color0" value="1"/><float name="color1" value="0"/></texture>)" + parts + "</bsdf>");
    CHECK(close(textured->eval(wo, wi, Vec2(0.75f, 0.25f)), metal->eval(wo, wi, kUv)));
    CHECK(close(textured->eval(wo, wi, Vec2(0.25f, 0.25f)), kd->eval(wo, wi, kUv)));
    // Errors name the element.
    CHECK_THROWS_WITH(s.load(R"(<bsdf type="blendbsdf"><bsdf type="diffuse"/></bsdf>)"), Catch::Contains("two nested BSDFs"));
    CHECK_THROWS_WITH(s.load(R"(<bsdf type="mixturebsdf"><string name="weights" value="0.5"/>)" + parts + "</bsdf>"),
                      Catch::Contains("one weight per nested BSDF"));
    CHECK_THROWS_WITH(s.load(R"(<bsdf type="mixturebsdf"><string name="weights" value="0.5, x"/>)" + parts + "</bsdf>"),
                      Catch::Contains("'weights'") && Catch::Contains("got 'x'"));
}

TEST_CASE("mitsuba bsdf: every built-in shift passes the validator on a blended scene", "[mitsuba][shift][mixture]") {
    const OutDir dir{"mitsuba-bsdf-blend"};
    validate_every_shift(load_scene_file(blend_box(dir, 64)));
}

TEST_CASE("mitsuba bsdf: gpt is unbiased on a blended box, for every shift", "[mitsuba][gpt][mixture][statistical]") {
    // As for the coated box: E[dx], E[dy] against pt's differences and the
    // primal against pt's image, 6 x 6 blocks of 24 x 24 pixels, 16 runs a side.
    const OutDir dir{"mitsuba-bsdf-blend-gpt"};
    check_gpt_unbiased_on_box(load_scene_file(blend_box(dir, 24)));
}

TEST_CASE("mitsuba bsdf: roughcoating loads strictly with Mitsuba's parameters and defaults", "[mitsuba][coating]") {
    BsdfScene s;
    const auto b = s.bsdf(R"(<bsdf type="roughcoating"><float name="intIOR" value="1.7"/><float name="thickness" value="2"/>
        <rgb name="sigmaA" value="0.1, 0.2, 0.3"/><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.4, 0.2"/></bsdf></bsdf>)");
    const auto ref = make_rough_coating(make_lambertian(make_constant_texture(Color(0.6f, 0.4f, 0.2f))), 1.7f / 1.00028f,
                                        0.2f, MicrofacetType::GGX, Color(0.2f, 0.4f, 0.6f));
    const Vec3 wo = dir(30.f), wi = dir(50.f, 2.f);
    CHECK(close(b->eval(wo, wi, kUv), ref->eval(wo, wi, kUv)));
    CHECK(b->pdf(wo, wi, kUv) == Approx(ref->pdf(wo, wi, kUv)));
    // Defaults: Beckmann of alpha 0.1, bk7 in air, no absorption.
    const auto d = s.bsdf(R"(<bsdf type="roughcoating"><bsdf type="diffuse"/></bsdf>)");
    const auto dref = make_rough_coating(make_lambertian(make_constant_texture(Color(0.5f))), 1.5046f / 1.00028f, 0.1f);
    CHECK(close(d->eval(wo, wi, kUv), dref->eval(wo, wi, kUv)));
    CHECK(d->min_roughness() == Approx(0.1f));
    CHECK_THROWS_WITH(s.load(R"(<bsdf type="roughcoating"/>)"), Catch::Contains("nested"));
}

TEST_CASE("mitsuba bsdf: every built-in shift passes the validator on a coated scene", "[mitsuba][shift][coating]") {
    const OutDir dir{"mitsuba-bsdf-coating"};
    const std::string file = coated_box(dir, 64);
    validate_every_shift(load_scene_file(file));
}

TEST_CASE("mitsuba bsdf: gpt is unbiased on a coated box, for every shift", "[mitsuba][gpt][coating][statistical]") {
    // The coated box: paths take the interface's delta lobe or the nested
    // one at every bounce. E[dx], E[dy]
    // against the differences of pt's image and the primal against pt's, in
    // 6 x 6 blocks of a 24 x 24 frame over 16 runs a side (|z| < 5 for the
    // gradients, 4.5 for the primal; the negated gradients must be rejected).
    const OutDir dir{"mitsuba-bsdf-coating-gpt"};
    check_gpt_unbiased_on_box(load_scene_file(coated_box(dir, 24)));
}
