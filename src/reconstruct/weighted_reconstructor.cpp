// The "poisson-weighted" reconstructor: a Reconstructor wrapper around
// gdr/reconstruct/weighted.h that reads the variance and spp layers.

#include <cmath>
#include <sstream>

#include "gdr/core/error.h"
#include "gdr/reconstruct/reconstructor.h"
#include "gdr/reconstruct/weighted.h"

namespace gdr {
namespace {

class PoissonWeighted final : public Reconstructor {
public:
    explicit PoissonWeighted(const Params& p) {
        const std::string ctx = p.context() + ": parameter '";
        auto real = [&](const char* key, double def, double lo, double hi) {
            const double v = p.get_real(key, def);
            if (!(v >= lo && v <= hi))
                throw ParameterError(ctx + key + "' must be in [" + fmt(lo) + ", " + fmt(hi) + "], got " + fmt(v));
            return v;
        };
        auto integer = [&](const char* key, long long def, long long lo, long long hi) {
            const long long v = p.get_int(key, def);
            if (v < lo || v > hi)
                throw ParameterError(ctx + key + "' must be in " + std::to_string(lo) + ".." + std::to_string(hi) +
                                     ", got " + std::to_string(v));
            return int(v);
        };
        const WeightedOptions def;
        norm_ = p.get_choice("norm", def.norm == WeightedNorm::l1 ? "l1" : "l2", {"l2", "l1"});
        outliers_ = p.get_choice("outliers", "drop", {"drop", "downweight", "none"});
        fallback_ = p.get_choice("fallback", "none", {"none", "tile"});
        guard_ = p.get_choice("guard", def.guard == VarianceGuard::median ? "median" : "mean", {"mean", "median"});
        o_.guard = guard_ == "median" ? VarianceGuard::median : VarianceGuard::mean;
        energy_ = p.get_choice("energy", "lowpass", {"none", "mean", "lowpass"});
        o_.norm = norm_ == "l1" ? WeightedNorm::l1 : WeightedNorm::l2;
        o_.outliers = outliers_ == "drop" ? OutlierMode::drop
                      : outliers_ == "downweight" ? OutlierMode::downweight
                                                  : OutlierMode::none;
        o_.tile_fallback = fallback_ == "tile";
        o_.energy = energy_ == "mean" ? EnergyMode::mean : energy_ == "lowpass" ? EnergyMode::lowpass : EnergyMode::none;
        o_.primal_scale = real("primal_scale", o_.primal_scale, 1e-6, 1e6);
        o_.variance_radius = integer("variance_radius", o_.variance_radius, 0, 64);
        o_.variance_floor = real("variance_floor", o_.variance_floor, 1e-12, 1.0);
        o_.tau = real("tau", o_.tau, 1e-3, 1e6);
        o_.tile = integer("tile", o_.tile, 1, 1 << 16);
        o_.kappa = real("kappa", o_.kappa, 1e-6, 1e6);
        o_.energy_radius = integer("energy_radius", o_.energy_radius, 1, 1 << 12);
        o_.energy_clip = real("energy_clip", o_.energy_clip, 0.0, 1e6);
        o_.irls_iterations = integer("irls_iterations", o_.irls_iterations, 0, 1000);
        o_.eps = real("eps", o_.eps, 1e-6, 1e6);
        o_.cg_iterations = integer("cg_iterations", o_.cg_iterations, 2, 100000);
        o_.tolerance = real("tolerance", o_.tolerance, 0.0, 1.0);
    }

    std::string describe() const override {
        std::ostringstream os;
        os.precision(17);
        os << "cg_iterations=" << o_.cg_iterations << "\nenergy=" << energy_ << "\nenergy_clip=" << o_.energy_clip
           << "\nenergy_radius=" << o_.energy_radius
           << "\neps=" << o_.eps << "\nfallback=" << fallback_ << "\nguard=" << guard_
           << "\nirls_iterations=" << o_.irls_iterations
           << "\nkappa=" << o_.kappa << "\nnorm=" << norm_ << "\noutliers=" << outliers_
           << "\nprimal_scale=" << o_.primal_scale << "\ntau=" << o_.tau << "\ntile=" << o_.tile
           << "\ntolerance=" << o_.tolerance << "\nvariance_floor=" << o_.variance_floor
           << "\nvariance_radius=" << o_.variance_radius << "\n";
        return os.str();
    }

protected:
    Image solve(const GradientBuffers& in) const override {
        std::string missing;
        const std::pair<const Image*, const char*> need[] = {{in.primal_variance, "primal_variance"},
                                                             {in.dx_variance, "dx_variance"},
                                                             {in.dy_variance, "dy_variance"},
                                                             {in.spp, "spp"}};
        for (const auto& [img, name] : need)
            if (!img) missing += std::string(missing.empty() ? "" : ", ") + name;
        if (!missing.empty())
            throw ParameterError("poisson-weighted needs the layers primal_variance, dx_variance, dy_variance and "
                                 "spp (as gpt writes them); missing: " + missing);
        auto view = [](const Image* img) { return ImageView{img->data(), img->width(), img->height(), img->channels()}; };
        VarianceProblem vp;
        vp.primal = view(in.primal), vp.dx = view(in.dx), vp.dy = view(in.dy);
        vp.primal_variance = view(in.primal_variance), vp.dx_variance = view(in.dx_variance);
        vp.dy_variance = view(in.dy_variance);
        vp.spp = in.spp->data();
        // A gpt render with a gradient mask: its masked edges hold primal
        // differences, not gradient estimates (RenderSettings::gradient_mask).
        std::vector<unsigned char> enabled;
        if (const Image* mask = in.layer("gradient_mask")) {
            if (mask->width() != in.primal->width() || mask->height() != in.primal->height() || mask->channels() != 1)
                throw InputError("poisson-weighted: layer 'gradient_mask' must have 1 channel and primal's size");
            enabled.resize(mask->values().size());
            for (size_t k = 0; k < enabled.size(); ++k) enabled[k] = mask->values()[k] != 0.f;
            vp.gradient_enabled = enabled.data();
        }
        Image out(in.primal->width(), in.primal->height(), in.primal->channels());
        poisson_variance_weighted(vp, o_, out.data());
        return out;
    }

private:
    static std::string fmt(double v) {
        std::ostringstream os;
        os << v;
        return os.str();
    }
    std::string norm_, outliers_, fallback_, energy_, guard_;
    WeightedOptions o_;
};

}  // namespace

void register_weighted_reconstructors(Registry<Reconstructor>& r) {
    r.add("poisson-weighted",
          "screened Poisson weighted by inverse variances (needs primal_variance, dx_variance, dy_variance, spp), "
          "outlier gradients dropped; norm (l2 | l1), outliers (drop | downweight | none), tau, fallback (none | "
          "tile), tile, kappa, energy (none | mean | lowpass), energy_radius, energy_clip, primal_scale, variance_radius, guard (mean | median), "
          "variance_floor, irls_iterations, eps, cg_iterations, tolerance",
          [](const Params& p) { return std::make_unique<PoissonWeighted>(p); });
}

}  // namespace gdr
