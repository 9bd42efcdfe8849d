// Gradient-domain path tracing: shift validation, unbiased gradients and an
// unbiased primal, on diffuse, mirror, glass and glossy scenes.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>

#include "gdr/integrators/gpt.h"
#include "../src/shift/offset_packets.h"
#include "gdr/integrators/integrator.h"
#include "gdr/path/dims.h"
#include "gdr/path/trace.h"
#include "gdr/io/scene_file.h"
#include "gdr/shift/steps.h"
#include "gdr/shift/validate.h"
#include "bad_shifts.h"
#include "block_stats.h"

using namespace gdr;
using namespace gdr::test;

namespace {

const char* const kShifts[] = {"half-vector", "reconnection", "replay", "replay-reconnect"};

}  // namespace

TEST_CASE("every built-in shift passes the validator", "[gpt][shift]") {
    const std::vector<std::string> scenes = {GDR_SOURCE_DIR "/scenes/cornell-box/scene.json",
                                             GDR_SOURCE_DIR "/scenes/cornell-box/mirror.json",
                                             GDR_SOURCE_DIR "/scenes/cornell-box/sphere.json",
                                             GDR_SOURCE_DIR "/scenes/veach-mis/scene.json"};
    for (const auto& path : scenes) {
        const SceneFile sf = load_scene_file(path);
        for (const char* name : kShifts) {
            ValidateOptions opt;
            opt.paths = 1500;
            const auto shift = shift_registry().create(name, Params());
            const ShiftReport rep = validate_shift(*sf.scene, *shift, ShiftConfig{}, opt);
            INFO(path << "\n" << rep.summary());
            CHECK(rep.passed);
            CHECK(rep.base_paths > 300);
            CHECK(rep.jacobian_checked + rep.jacobian_skipped > 300);
            CHECK(rep.reverse_ok == rep.reverse_checked);
            // Every Jacobian the finite differences can resolve agrees, not
            // just the required share.
            CHECK(rep.jacobian_worst_error < 0.1);
        }
    }
}


TEST_CASE("validator catches a wrong Jacobian", "[gpt][shift]") {
    // A reconnection whose Jacobian forgets the cosine ratio must fail the finite-difference check.
    const SceneFile sf = load_scene_file(GDR_SOURCE_DIR "/scenes/cornell-box/scene.json");
    ValidateOptions opt;
    opt.paths = 1000;
    const ShiftReport rep = validate_shift(*sf.scene, *make_shift(BadReconnection{}), ShiftConfig{}, opt);
    INFO(rep.summary());
    CHECK_FALSE(rep.passed);
}

TEST_CASE("gpt gradients are unbiased: E[dx], E[dy] equal differences of the PT image", "[gpt][statistical]") {
    // Block z-test: 24x24 pixels in 6x6 blocks, per-run block means over 16
    // independent seeds each side (standard errors with ~30 degrees of freedom).
    // 512 tests in all; |z| < 5 keeps the family-wise false-alarm rate below 1%.
    const int res = 24, block = 6, runs = 16;
    for (const std::string variant : {"Original", "Mirror", "Sphere", "Glossy"}) {
        const auto scene = small_box(variant, res);
        std::vector<FrameBuffer> pt;
        for (int r = 0; r < runs; ++r) pt.push_back(render(*scene, "pt", Params(), 128, 1000 + r));
        const auto ref_d = [&](bool along_x) {
            return block_stats(runs, res, res, block, [&](int r, auto&& add) {
                const Image& c = pt[r].get("color");
                for (int y = 0; y < res - !along_x; ++y)
                    for (int x = 0; x < res - along_x; ++x)
                        add(x, y, grey(c, x + along_x, y + !along_x) - grey(c, x, y));
            });
        };
        const BlockStats ref_dx = ref_d(true), ref_dy = ref_d(false);
        for (const char* shift : kShifts) {
            Params p;
            p.set("shift", std::string(shift));
            std::vector<FrameBuffer> g;
            for (int r = 0; r < runs; ++r) g.push_back(render(*scene, "gpt", p, 48, 1 + r));
            // Gradients leave directly visible emitters out (they are added after
            // reconstruction), so the direct layer's own differences are added back.
            const auto est = [&](const char* layer, bool along_x) {
                return block_stats(runs, res, res, block, [&](int r, auto&& add) {
                    const Image& d = g[r].get(layer);
                    const Image& e = g[r].get("direct");
                    for (int y = 0; y < res - !along_x; ++y)
                        for (int x = 0; x < res - along_x; ++x)
                            add(x, y, grey(d, x, y) + grey(e, x + along_x, y + !along_x) - grey(e, x, y));
                });
            };
            const BlockStats dx = est("dx", true), dy = est("dy", false);
            INFO(variant << " " << shift);
            CHECK(max_z(dx, ref_dx) < 5.0);
            CHECK(max_z(dy, ref_dy) < 5.0);
            // The test has power: the negated gradients are rejected.
            BlockStats neg = dx;
            for (double& m : neg.mean) m = -m;
            CHECK(max_z(neg, ref_dx) > 5.0);
        }
    }
}

TEST_CASE("gpt primal agrees with pt in expectation, in both primal modes", "[gpt][statistical]") {
    const int res = 24, block = 6, runs = 16;  // 64 tests: |z| < 4.5 (t, ~30 dof) at about 1% family-wise
    for (const std::string variant : {"Original", "Sphere"}) {
        const auto scene = small_box(variant, res);
        const auto stats = [&](const std::string& integ, const Params& p, long long spp, uint64_t seed0) {
            std::vector<FrameBuffer> fb;
            for (int r = 0; r < runs; ++r) fb.push_back(render(*scene, integ, p, spp, seed0 + r));
            return block_stats(runs, res, res, block, [&](int r, auto&& add) {
                const Image& c = fb[r].get("color");
                for (int y = 0; y < res; ++y)
                    for (int x = 0; x < res; ++x) add(x, y, grey(c, x, y));
            });
        };
        const BlockStats ref = stats("pt", Params(), 64, 500);
        for (const char* mode : {"both", "base"}) {
            Params p;
            p.set("primal", std::string(mode));
            INFO(variant << " primal=" << mode);
            CHECK(max_z(stats("gpt", p, 24, 1), ref) < 4.5);
        }
    }
}

TEST_CASE("gpt writes the documented layers and rejects bad parameters", "[gpt]") {
    const auto scene = small_box("Original", 8);
    const FrameBuffer fb = render(*scene, "gpt", Params(), 2, 0);
    for (const char* l : {"color", "primal", "dx", "dy", "direct", "primal_variance", "dx_variance", "dy_variance",
                          "albedo", "normal", "depth", "spp"})
        CHECK(fb.has(l));
    Params bad;
    bad.set("shift", std::string("half-vectr"));
    CHECK_THROWS_WITH(integrator_registry().create("gpt", bad), Catch::Contains("available: half-vector"));
    Params typo;
    typo.set("treshold", 0.01);
    CHECK_THROWS_WITH(integrator_registry().create("gpt", typo), Catch::Contains("'treshold'"));
}

TEST_CASE("gpt images do not depend on how many samples run their stages together", "[gpt]") {
    // 20x20 leaves partial tiles; 1 spp makes batches span pixels, 5 spp
    // makes them cross from one pixel's samples into the next pixel's.
    const auto scene = small_box("Sphere", 20);
    for (long long spp : {1LL, 5LL}) {
        Params one;
        one.set("batch", 1LL);
        one.set("reconstruct", std::string("none"));
        const FrameBuffer ref = render(*scene, "gpt", one, spp, 7);
        for (long long batch : {3LL, 8LL}) {
            Params p = one;
            p.set("batch", batch);
            const FrameBuffer fb = render(*scene, "gpt", p, spp, 7);
            for (const char* l : {"primal", "dx", "dy", "direct", "primal_variance", "dx_variance", "dy_variance",
                                  "albedo", "normal", "depth"}) {
                INFO("spp " << spp << ", batch " << batch << ", layer " << l);
                const auto& a = ref.get(l).values();
                const auto& b = fb.get(l).values();
                REQUIRE(a.size() == b.size());
                CHECK(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0);
            }
        }
    }
    for (long long bad : {0LL, 9LL}) {
        Params p;
        p.set("batch", bad);
        CHECK_THROWS_WITH(integrator_registry().create("gpt", p), Catch::Contains("batch must be between 1 and 8"));
    }
}

TEST_CASE("suffixes in closed form (merged or offset-less) equal the vertex-by-vertex sum", "[gpt]") {
    // Same base paths and offsets, both evaluations, every shift, both
    // heuristics and an uneven sample ratio, and the base alone: the closed
    // forms are exact refactorings, so only float rounding (relative 1e-4)
    // may separate them.
    for (const char* variant : {"Original", "Glossy", "Mirror"}) {
        const auto scene = small_box(variant, 24);
        for (const char* shift_name : kShifts) {
            const auto shift = shift_registry().create(shift_name, Params("shift"));
            for (MisHeuristic h : {MisHeuristic::Power, MisHeuristic::Balance}) {
                GradientMis mis;
                mis.heuristic = h;
                mis.sample_ratio = h == MisHeuristic::Power ? 0.5 : 0.7;
                CameraPath path;
                OffsetPath offset;
                BaseTerms terms;
                int merged = 0;
                for (int py = 1; py < 23; ++py)
                    for (int px = 1; px < 23; ++px) {
                        Sampler sampler(SampleKey{7, uint32_t(px), uint32_t(py), 0});
                        const Vec2 film = Vec2(float(px), float(py)) + sampler.next2d();
                        trace_camera_path(*scene, film, sampler, WalkOptions{}, path);
                        if (path.size() <= 1) continue;
                        compute_base_terms(*scene, path, h, terms);
                        shift_camera_path(*scene, *shift, ShiftConfig{}, path, Vec2(1.f, 0.f), offset);
                        merged += offset.merged_from != size_t(-1);
                        for (const OffsetPath* y : {static_cast<const OffsetPath*>(&offset), static_cast<const OffsetPath*>(nullptr)}) {
                            const PairEstimate a = evaluate_pair(*scene, path, terms, y, mis, true);
                            const PairEstimate b = evaluate_pair(*scene, path, terms, y, mis, false);
                            for (int c = 0; c < 3; ++c) {
                                const auto near = [](float u, float v) {
                                    return std::abs(u - v) <= 1e-4f * std::max({std::abs(u), std::abs(v), 1e-3f});
                                };
                                INFO(variant << " " << shift_name << " pixel " << px << "," << py << " channel " << c
                                             << (y ? "" : " (base alone)"));
                                REQUIRE(near(a.base[c], b.base[c]));
                                REQUIRE(near(a.offset[c], b.offset[c]));
                                REQUIRE(near(a.gradient[c], b.gradient[c]));
                            }
                        }
                    }
                // The comparison means something only where offsets merged.
                if (std::string(shift_name) != "replay") CHECK(merged > 100);
            }
        }
    }
}

TEST_CASE("offsets traced as one packet equal offsets traced one by one", "[gpt][shift]") {
    // Embree's packet and single-ray kernels may round a hit differently in
    // the last bits, so vertices agree to a relative 1e-4, and they may break
    // ties between coincident triangles differently (the McGuire box holds
    // duplicates), so hits are compared by point and material, not by
    // triangle. A hit on another surface (only possible at an edge) may occur
    // in at most 0.5% of offsets. Both packet forms are checked: the offsets'
    // 4-ray packet after the base was traced, and the 8-ray packet that also
    // holds the base's camera ray.
    const Vec2 steps[4] = {{1.f, 0.f}, {-1.f, 0.f}, {0.f, 1.f}, {0.f, -1.f}};
    // Hits on one triangle must also agree in normal and shading frame (packet
    // lanes on one flat triangle share them, see Scene::fill_hit_like).
    const auto same_surface = [](const SurfaceInteraction& a, const SurfaceInteraction& b) {
        if (a.prim == b.prim) {
            REQUIRE(glm::length(a.ng - b.ng) <= 1e-5f);
            REQUIRE(glm::length(a.frame.n - b.frame.n) <= 1e-5f);
            REQUIRE(glm::length(a.frame.s - b.frame.s) <= 1e-5f);
        }
        return a.material == b.material && glm::length(a.p - b.p) <= 1e-4f * (1.f + glm::length(b.p));
    };
    // False if the first hits lie on different surfaces; otherwise requires equal offsets.
    const auto agree = [&](const OffsetPath& p, const OffsetPath& single) {
        if (single.v.size() > 1 && p.v.size() > 1 && !same_surface(single.v[1].y.si, p.v[1].y.si)) return false;
        REQUIRE(p.v.size() == single.v.size());
        REQUIRE(p.size() == single.size());
        REQUIRE(p.merged_from == single.merged_from);
        REQUIRE(p.rays == single.rays);
        for (size_t k = 0; k < p.v.size(); ++k) {
            const OffsetRecord &a = p.v[k], &b = single.v[k];
            REQUIRE(same_surface(a.y.si, b.y.si));
            REQUIRE(a.step.kind == b.step.kind);
            REQUIRE(a.nee == b.nee);
            // A blocked light connection (tested at once, or in a packet after the walks) carries no radiance.
            REQUIRE(is_black(a.nee_radiance) == is_black(b.nee_radiance));
            REQUIRE(std::abs(a.step.jacobian - b.step.jacobian) <= 1e-3 * std::abs(b.step.jacobian));
        }
        return true;
    };
    for (const char* variant : {"Original", "Glossy", "Mirror", "Sphere"}) {
        const int res = 20;
        const auto scene = small_box(variant, res);
        for (const char* shift_name : kShifts) {
            const auto shift = shift_registry().create(shift_name, Params("shift"));
            CameraPath path, path8;
            OffsetPath single, packet[4], packet8[4];
            int compared = 0, other_surface = 0, bases = 0, other_base = 0;
            for (int py = 0; py < res; ++py)
                for (int px = 0; px < res; ++px) {
                    Sampler sampler(SampleKey{11, uint32_t(px), uint32_t(py), 0});
                    const Vec2 film = Vec2(float(px), float(py)) + sampler.next2d();
                    Sampler sampler8 = sampler;
                    trace_camera_path(*scene, film, sampler, WalkOptions{}, path);
                    // Border pixels leave some offsets inactive, as in the integrator.
                    bool active[4];
                    for (int d = 0; d < 4; ++d) {
                        const int nx = px + int(steps[d].x), ny = py + int(steps[d].y);
                        active[d] = nx >= 0 && ny >= 0 && nx < res && ny < res;
                    }
                    shift_camera_paths4(*scene, *shift, ShiftConfig{}, path, steps, active, packet);
                    trace_and_shift_camera_paths4(*scene, *shift, ShiftConfig{}, film, sampler8, WalkOptions{}, path8,
                                                  steps, active, packet8);
                    // The base traced in the 8-ray packet is the base traced alone.
                    ++bases;
                    const bool same_base = path.size() == path8.size() &&
                                           (path.size() <= 1 || same_surface(path.v[1].si, path8.v[1].si));
                    if (!same_base) ++other_base;
                    if (same_base) {
                        REQUIRE(path8.rays == path.rays);
                        for (size_t k = 1; k < path.size(); ++k) {
                            REQUIRE(same_surface(path8.v[k].si, path.v[k].si));
                            REQUIRE(path8.v[k].scattered() == path.v[k].scattered());
                        }
                    }
                    for (int d = 0; d < 4; ++d) {
                        INFO(variant << " " << shift_name << " pixel " << px << "," << py << " offset " << d);
                        if (!active[d]) {
                            CHECK(packet[d].v.empty());
                            CHECK(packet[d].size() == 0);
                            CHECK(packet8[d].v.empty());
                            CHECK(packet8[d].size() == 0);
                            continue;
                        }
                        shift_camera_path(*scene, *shift, ShiftConfig{}, path, steps[d], single);
                        ++compared;
                        if (!agree(packet[d], single)) ++other_surface;
                        if (same_base && path.size() <= 1) {
                            // Nothing to shift; the offset's camera ray was cast in the packet all the same.
                            CHECK(packet8[d].size() == 0);
                            CHECK(packet8[d].rays == 1);
                        } else if (same_base) {
                            ++compared;
                            if (!agree(packet8[d], single)) ++other_surface;
                        }
                    }
                }
            INFO(variant << " " << shift_name);
            CHECK(compared > 2000);
            CHECK(other_surface * 200 <= compared);
            CHECK(other_base * 200 <= bases);
        }
    }
}

TEST_CASE("camera packets of several samples give what one packet per sample gives", "[gpt][shift]") {
    // Packets grouped by lane across samples (trace_camera_packets) hold
    // other rays than one sample's own packet; each lane's hit must not
    // depend on its neighbours.
    const auto scene = small_box("Original", 20);
    const Vec2 steps[4] = {{1.f, 0.f}, {-1.f, 0.f}, {0.f, 1.f}, {0.f, -1.f}};
    constexpr int n = 8;
    static CameraPath base[n], base1[n];
    static OffsetPath out[n][4], out1[n][4];
    static CameraPacket packet[n], packet1[n];
    int hits = 0;
    for (int first = 0; first < 400; first += n) {
        Vec2 film[n];
        bool active[n][4];
        for (int j = 0; j < n; ++j) {
            const int px = (first + j) % 20, py = (first + j) / 20;
            Sampler s(SampleKey{5, uint32_t(px), uint32_t(py), uint32_t(j)});
            film[j] = Vec2(float(px), float(py)) + s.next2d();
            for (int d = 0; d < 4; ++d) active[j][d] = (j + d) % 3 != 0;  // some lanes idle
        }
        const bool* act[n];
        OffsetPath* outs[n];
        for (int j = 0; j < n; ++j) act[j] = active[j], outs[j] = out[j];
        trace_camera_packets(*scene, n, film, base, steps, act, outs, packet);
        for (int j = 0; j < n; ++j) trace_camera_packet(*scene, film[j], base1[j], steps, active[j], out1[j], packet1[j]);
        for (int j = 0; j < n; ++j)
            for (int l = 0; l < 5; ++l) {
                INFO("sample " << first + j << " lane " << l);
                REQUIRE(packet[j].traced[l] == packet1[j].traced[l]);
                REQUIRE(packet[j].hit[l] == packet1[j].hit[l]);
                if (!packet[j].hit[l]) continue;
                ++hits;
                const SurfaceInteraction& a = l == 0 ? base[j].v[1].si : out[j][l - 1].v[1].y.si;
                const SurfaceInteraction& b = l == 0 ? base1[j].v[1].si : out1[j][l - 1].v[1].y.si;
                REQUIRE(a.prim == b.prim);
                REQUIRE(std::memcmp(&a.p, &b.p, sizeof(Vec3)) == 0);
                REQUIRE(a.t == b.t);
            }
    }
    CHECK(hits > 1000);
}

TEST_CASE("an offset traces the light segment of a shared vertex the base left untraced", "[gpt][shift]") {
    // The base traces its light segment only where the sample contributes to
    // it. An offset that reconnects onto the same vertex with a BSDF value of
    // its own there must then test that segment itself. Shading normals make
    // this happen: the offset arrives on the base's geometric side (as a
    // reconnection must) but on the other side of the shading normal.
    //   wall z = -2, facing the camera; sheet x = 0, two-sided, from the wall
    //   to z = 0, seen edge-on by the camera, its shading normal (1, 0, 1)
    //   tilted 45 degrees off the geometric one; light x = 1.5, facing the
    //   sheet; a blocker x = 0.75 hiding part of the light from the sheet.
    // At 4x4 pixels of 2 wall units, pixel (2,1)'s camera rays reach the wall
    // 0-2 units right of the sheet, pixel (3,1)'s 2-4 units: from most points
    // on the sheet, the first lie below the shading horizon, the second above.
    // All grey and Lambertian: values differ only by side.
    TriangleMesh m;
    auto quad = [&](Vec3 a, Vec3 b, Vec3 c, Vec3 d, uint32_t mat, Vec3 n) {  // ng = (b-a) x (c-a)
        m.positions.insert(m.positions.end(), {a, b, c, a, c, d});
        m.normals.insert(m.normals.end(), 6, glm::normalize(n));
        m.material_ids.insert(m.material_ids.end(), {mat, mat});
    };
    quad(Vec3(-8, -8, -2), Vec3(8, -8, -2), Vec3(8, 8, -2), Vec3(-8, 8, -2), 0, Vec3(0, 0, 1));
    quad(Vec3(0, -8, -2), Vec3(0, -8, 0), Vec3(0, 8, 0), Vec3(0, 8, -2), 0, Vec3(1, 0, 1));
    quad(Vec3(1.5f, 2.2f, -1.5f), Vec3(1.5f, 2.2f, -0.5f), Vec3(1.5f, 3.2f, -0.5f), Vec3(1.5f, 3.2f, -1.5f), 1,
         Vec3(-1, 0, 0));
    quad(Vec3(0.75f, 1.9f, -1.5f), Vec3(0.75f, 1.9f, -1.f), Vec3(0.75f, 3.3f, -1.f), Vec3(0.75f, 3.3f, -1.5f), 0,
         Vec3(-1, 0, 0));
    auto grey = make_lambertian(make_constant_texture(Color(0.5f)));
    CameraDesc cd;
    cd.position = {0.f, 0.f, 5.f};
    cd.target = {0.f, 0.f, 0.f};
    cd.fov_deg = 2.f * glm::degrees(std::atan(4.f / 7.f));  // 8 units across at the wall
    cd.width = cd.height = 4;
    const Scene scene(std::move(m), {Material{"grey", grey, Color(0.f)}, Material{"light", grey, Color(4.f)}},
                      Camera(cd), "sheet scene");
    const auto shift = shift_registry().create("half-vector", Params("shift"));
    const Vec2 steps[4] = {{1.f, 0.f}, {-1.f, 0.f}, {0.f, 1.f}, {0.f, -1.f}};
    const bool active[4] = {true, false, false, false};
    CameraPath path;
    OffsetPath single, packet[4];
    int untested = 0, lit = 0, blocked = 0;
    for (uint32_t i = 0; i < 4000; ++i) {
        Sampler sampler(SampleKey{3, 2, 1, i});
        const Vec2 film = Vec2(2.f, 1.f) + sampler.next2d();
        trace_camera_path(scene, film, sampler, WalkOptions{}, path);
        if (path.size() < 3 || std::abs(path.v[2].si.p.x) > 1e-4f) continue;
        const Vertex& x1 = path.v[2];
        const LightConnection& nee = path.nee[2];
        if (!nee.valid || is_black(nee.light.radiance)) continue;
        // The base traced its segment exactly where it has a value.
        REQUIRE(nee.tested == !is_black(nee.f));
        if (nee.tested) continue;
        ++untested;
        const bool visible = scene.visible(x1.si.p, x1.si.ng, nee.light.p, nee.light.n);
        shift_camera_path(scene, *shift, ShiftConfig{}, path, steps[0], single);
        shift_camera_paths4(scene, *shift, ShiftConfig{}, path, steps, active, packet);
        for (const OffsetPath* y : {&single, &packet[0]}) {
            if (y->v.size() < 3 || !y->v[2].y.on_base || !y->v[2].nee || is_black(y->v[2].nee_f)) continue;
            CHECK(y->v[2].nee_radiance == (visible ? nee.light.radiance : Color(0.f)));
            ++(visible ? lit : blocked);
        }
    }
    // Both outcomes occur often enough for the test to mean something.
    INFO("untested " << untested);
    CHECK(lit > 50);
    CHECK(blocked > 50);
}
