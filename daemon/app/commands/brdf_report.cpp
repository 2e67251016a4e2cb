#include "brdf_report.h"

namespace photorig::app {
namespace {

namespace brdf = photorig::solvers::brdf;

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

nlohmann::json FitJson(const brdf::FitSummary& f) {
  return {{"model", brdf::ModelName(f.params.model)},
          {"termination", solvers::TerminationName(f.termination)},
          {"message", f.message},
          {"bic", f.bic},
          {"held_out_rms", f.held_out_rms},
          {"cost", f.cost},
          {"parameters", f.parameters},
          {"diffuse", Vec(f.params.diffuse)},
          {"diffuse_sigma", Vec(f.diffuse_sigma)},
          {"specular", Vec(f.params.specular)},
          {"specular_sigma", Vec(f.specular_sigma)},
          {"shape", f.params.shape},
          {"shape_sigma", f.shape_sigma},
          {"fresnel_f0", f.params.fresnel_f0},
          {"fresnel_f0_sigma", f.fresnel_f0_sigma},
          {"lobe_identifiable", f.lobe_identifiable}};
}

}  // namespace

nlohmann::json SelectionJson(const brdf::SelectionSummary& s) {
  nlohmann::json doc = {{"termination", solvers::TerminationName(s.termination)},
                        {"message", s.message},
                        {"min_theta_h_deg", s.min_theta_h_deg},
                        {"peak_sampled", s.peak_sampled},
                        {"candidates", nlohmann::json::array()}};
  for (const brdf::FitSummary& f : s.candidates) doc["candidates"].push_back(FitJson(f));
  if (s.chosen) doc["chosen"] = brdf::ModelName(*s.chosen);
  return doc;
}

void PrintSelection(std::FILE* text, const brdf::SelectionSummary& s) {
  for (const brdf::FitSummary& f : s.candidates) {
    std::fprintf(text, "  %-13s %-14s BIC %12.1f  held-out rms %8.3f  rho_d %.4f +- %.4f",
                 brdf::ModelName(f.params.model), solvers::TerminationName(f.termination), f.bic, f.held_out_rms,
                 f.params.diffuse[0], f.diffuse_sigma[0]);
    if (f.params.model != brdf::Model::kLambertian)
      std::fprintf(text, "  specular %.4f +- %.4f  shape %.4g +- %.2g", f.params.specular[0], f.specular_sigma[0],
                   f.params.shape, f.shape_sigma);
    if (f.params.model == brdf::Model::kCookTorrance)
      std::fprintf(text, "  F0 %.4f +- %.4f", f.params.fresnel_f0, f.fresnel_f0_sigma);
    if (!f.lobe_identifiable) std::fprintf(text, "  (not identifiable)");
    std::fprintf(text, "\n");
  }
  if (s.chosen) std::fprintf(text, "chosen: %s\n", brdf::ModelName(*s.chosen));
  if (!s.message.empty()) std::fprintf(text, "%s\n", s.message.c_str());
}

}  // namespace photorig::app
