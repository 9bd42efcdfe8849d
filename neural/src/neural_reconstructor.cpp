// The "neural" reconstructor (gdr/neural/neural_reconstructor.h).

#include "gdr/neural/neural_reconstructor.h"

#include <filesystem>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include "gdr/neural/unet.h"

namespace gdr::neural {
namespace {

class NeuralReconstructor final : public Reconstructor {
public:
    NeuralReconstructor(const Params& p, const std::string& default_weights, const std::string& missing_default) {
        weights_ = p.get_string("weights", default_weights);
        if (weights_.empty())
            throw ParameterError(p.context() + ": the neural reconstructor needs weights=PATH (a file written by gdr_train)" +
                                 (missing_default.empty() ? "" : "; " + missing_default));
        // Absolute, as describe() reports it: a render stores it, and its
        // resume or merge may run from another directory.
        weights_ = std::filesystem::absolute(weights_).lexically_normal().string();
        const long long threads = p.get_int("threads", 0);
        if (threads < 0 || threads > 1024)
            throw ParameterError(p.context() + ": parameter 'threads' must be in 0..1024, got " + std::to_string(threads));
        threads_ = threads > 0 ? int(threads) : int(std::max(1u, std::thread::hardware_concurrency()));
        net_ = std::make_unique<UNet>(load_weights(weights_));
    }
    std::string describe() const override {
        std::ostringstream os;
        os << "gradients=" << ((*net_)->config().gradients ? "true" : "false") << "\nthreads=" << threads_
           << "\npoisson=" << ((*net_)->config().poisson ? ((*net_)->config().weighted ? "weighted" : "true") : "false")
           << "\nweights=" << weights_ << "\nwidths=";
        for (size_t i = 0; i < (*net_)->config().widths.size(); ++i) os << (i ? "," : "") << (*net_)->config().widths[i];
        os << "\n";
        return os.str();
    }
    std::vector<std::string> required_layers() const override {
        if ((*net_)->config().weighted)
            return {"albedo", "normal", "depth", "primal_variance", "dx_variance", "dy_variance", "spp"};
        return {"albedo", "normal", "depth"};
    }

protected:
    Image solve(const GradientBuffers& in) const override {
        // One forward pass at a time per reconstructor: torch modules are not
        // meant to be run concurrently from several threads.
        std::lock_guard<std::mutex> lock(mutex_);
        torch::set_num_threads(threads_);
        return infer(*net_, in);
    }

private:
    std::string weights_;
    int threads_ = 1;
    std::unique_ptr<UNet> net_;
    mutable std::mutex mutex_;
};

}  // namespace

void register_neural_reconstructor(Registry<Reconstructor>& r, const std::string& default_weights,
                                   const std::string& missing_default) {
    const std::string weights_doc = default_weights.empty() ? "weights=PATH" : "weights (default " + default_weights + ")";
    r.add("neural", "U-Net on primal, gradients, albedo, normal, depth (libtorch); " + weights_doc + ", threads",
          [default_weights, missing_default](const Params& p) {
              return std::make_unique<NeuralReconstructor>(p, default_weights, missing_default);
          });
}

}  // namespace gdr::neural
