// A weighted sum of BSDFs, as Mitsuba's `mixturebsdf` (constant weights) and
// `blendbsdf` (two BSDFs blended by a weight texture) define it:
// f = sum_k w_k f_k. A component is picked with probability w_k / sum_j w_j
// at the hit's uv and sampled; a smooth sample then carries the whole
// mixture's value and density (sum_k w_k f_k and sum_k p_k pdf_k), so that
// every component's lobes are combined by one-sample MIS, and a delta sample
// the weighted sum of the delta lobes along its direction (one lobe, or two
// coinciding mirrors), w_k f_k with density p_k pdf_k summed over them.
#include <fmt/format.h>

#include "gdr/core/error.h"
#include "gdr/scene/bsdf.h"

namespace gdr {
namespace {

class Mixture final : public Bsdf {
public:
    // Either constant weights (blend = null) or two components blended by `blend`.
    Mixture(std::vector<std::shared_ptr<Bsdf>> parts, std::vector<float> weights, std::shared_ptr<Texture> blend)
        : parts_(std::move(parts)), weights_(std::move(weights)), blend_(std::move(blend)) {
        for (const auto& b : parts_) {
            flags_ |= b->flags();
            min_roughness_ = std::min(min_roughness_, b->min_roughness());
            wo_side_only_ = wo_side_only_ && b->wo_side_only();
            if (b->flags() & kTransmission) {
                if (eta_ != 1.f && b->eta() != eta_)
                    throw ParameterError("mixture: its transmitting BSDFs have different indices of refraction");
                eta_ = b->eta();
            }
        }
    }

    std::optional<BsdfSample> sample(const Vec3& wo, const Vec2& uv, float u_lobe, const Vec2& u) const override {
        float w[kMax];
        const float total = weights_at(uv, w);
        if (!(total > 0.f)) return std::nullopt;
        // Pick a component by its share of the weights; the rest of u_lobe chooses within it.
        const int n = int(parts_.size());
        float x = u_lobe * total;
        int k = 0;
        while (k + 1 < n && (w[k] <= 0.f || x >= w[k])) x -= w[k], ++k;
        if (!(w[k] > 0.f)) return std::nullopt;
        const float u_inner = std::clamp(x / w[k], 0.f, std::nextafter(1.f, 0.f));
        std::optional<BsdfSample> s = parts_[k]->sample(wo, uv, u_inner, u);
        if (!s) return std::nullopt;
        if (s->is_delta()) {
            // Every component's delta lobe along this wi (a coated mirror's
            // two): as eval_delta() gives it, so that shifts see the same.
            if (std::optional<BsdfSample> d = eval_delta(wo, s->wi, uv)) return d;
            s->f *= w[k];
            s->pdf *= w[k] / total;
            return s;
        }
        const BsdfEval e = mix(wo, s->wi, uv, w, total);
        if (!(e.pdf > 0.f)) return std::nullopt;
        s->f = e.f, s->pdf = e.pdf;
        return s;
    }

    Color eval(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override { return eval_pdf(wo, wi, uv).f; }
    float pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override { return eval_pdf(wo, wi, uv).pdf; }

    BsdfEval eval_pdf(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        float w[kMax];
        const float total = weights_at(uv, w);
        if (!(total > 0.f)) return {};
        return mix(wo, wi, uv, w, total);
    }

    std::optional<BsdfSample> eval_delta(const Vec3& wo, const Vec3& wi, const Vec2& uv) const override {
        float w[kMax];
        const float total = weights_at(uv, w);
        if (!(total > 0.f)) return std::nullopt;
        // Delta lobes of several components along the same wi (two mirrors) add up.
        std::optional<BsdfSample> sum;
        for (size_t k = 0; k < parts_.size(); ++k) {
            if (!(w[k] > 0.f)) continue;
            const std::optional<BsdfSample> d = parts_[k]->eval_delta(wo, wi, uv);
            if (!d) continue;
            if (!sum) {
                sum = d, sum->f *= w[k], sum->pdf *= w[k] / total;
            } else {
                sum->f += d->f * w[k], sum->pdf += d->pdf * w[k] / total;
            }
        }
        return sum;
    }

    uint32_t flags() const override { return flags_; }
    Color albedo(const Vec2& uv) const override {
        float w[kMax];
        weights_at(uv, w);
        Color a(0.f);
        for (size_t k = 0; k < parts_.size(); ++k) a += w[k] * parts_[k]->albedo(uv);
        return a;
    }
    float min_roughness() const override { return min_roughness_; }
    float eta() const override { return eta_; }
    bool wo_side_only() const override { return wo_side_only_; }
    bool is_black() const override {
        for (size_t k = 0; k < parts_.size(); ++k)
            if (!parts_[k]->is_black() && (blend_ || weights_[k] > 0.f)) return false;
        return true;
    }

    static constexpr size_t kMax = 16;  // components, as many as the importer accepts

private:
    // The weights at uv into w; returns their sum.
    float weights_at(const Vec2& uv, float* w) const {
        if (blend_) {
            // Mitsuba's blendbsdf: the texture's channel average, in [0, 1].
            const Color c = blend_->eval(uv);
            const float b = std::clamp((c.r + c.g + c.b) / 3.f, 0.f, 1.f);
            w[0] = 1.f - b, w[1] = b;
            return 1.f;
        }
        float total = 0.f;
        for (size_t k = 0; k < parts_.size(); ++k) total += (w[k] = weights_[k]);
        return total;
    }

    // The mixture's value and density over its smooth lobes.
    BsdfEval mix(const Vec3& wo, const Vec3& wi, const Vec2& uv, const float* w, float total) const {
        BsdfEval r;
        for (size_t k = 0; k < parts_.size(); ++k) {
            if (!(w[k] > 0.f)) continue;
            const BsdfEval e = parts_[k]->eval_pdf(wo, wi, uv);
            r.f += w[k] * e.f;
            r.pdf += w[k] / total * e.pdf;
        }
        return r;
    }

    std::vector<std::shared_ptr<Bsdf>> parts_;
    std::vector<float> weights_;
    std::shared_ptr<Texture> blend_;
    uint32_t flags_ = 0;
    float min_roughness_ = 1.f, eta_ = 1.f;
    bool wo_side_only_ = true;
};

void check_parts(const std::vector<std::shared_ptr<Bsdf>>& parts, const char* what) {
    if (parts.size() < 1 || parts.size() > Mixture::kMax)
        throw ParameterError(fmt::format("{}: needs 1 to {} BSDFs, got {}", what, Mixture::kMax, parts.size()));
    for (const auto& b : parts)
        if (!b) throw ParameterError(std::string(what) + ": a nested BSDF is missing");
}

}  // namespace

std::shared_ptr<Bsdf> make_mixture(std::vector<std::shared_ptr<Bsdf>> parts, std::vector<float> weights) {
    check_parts(parts, "mixture");
    if (weights.size() != parts.size())
        throw ParameterError(fmt::format("mixture: {} weights for {} BSDFs", weights.size(), parts.size()));
    for (float w : weights)
        if (!(w >= 0.f) || !std::isfinite(w))
            throw ParameterError(fmt::format("mixture: the weights must be finite and >= 0, got {}", w));
    return std::make_shared<Mixture>(std::move(parts), std::move(weights), nullptr);
}

std::shared_ptr<Bsdf> make_blend(std::shared_ptr<Bsdf> first, std::shared_ptr<Bsdf> second,
                                 std::shared_ptr<Texture> weight) {
    std::vector<std::shared_ptr<Bsdf>> parts{std::move(first), std::move(second)};
    check_parts(parts, "blend");
    if (!weight) throw ParameterError("blend: the weight texture is missing");
    return std::make_shared<Mixture>(std::move(parts), std::vector<float>{0.f, 0.f}, std::move(weight));
}

}  // namespace gdr
