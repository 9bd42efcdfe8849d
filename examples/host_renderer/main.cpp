// Renders the toy renderer's Cornell-style scene (host.h) with gradient-
// domain path tracing through gdr's templated path-space core (host_gpt.h),
// reconstructs the image with gdr's screened Poisson solver, and writes the
// layers to one OpenEXR file (color, primal, dx, dy, direct). --method pt
// renders with gdr's path tracer estimator instead, --method reference with
// the toy's own path tracer (reference_pt.h).
//
//   gdr_host_renderer OUT.exr [--method gpt|pt|reference] [--spp N] [--size N] [--max-depth N] [--shift NAME]
#include <cstdio>
#include <string>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <tbb/parallel_for.h>

#include "gdr/core/error.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/path/path_tracer.h"
#include "host_gpt.h"
#include "reference_pt.h"

namespace {

// Mean radiance per pixel (W/(m^2 sr)) over `spp` samples of the toy's own
// path tracer, or with `core` of gdr's path tracer estimator, row-major RGB;
// non-finite samples are dropped (and counted in `dropped`) so that no pixel
// holds NaN or Inf.
std::vector<float> render_pt(const toy::Renderer& host, int spp, const toy::PtOptions& opt, bool core, long& dropped) {
    const int w = host.camera().width(), h = host.camera().height();
    std::vector<float> rgb(size_t(w) * h * 3, 0.f);
    std::vector<long> bad(h, 0);
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            gdr::Color sum(0.f);
            for (int i = 0; i < spp; ++i) {
                gdr::Sampler s(gdr::SampleKey{7, uint32_t(x), uint32_t(y), uint32_t(i)});
                const gdr::Vec2 film = gdr::Vec2(x, y) + s.next2d();
                gdr::Color c;
                if (core) {
                    s.set_dimension(gdr::dims::kFilm);
                    const gdr::Vec2 f = gdr::Vec2(x, y) + s.next2d();
                    const gdr::PathOptions po{opt.max_depth, opt.rr_depth < 0 ? 1 << 30 : opt.rr_depth, opt.nee};
                    c = gdr::trace_path(host, host.camera().generate_ray(f), s, po).radiance;
                } else {
                    c = toy::radiance(host, film, s, opt);
                }
                if (gdr::is_finite(c)) sum += c;
                else ++bad[y];
            }
            for (int c = 0; c < 3; ++c) rgb[(size_t(y) * w + x) * 3 + c] = sum[c] / float(spp);
        }
    });
    for (long b : bad) dropped += b;
    return rgb;
}

// Writes RGB layers (row-major, w x h) to one float OpenEXR file: the layer
// named "color" as R, G, B, the others as name.R, name.G, name.B.
void write_exr(const std::string& path, const std::vector<std::pair<std::string, const std::vector<float>*>>& layers,
               int w, int h) {
    Imf::Header header(w, h);
    Imf::FrameBuffer fb;
    const char* rgb[3] = {"R", "G", "B"};
    for (const auto& [name, data] : layers)
        for (int c = 0; c < 3; ++c) {
            const std::string ch = name == "color" ? rgb[c] : name + "." + rgb[c];
            header.channels().insert(ch, Imf::Channel(Imf::FLOAT));
            fb.insert(ch, Imf::Slice(Imf::FLOAT, (char*)(data->data() + c), 3 * sizeof(float), 3 * sizeof(float) * w));
        }
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(h);
}

gdr::Image to_image(const std::vector<float>& rgb, int w, int h) {
    gdr::Image im(w, h, 3);
    std::copy(rgb.begin(), rgb.end(), im.data());
    return im;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc % 2 != 0) {
        std::fprintf(stderr, "usage: gdr_host_renderer OUT.exr [--spp N] [--size N] [--max-depth N]\n");
        return 2;
    }
    int spp = 64, size = 64;
    toy::PtOptions opt;
    std::string shift = "half-vector", method = "gpt";
    for (int i = 2; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        if (key == "--shift" || key == "--method") {
            (key == "--shift" ? shift : method) = argv[i + 1];
            continue;
        }
        int value = 0;
        try {
            value = std::stoi(argv[i + 1]);
        } catch (const std::exception&) {
            value = 0;
        }
        int* target = key == "--spp" ? &spp : key == "--size" ? &size : key == "--max-depth" ? &opt.max_depth : nullptr;
        if (!target || value <= 0 || value > 1 << 16) {
            std::fprintf(stderr,
                         "gdr_host_renderer: %s %s: expected --spp, --size or --max-depth and a number in [1, 65536], "
                         "--method gpt|pt|reference or --shift NAME\n",
                         argv[i], argv[i + 1]);
            return 2;
        }
        *target = value;
    }
    if (method != "gpt" && method != "pt" && method != "reference") {
        std::fprintf(stderr, "gdr_host_renderer: --method %s: expected gpt, pt or reference\n", method.c_str());
        return 2;
    }
    const toy::Renderer host = toy::cornell_scene(size, size);
    try {
        if (method != "gpt") {
            long dropped = 0;
            const std::vector<float> rgb = render_pt(host, spp, opt, method == "pt", dropped);
            write_exr(argv[1], {{"color", &rgb}}, size, size);
            double mean = 0.0;
            for (float v : rgb) mean += v;
            std::printf("wrote %s: %dx%d, %d spp (%s), mean radiance %.4f, %ld non-finite samples dropped\n", argv[1],
                        size, size, spp, method == "pt" ? "gdr's path tracer" : "the toy's own path tracer",
                        mean / double(rgb.size()), dropped);
            return 0;
        }
        toy::GptOptions g;
        g.spp = spp, g.max_depth = opt.max_depth, g.shift = shift;
        const toy::GptImages im = toy::render_gpt(host, g);
        const gdr::Image primal = to_image(im.primal, size, size), dx = to_image(im.dx, size, size),
                         dy = to_image(im.dy, size, size), direct = to_image(im.direct, size, size);
        const gdr::Image color =
            gdr::reconstruct("poisson-l1", gdr::Params("gdr_host_renderer"), {&primal, &dx, &dy, &direct});
        const std::vector<float> c(color.data(), color.data() + size_t(size) * size * 3);
        write_exr(argv[1], {{"color", &c}, {"primal", &im.primal}, {"dx", &im.dx}, {"dy", &im.dy}, {"direct", &im.direct}},
                  size, size);
        double mean = 0.0;
        for (float v : c) mean += v;
        std::printf("wrote %s: %dx%d, %d spp G-PT (shift %s), poisson-l1 mean radiance %.4f\n", argv[1], size, size,
                    spp, shift.c_str(), mean / double(c.size()));
    } catch (const gdr::Error& e) {  // an unknown shift, bad parameters or non-finite buffers
        std::fprintf(stderr, "gdr_host_renderer: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "gdr_host_renderer: cannot write %s: %s\n", argv[1], e.what());
        return 1;
    }
    return 0;
}
