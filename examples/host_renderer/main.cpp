// Renders the toy renderer's Cornell-style scene (host.h) with its own
// reference path tracer (reference_pt.h) and writes a float RGB OpenEXR.
//
//   gdr_host_renderer OUT.exr [--spp N] [--size N] [--max-depth N]
#include <cstdio>
#include <string>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfOutputFile.h>
#include <tbb/parallel_for.h>

#include "reference_pt.h"

namespace {

// Mean radiance per pixel (W/(m^2 sr)) over `spp` samples, row-major RGB; non-finite
// samples are dropped (and counted in `dropped`) so that no pixel holds NaN or Inf.
std::vector<float> render_reference(const toy::Renderer& host, int spp, const toy::PtOptions& opt, long& dropped) {
    const int w = host.camera().width(), h = host.camera().height();
    std::vector<float> rgb(size_t(w) * h * 3, 0.f);
    std::vector<long> bad(h, 0);
    tbb::parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            gdr::Color sum(0.f);
            for (int i = 0; i < spp; ++i) {
                gdr::Sampler s(gdr::SampleKey{7, uint32_t(x), uint32_t(y), uint32_t(i)});
                const gdr::Vec2 film = gdr::Vec2(x, y) + s.next2d();
                const gdr::Color c = toy::radiance(host, film, s, opt);
                if (gdr::is_finite(c)) sum += c;
                else ++bad[y];
            }
            for (int c = 0; c < 3; ++c) rgb[(size_t(y) * w + x) * 3 + c] = sum[c] / float(spp);
        }
    });
    for (long b : bad) dropped += b;
    return rgb;
}

void write_exr(const std::string& path, const std::vector<float>& rgb, int w, int h) {
    Imf::Header header(w, h);
    Imf::FrameBuffer fb;
    const char* names[3] = {"R", "G", "B"};
    for (int c = 0; c < 3; ++c) {
        header.channels().insert(names[c], Imf::Channel(Imf::FLOAT));
        fb.insert(names[c], Imf::Slice(Imf::FLOAT, (char*)(rgb.data() + c), 3 * sizeof(float), 3 * sizeof(float) * w));
    }
    Imf::OutputFile file(path.c_str(), header);
    file.setFrameBuffer(fb);
    file.writePixels(h);
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2 || argc % 2 != 0) {
        std::fprintf(stderr, "usage: gdr_host_renderer OUT.exr [--spp N] [--size N] [--max-depth N]\n");
        return 2;
    }
    int spp = 64, size = 64;
    toy::PtOptions opt;
    for (int i = 2; i + 1 < argc; i += 2) {
        const std::string key = argv[i];
        int value = 0;
        try {
            value = std::stoi(argv[i + 1]);
        } catch (const std::exception&) {
            value = 0;
        }
        int* target = key == "--spp" ? &spp : key == "--size" ? &size : key == "--max-depth" ? &opt.max_depth : nullptr;
        if (!target || value <= 0 || value > 1 << 16) {
            std::fprintf(stderr, "gdr_host_renderer: %s %s: expected --spp, --size or --max-depth and a number in [1, 65536]\n",
                         argv[i], argv[i + 1]);
            return 2;
        }
        *target = value;
    }
    const toy::Renderer host = toy::cornell_scene(size, size);
    long dropped = 0;
    const std::vector<float> rgb = render_reference(host, spp, opt, dropped);
    try {
        write_exr(argv[1], rgb, size, size);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "gdr_host_renderer: cannot write %s: %s\n", argv[1], e.what());
        return 1;
    }
    double mean = 0.0;
    for (float v : rgb) mean += v;
    std::printf("wrote %s: %dx%d, %d spp, mean radiance %.4f, %ld non-finite samples dropped\n", argv[1], size, size,
                spp, mean / double(rgb.size()), dropped);
    return 0;
}
