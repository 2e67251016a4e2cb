// ART: Kaczmarz's row action, one ray at a time (reconstruct.h).
#include "iteration.h"

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

namespace photorig::solvers::tomography::internal {
namespace {

// One Kaczmarz sweep: every valid ray once, views in `order`.
void ArtSweep(const Projector& projector, const Eigen::VectorXf& b, const Eigen::VectorXf& mask,
              const std::vector<int>& order, double lambda, bool non_negative, Eigen::VectorXf* x) {
  const std::int64_t per_view = projector.geometry().pixels_per_view();
  std::vector<RayWeight> weights;
  float* xs = x->data();
  for (int view : order)
    for (std::int64_t p = 0; p < per_view; ++p) {
      const std::int64_t ray = view * per_view + p;
      if (mask[ray] == 0.0f) continue;
      projector.Row(ray, &weights);
      double dot = 0.0, norm2 = 0.0;
      for (const RayWeight& w : weights) {
        dot += static_cast<double>(w.weight_mm) * xs[w.voxel];
        norm2 += static_cast<double>(w.weight_mm) * w.weight_mm;
      }
      if (norm2 <= 0.0) continue;
      const auto c = static_cast<float>(lambda * (b[ray] - dot) / norm2);
      for (const RayWeight& w : weights) {
        float& v = xs[w.voxel];
        v += c * w.weight_mm;
        if (non_negative && v < 0.0f) v = 0.0f;
      }
    }
}

class Art final : public Iteration {
 public:
  explicit Art(const IterationInputs& in) : in_(in), order_(static_cast<std::size_t>(in.system.views())) {
    // Views in a shuffled order: consecutive updates from nearby angles are
    // nearly parallel hyperplanes and make slow progress.
    std::iota(order_.begin(), order_.end(), 0);
    std::shuffle(order_.begin(), order_.end(), std::mt19937(27));
  }

  StepResult Step(Eigen::VectorXf* x, Eigen::VectorXf* r) override {
    ArtSweep(*in_.whole, in_.b, in_.mask, order_, in_.lambda, in_.non_negative, x);
    in_.system.Forward(*x, in_.wx);
    MaskedResidual(in_.b, *in_.wx, in_.mask, r);
    return {};
  }

 private:
  IterationInputs in_;
  std::vector<int> order_;
};

}  // namespace

std::unique_ptr<Iteration> MakeArt(const IterationInputs& in) { return std::make_unique<Art>(in); }

}  // namespace photorig::solvers::tomography::internal
