// Internal: an aggregation multigrid V-cycle for the weighted screened
// Poisson operator, the CG preconditioner of the IRLS steps.
//
// IRLS weights 1 / (|e| + eps) vary over orders of magnitude from pixel to
// pixel; a constant-coefficient (DCT) preconditioner cannot follow that, so
// CG preconditioned by it needs many iterations (measured on the reference
// cbox buffers: 2 DCT-PCG iterations per IRLS step leave a 1% energy gap,
// 2 multigrid ones about 0.2%, at lower cost per iteration). Galerkin
// coarsening with 2x2 piecewise-constant aggregates keeps the weights in
// every coarse operator, and on a grid it is closed: the coarse operator is
// again "diagonal + 5-point weighted Laplacian" (coarse diagonal = sum of the
// 4 fine diagonal terms, coarse edge = sum of the 2 fine edges crossing the
// aggregate boundary). The screening term grows 4x per level while edges
// grow 2x, so coarse systems become diagonally dominant; the coarsest
// (<= 64 pixels) is solved exactly by a dense Cholesky factor.
#pragma once

#include <cstddef>
#include <vector>

#include "gdr/detail/large_alloc.h"

namespace gdr::detail {

/// A frame-sized work plane (see gdr/detail/large_alloc.h for why not plain std::vector<float>).
using Plane = std::vector<float, LargeAllocator<float>>;

/// sum a[i] b[i] in double. Four independent accumulators let the compiler
/// vectorise without -ffast-math (a single accumulator is a serial chain).
inline double dot(const float* a, const float* b, size_t n) {
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    size_t i = 0;
    for (; i + 4 <= n; i += 4) {
        s0 += double(a[i]) * b[i];
        s1 += double(a[i + 1]) * b[i + 1];
        s2 += double(a[i + 2]) * b[i + 2];
        s3 += double(a[i + 3]) * b[i + 3];
    }
    for (; i < n; ++i) s0 += double(a[i]) * b[i];
    return (s0 + s1) + (s2 + s3);
}

/// Symmetric V-cycle (red-black Gauss-Seidel, reversed colour order after the
/// coarse correction, exact coarsest solve), so it is a valid (symmetric
/// positive definite) CG preconditioner for
/// A x = d .* x + sum over edges e=(i,j) of w_e (x_i - x_j) at both ends.
class WeightedMultigrid {
public:
    /// Builds the hierarchy. d: diagonal (screening) term; ex: weight of the
    /// edge (x,y)-(x+1,y), must be 0 in the last column; ey: weight of the edge
    /// (x,y)-(x,y+1), must be 0 in the last row. All width * height,
    /// non-negative. The fine-level arrays are referenced, not copied: they
    /// must stay unchanged while apply() is used.
    void setup(int width, int height, const float* d, const float* ex, const float* ey);

    /// z ~= A^-1 r by one V-cycle, for `channels` planar images (plane stride
    /// width * height); r and z must not alias. If r_dot_z is given it
    /// receives <r, z> per channel (summed in a fixed order, so deterministic),
    /// computed during the last sweep instead of another pass over memory.
    void apply(const float* r, float* z, int channels, double* r_dot_z = nullptr);

private:
    struct Level {
        int w = 0, h = 0;
        const float *d = nullptr, *ex = nullptr, *ey = nullptr;  // operator (owned storage below for coarse levels)
        Plane d_own, ex_own, ey_own;
        Plane diag, inv_diag;  // full diagonal of A and its inverse
        const float* b = nullptr;           // right-hand side (planar, channels)
        float* x = nullptr;                 // solution (planar, channels)
        Plane b_own, x_own;    // storage for coarse levels
        Plane xs;              // pre-smoothing values (read by the fused post-smoothing)
    };
    void cycle(std::size_t level, int channels);
    void coarsest_solve(Level& L, int channels);
    std::vector<Level> levels_;
    std::vector<double> chol_;  // dense Cholesky factor of the coarsest operator (lower, row-major)
    bool dots_ = false;                // this apply() wants <r, z>
    std::vector<double> dot_parts_;   // per row block and channel
};

}  // namespace gdr::detail
