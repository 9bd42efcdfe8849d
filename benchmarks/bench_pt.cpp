// Path-tracing throughput against the bare-Embree bound on the same rays.
//
// For each scene it records the rays of a 1-spp path-traced render (camera and
// bounce rays as closest-hit queries, NEE rays as shadow queries), then
// alternates, `repeats` times: (a) a timed PT render of `spp` samples per pixel
// on all threads; (b) a timed replay of the recorded rays `spp` times with
// rtcIntersect1 / rtcOccluded1 only, no shading, on the same threads. The replay
// casts the same number and kinds of rays in the same distribution and order,
// so (b) bounds what any shading could reach. Medians over repeats are quoted;
// both halves run in the same process, back to back, (a) first in even runs
// and (b) first in odd ones. Wall-clock figures
// swing with other programs on a shared machine, so the ratio is also given
// in process CPU time (user + system, all threads), which other programs do
// not inflate; that is the figure to quote when the machine is busy.
//
//   bench_pt [--spp N] [--repeats R] [--threads T] [--set key=value]... [SCENE.json ...]
//
// --set passes a parameter to the integrator (e.g. nee=false, to time BSDF
// sampling alone).
//
// Without scenes it runs scenes/cornell-box/scene.json and scenes/veach-mis/scene.json.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>
#include <vector>

#include <embree3/rtcore.h>
#include <fmt/core.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "gdr/core/args.h"
#include "gdr/core/error.h"
#include "gdr/integrators/integrator.h"
#include "gdr/io/scene_file.h"
#include "run_stats.h"

namespace {

using Clock = std::chrono::steady_clock;

struct RecordedRay {
    gdr::Vec3 o;
    float tmin;
    gdr::Vec3 d;
    float tmax;
    bool shadow;
};

// Keeps every ray of a render in the order it was traced.
class Recorder final : public gdr::RayObserver {
public:
    void on_intersect(const gdr::Ray& r) override { add(r, false); }
    void on_occluded(const gdr::Ray& r) override { add(r, true); }
    std::vector<RecordedRay> rays;

private:
    void add(const gdr::Ray& r, bool shadow) {
        std::lock_guard<std::mutex> lock(mutex_);
        rays.push_back({r.o, r.tmin, r.d, r.tmax, shadow});
    }
    std::mutex mutex_;
};

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// "q1-q3" of the runs, as printed.
std::string quartile_range(const std::vector<double>& v) {
    const auto [q1, q3] = gdr::bench::quartiles(v);
    return fmt::format("{:.3f}-{:.3f}", q1, q3);
}

// Casts `rays` `passes` times with bare Embree calls; returns seconds.
double replay(RTCScene scene, const std::vector<RecordedRay>& rays, long long passes, tbb::task_arena& arena,
              uint64_t& hits) {
    std::atomic<uint64_t> hit_count{0};
    const auto t0 = Clock::now();
    for (long long pass = 0; pass < passes; ++pass) {
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
                uint64_t local = 0;
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                for (size_t i = r.begin(); i != r.end(); ++i) {
                    const RecordedRay& q = rays[i];
                    if (q.shadow) {
                        RTCRay ray;
                        ray.org_x = q.o.x, ray.org_y = q.o.y, ray.org_z = q.o.z, ray.tnear = q.tmin;
                        ray.dir_x = q.d.x, ray.dir_y = q.d.y, ray.dir_z = q.d.z, ray.time = 0.f;
                        ray.tfar = q.tmax, ray.mask = 0xffffffffu, ray.id = 0, ray.flags = 0;
                        rtcOccluded1(scene, &ctx, &ray);
                        local += ray.tfar < 0.f;
                    } else {
                        RTCRayHit rh;
                        rh.ray.org_x = q.o.x, rh.ray.org_y = q.o.y, rh.ray.org_z = q.o.z, rh.ray.tnear = q.tmin;
                        rh.ray.dir_x = q.d.x, rh.ray.dir_y = q.d.y, rh.ray.dir_z = q.d.z, rh.ray.time = 0.f;
                        rh.ray.tfar = q.tmax, rh.ray.mask = 0xffffffffu, rh.ray.id = 0, rh.ray.flags = 0;
                        rh.hit.geomID = rh.hit.primID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                        rtcIntersect1(scene, &ctx, &rh);
                        local += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
                    }
                }
                hit_count += local;
            });
        });
    }
    hits = hit_count;
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

bool bench_scene(const std::string& path, long long spp, int repeats, int threads,
                 const std::vector<std::string>& sets) {
    gdr::SceneFile sf = gdr::load_scene_file(path);
    gdr::Scene& scene = *sf.scene;
    const auto& cam = scene.camera();
    fmt::print("{}: {} triangles, {} emitting, {}x{}, {} spp, {} repeats, {} threads\n", path, scene.stats().triangles,
               scene.stats().emitters, cam.width(), cam.height(), spp, repeats,
               threads > 0 ? threads : tbb::this_task_arena::max_concurrency());

    gdr::Params params = sf.defaults.params;
    for (const auto& kv : sets) params.set_from_text(kv);
    auto pt = gdr::integrator_registry().create(sf.defaults.integrator, params);
    std::string settings = pt->describe();
    std::replace(settings.begin(), settings.end(), '\n', ' ');
    fmt::print("  {}: {}\n", sf.defaults.integrator, settings);

    // Record the ray distribution of one sample per pixel.
    Recorder rec;
    scene.set_ray_observer(&rec);
    gdr::RenderSettings rs;
    rs.spp = 1;
    rs.threads = 1;
    rs.seed = 12345;
    gdr::FrameBuffer fb;
    const gdr::RenderStats rec_stats = pt->render(scene, rs, fb, {});
    scene.set_ray_observer(nullptr);
    size_t shadow = 0;
    for (const auto& r : rec.rays) shadow += r.shadow;
    fmt::print("  recorded {} rays ({} closest-hit, {} shadow), {:.2f} rays/sample\n", rec.rays.size(),
               rec.rays.size() - shadow, shadow, double(rec.rays.size()) / double(rec_stats.samples));
    if (rec.rays.size() != rec_stats.rays)
        throw gdr::RuntimeFailure("ray count mismatch: integrator reported " + std::to_string(rec_stats.rays) +
                                  ", scene traced " + std::to_string(rec.rays.size()));

    tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
    std::vector<double> pt_sps, pt_rps, bound_rps, bound_sps, ratio, cpu_ratio;
    for (int i = 0; i < repeats; ++i) {
        gdr::RenderSettings st;
        st.spp = spp;
        st.threads = threads;
        st.seed = uint64_t(i);
        // The two halves take turns going first, so that a drift of the
        // machine within a run does not favour one of them in the median.
        gdr::RenderStats s;
        uint64_t hits = 0;
        double tb = 0.0, pt_cpu = 0.0, bound_cpu = 0.0;
        const auto run_pt = [&] {
            const double c0 = gdr::bench::cpu_seconds();
            s = pt->render(scene, st, fb, {});
            pt_cpu = gdr::bench::cpu_seconds() - c0;
        };
        const auto run_bound = [&] {
            const double c0 = gdr::bench::cpu_seconds();
            tb = replay(static_cast<RTCScene>(scene.embree_scene()), rec.rays, spp, arena, hits);
            bound_cpu = gdr::bench::cpu_seconds() - c0;
        };
        if (i % 2 == 0) run_pt(), run_bound();
        else run_bound(), run_pt();
        const double rays_b = double(rec.rays.size()) * double(spp);
        const double rps = double(s.rays) / s.seconds, rps_b = rays_b / tb;
        const double rays_per_sample = double(s.rays) / double(s.samples);
        pt_sps.push_back(double(s.samples) / s.seconds);
        pt_rps.push_back(rps);
        bound_rps.push_back(rps_b);
        bound_sps.push_back(rps_b / rays_per_sample);
        ratio.push_back(rps / rps_b);
        // Rays per CPU second of each, in ratio.
        cpu_ratio.push_back((double(s.rays) / pt_cpu) / (rays_b / bound_cpu));
        fmt::print("  run {}: PT {:.3f} s ({:.3f} s CPU), {:.3f} M rays, {:.2f} M rays/s | bound {:.3f} s ({:.3f} s CPU), "
                   "{:.3f} M rays, {:.2f} M rays/s, {} hits | ratio {:.3f} wall, {:.3f} CPU\n",
                   i, s.seconds, pt_cpu, s.rays * 1e-6, rps * 1e-6, tb, bound_cpu, rays_b * 1e-6, rps_b * 1e-6, hits,
                   ratio.back(), cpu_ratio.back());
    }
    const double r = median(cpu_ratio);
    fmt::print("  median: PT {:.3f} M samples/s, {:.2f} M rays/s | bare Embree {:.3f} M samples/s, {:.2f} M rays/s | "
               "PT/bound {:.3f} wall-clock, {:.3f} CPU time ({}; quartiles of the runs: {} wall-clock, {} CPU time)\n\n",
               median(pt_sps) * 1e-6, median(pt_rps) * 1e-6, median(bound_sps) * 1e-6, median(bound_rps) * 1e-6,
               median(ratio), r, r >= 0.5 ? "meets the 0.5 target" : "BELOW the 0.5 target", quartile_range(ratio),
               quartile_range(cpu_ratio));
    return r >= 0.5;
}

}  // namespace

int main(int argc, char** argv) {
    long long spp = 4;
    int repeats = 5, threads = 0;
    std::vector<std::string> scenes, sets;
    try {
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto value = [&]() -> std::string {
                if (i + 1 >= argc) throw gdr::ParameterError("option " + a + " needs a value");
                return argv[++i];
            };
            if (a == "--spp") spp = gdr::ArgReader::parse_int(a, value(), 1, 1LL << 32);
            else if (a == "--repeats") repeats = int(gdr::ArgReader::parse_int(a, value(), 1, 10000));
            else if (a == "--threads") threads = int(gdr::ArgReader::parse_int(a, value(), 0, 1 << 16));
            else if (a == "--set") sets.push_back(value());
            else if (a == "-h" || a == "--help") {
                fmt::print("usage: bench_pt [--spp N] [--repeats R] [--threads T] [--set key=value]... [SCENE.json ...]\n");
                return 0;
            } else if (!a.empty() && a[0] == '-') throw gdr::ParameterError("unknown option '" + a + "'");
            else scenes.push_back(a);
        }
        if (spp < 1 || repeats < 1 || threads < 0) throw gdr::ParameterError("--spp and --repeats must be >= 1, --threads >= 0");
        if (scenes.empty())
            scenes = {std::string(GDR_SOURCE_DIR) + "/scenes/cornell-box/scene.json",
                      std::string(GDR_SOURCE_DIR) + "/scenes/veach-mis/scene.json"};
        fmt::print("machine: {}\n", gdr::bench::machine_description());
        bool ok = true;
        for (const auto& s : scenes) ok &= bench_scene(s, spp, repeats, threads, sets);
        return ok ? 0 : 3;
    } catch (const std::exception& e) {
        fmt::print(stderr, "bench_pt: error: {}\n", e.what());
        return 1;
    }
}
