// The screened Poisson reconstructors "poisson-l2" and "poisson-l1": thin
// Reconstructor wrappers around gdr/reconstruct/poisson.h.

#include <cmath>
#include <sstream>

#include "gdr/reconstruct/poisson.h"
#include "gdr/reconstruct/reconstructor.h"

namespace gdr {
namespace {

PoissonProblem problem_of(const GradientBuffers& in, double alpha) {
    auto view = [](const Image* img) { return ImageView{img->data(), img->width(), img->height(), img->channels()}; };
    return PoissonProblem{view(in.primal), view(in.dx), view(in.dy), alpha};
}

double read_alpha(const Params& p) {
    const double alpha = p.get_real("alpha", 0.2);
    if (!(alpha > 0) || !std::isfinite(alpha))
        throw ParameterError(p.context() + ": parameter 'alpha' must be finite and > 0, got " + std::to_string(alpha));
    return alpha;
}

class PoissonL2 final : public Reconstructor {
public:
    explicit PoissonL2(const Params& p) : alpha_(read_alpha(p)) {}
    std::string describe() const override {
        std::ostringstream os;
        os.precision(17);
        os << "alpha=" << alpha_ << "\n";
        return os.str();
    }

protected:
    Image solve(const GradientBuffers& in) const override {
        Image out(in.primal->width(), in.primal->height(), in.primal->channels());
        poisson_l2(problem_of(in, alpha_), out.data());
        return out;
    }

private:
    double alpha_;
};

class PoissonL1 final : public Reconstructor {
public:
    explicit PoissonL1(const Params& p) : alpha_(read_alpha(p)) {
        // "reference" is the own L1 preset of the authors' public Mitsuba implementation of G-PT ("L1D":
        // 20 IRLS steps of 50 plain CG iterations from the primal), for
        // reproducing its output; "fast" the defaults of L1Options.
        preset_ = p.get_choice("preset", "fast", {"fast", "reference"});
        if (preset_ == "reference") {
            opt_.iterations = 20, opt_.cg_iterations = 50, opt_.tolerance = 0.0;
            opt_.exact_l2_start = false, opt_.preconditioner = Preconditioner::none;
        }
        const long long it = p.get_int("iterations", opt_.iterations);
        const long long cg = p.get_int("cg_iterations", opt_.cg_iterations);
        const double tol = p.get_real("tolerance", opt_.tolerance);
        if (it < 1 || it > 1000)
            throw ParameterError(p.context() + ": parameter 'iterations' must be in 1..1000, got " + std::to_string(it));
        if (cg < 1 || cg > 100000)
            throw ParameterError(p.context() + ": parameter 'cg_iterations' must be in 1..100000, got " +
                                 std::to_string(cg));
        if (!(tol >= 0) || !std::isfinite(tol))
            throw ParameterError(p.context() + ": parameter 'tolerance' must be >= 0, got " + std::to_string(tol));
        opt_.iterations = int(it), opt_.cg_iterations = int(cg), opt_.tolerance = tol;
    }
    std::string describe() const override {
        std::ostringstream os;
        os.precision(17);
        os << "alpha=" << alpha_ << "\ncg_iterations=" << opt_.cg_iterations << "\niterations=" << opt_.iterations
           << "\npreset=" << preset_ << "\ntolerance=" << opt_.tolerance << "\n";
        return os.str();
    }

protected:
    Image solve(const GradientBuffers& in) const override {
        Image out(in.primal->width(), in.primal->height(), in.primal->channels());
        poisson_l1(problem_of(in, alpha_), opt_, out.data());
        return out;
    }

private:
    double alpha_;
    std::string preset_;
    L1Options opt_;
};

}  // namespace

void register_poisson_reconstructors(Registry<Reconstructor>& r) {
    r.add("poisson-l2", "screened Poisson, exact L2 (unbiased) via the 2-D DCT; alpha",
          [](const Params& p) { return std::make_unique<PoissonL2>(p); });
    r.add("poisson-l1",
          "screened Poisson, L1 by IRLS with multigrid-preconditioned CG; alpha, iterations, cg_iterations, "
          "tolerance, preset (fast | reference)",
          [](const Params& p) { return std::make_unique<PoissonL1>(p); });
}

}  // namespace gdr
