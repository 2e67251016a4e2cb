// Fit error against fit time for every model on synthetic gonioreflectometer
// measurements of three materials (matte, rough Blinn-Phong, glossy GGX),
// sweeping the number of samples. Writes a CSV for scripts/charts/brdf.py:
//   photorig-brdf-chart OUT.csv
// error = RMS over 4000 held-out configurations of the cosine-weighted
// difference (f_fit - f_true) cos theta_i, relative to the RMS of f_true cos theta_i.

#include "photorig/solvers/brdf/fit.h"

#include "synthetic_samples.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>

using namespace photorig::solvers::brdf;
namespace synthetic = photorig::solvers::brdf::testing;

namespace {

struct Material {
  const char* name;
  ModelParams truth;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: photorig-brdf-chart OUT.csv\n";
    return 2;
  }
  std::vector<Material> materials(3);
  materials[0] = {"matte", {}};
  materials[0].truth.diffuse = {0.6, 0.4, 0.2};
  materials[1] = {"rough_blinn_phong", {Model::kBlinnPhong, {0.3, 0.2, 0.1}, {0.5, 0.4, 0.3}, 15.0}};
  materials[2] = {"glossy_ggx", {Model::kGgx, {0.25, 0.15, 0.05}, {0.9, 0.7, 0.5}, 0.15}};
  std::ofstream out(argv[1]);
  out << "material,model,samples,fit_ms,relative_error,bic,chosen\n";
  for (const Material& m : materials) {
    synthetic::SyntheticSpec held_spec;
    held_spec.count = 4000;
    held_spec.seed = 999;
    const auto held_out = synthetic::SyntheticSamples(m.truth, held_spec);
    for (int count : {20, 40, 80, 160, 320, 640, 1280, 2560}) {
      constexpr int kRepeats = 5;
      const std::vector<Model> models = SelectionOptions{}.candidates;
      std::vector<std::vector<double>> ms(models.size()), err(models.size()), bic(models.size());
      std::vector<int> chosen(models.size(), 0);
      for (int r = 0; r < kRepeats; ++r) {
        synthetic::SyntheticSpec spec;
        spec.count = count;
        spec.seed = static_cast<std::uint32_t>(1000 * count + r);
        const SelectionSummary s = SelectModel(synthetic::SyntheticSamples(m.truth, spec));
        for (std::size_t i = 0; i < s.candidates.size(); ++i) {
          const FitSummary& f = s.candidates[i];
          if (!f.IsSolutionUsable()) continue;
          ms[i].push_back(f.total_ms);
          err[i].push_back(synthetic::RelativeError(f.params, m.truth, held_out));
          bic[i].push_back(f.bic);
        }
        if (s.IsSolutionUsable()) ++chosen[s.chosen_index];
      }
      auto median = [](std::vector<double> v) {
        if (v.empty()) return std::nan("");
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        return v[v.size() / 2];
      };
      for (std::size_t i = 0; i < models.size(); ++i)
        out << m.name << ',' << ModelName(models[i]) << ',' << count << ',' << median(ms[i]) << ','
            << median(err[i]) << ',' << median(bic[i]) << ',' << chosen[i] << '\n';
      std::cerr << m.name << ' ' << count << " samples done\n";
    }
  }
  return 0;
}
