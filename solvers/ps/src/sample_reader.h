#pragma once
// Reading one pixel's samples out of a stack's planes, in double.

#include "kernels/sample_rows.h"
#include "photorig/solvers/ps/lambertian.h"
#include "photorig/solvers/ps/stack.h"

#include <Eigen/Core>

#include <array>
#include <vector>

namespace photorig::solvers::ps::internal {

// The usable samples of one pixel in solver units: b_k = (I_k - D) / s_k with
// variance var_k = Var(I_k - D) / s_k^2.
struct PixelSamples {
  std::vector<double> b, variance;
  std::vector<Eigen::Vector3d> w;
  std::vector<int> light;
  std::vector<double> row_observed, row_inverse_sigma;  // every light's, while gathering
  int size() const { return static_cast<int>(b.size()); }
};


// A stack's samples, pixel by pixel, in solver units: as rows of every
// light's sample (for the lane fitters and FitLit) or as the usable ones only
// (for the per-pixel fits).
class SampleReader {
 public:
  SampleReader(const PhotometricStack& stack, const LambertianOptions& thresholds)
      : stack_(stack), max_condition_(thresholds.max_condition_number) {
    for (int k = 0; k < stack.light_count(); ++k) {
      planes_.push_back(stack.images[k].ptr<float>());
      inverse_scales_.push_back(1.0 / stack.light_scales[k]);
      for (int i = 0; i < 3; ++i) {
        directions_.push_back(stack.light_directions[k][i]);
        direction_axes_[i].push_back(stack.light_directions[k][i]);
      }
    }
    inputs_ = {stack.light_count(), planes_.data(), stack.dark.empty() ? nullptr : stack.dark.ptr<float>(),
               thresholds.shadow_threshold, thresholds.saturation_level, stack.light_scales.data(),
               inverse_scales_.data(), stack.noise.read_sigma * stack.noise.read_sigma, stack.noise.shot_gain,
               directions_.data()};
  }

  int lights() const { return inputs_.lights; }

  // The light directions, one array per axis.
  const double* direction_axis(int axis) const { return direction_axes_[axis].data(); }
  double max_condition() const { return max_condition_; }

  // Every light's sample (see ReadRow); returns chi-square at x.
  double Row(int pixel, const Eigen::Vector3d& x, double* observed, double* inverse_sigma, int* usable) const {
    for (int k = 0; k < lights(); ++k) observed[k] = inputs_.planes[k][pixel];
    double chi2 = 0.0;
    ReadRow(inputs_, inputs_.dark ? inputs_.dark[pixel] : 0.0, x.data(), observed, inverse_sigma, &chi2, usable);
    return chi2;
  }
  // The same from a pixel's raw samples as TrimmedLambertianLanes::CopySamples
  // wrote them: every light's value, then the dark frame's.
  double RowFromSamples(const float* samples, const Eigen::Vector3d& x, double* observed, double* inverse_sigma,
                        int* usable) const {
    for (int k = 0; k < lights(); ++k) observed[k] = samples[k];
    double chi2 = 0.0;
    ReadRow(inputs_, samples[lights()], x.data(), observed, inverse_sigma, &chi2, usable);
    return chi2;
  }

  // The usable samples only.
  void Usable(int pixel, PixelSamples* out) const {
    int usable = 0;
    out->row_observed.resize(lights());
    out->row_inverse_sigma.resize(lights());
    const double* observed = out->row_observed.data();
    const double* inverse_sigma = out->row_inverse_sigma.data();
    Row(pixel, Eigen::Vector3d::Zero(), out->row_observed.data(), out->row_inverse_sigma.data(), &usable);
    const std::vector<Eigen::Vector3d>& light_directions = stack_.light_directions;
    out->b.clear();
    out->variance.clear();
    out->w.clear();
    out->light.clear();
    for (int k = 0; k < lights(); ++k) {
      if (inverse_sigma[k] == 0.0) continue;
      out->b.push_back(observed[k]);
      out->variance.push_back(1.0 / (inverse_sigma[k] * inverse_sigma[k]));
      out->w.push_back(light_directions[k]);
      out->light.push_back(k);
    }
  }

 private:
  const PhotometricStack& stack_;  // must outlive the reader
  std::vector<const float*> planes_;
  std::vector<double> directions_;  // the stack's, 3 per light
  std::array<std::vector<double>, 3> direction_axes_;  // the same, one array per axis
  double max_condition_;
  std::vector<double> inverse_scales_;  // 1 / s_k
  RowInputs inputs_;
};

}  // namespace photorig::solvers::ps::internal
