
#include "photorig/daemon/pipelines/internal/brdf_report.h"

#include "photorig/daemon/pipelines/brdf_measurement.h"
#include "photorig/solvers/core/summary_json.h"

#include <cmath>
#include <string>

namespace photorig::daemon {
namespace {

namespace brdf = photorig::solvers::brdf;

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v[0], v[1], v[2]}; }

nlohmann::json FitJson(const brdf::FitSummary& f) {
  nlohmann::json doc = solvers::core::ToJson(f);
  doc.update({{"model", brdf::ModelName(f.params.model)},
              {"bic", f.bic},
              {"train_rms", f.residuals > 0 ? std::sqrt(f.cost / static_cast<double>(f.residuals)) : NAN},
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
              {"specular_scale", f.params.specular_scale},
              {"specular_scale_sigma", f.specular_scale_sigma},
              {"specular2", Vec(f.params.specular2)},
              {"specular2_sigma", Vec(f.specular2_sigma)},
              {"shape2", f.params.shape2},
              {"shape2_sigma", f.shape2_sigma},
              {"lobe_identifiable", f.lobe_identifiable},
              {"at_bound", f.at_bound},
              {"normal_albedo", Vec(f.normal_albedo)},
              {"implausible", f.implausible},
              {"samples_fitted", f.fitted_samples}});
  return doc;
}

bool ReadVec(const nlohmann::json& j, const char* key, Eigen::Vector3d* v, std::string* error) {
  if (!j.contains(key)) return true;
  const nlohmann::json& a = j[key];
  if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() || !a[2].is_number()) {
    *error = std::string("'") + key + "' must be three numbers";
    return false;
  }
  *v = {a[0].get<double>(), a[1].get<double>(), a[2].get<double>()};
  return true;
}

}  // namespace

nlohmann::json SelectionJson(const brdf::SelectionSummary& s) {
  nlohmann::json doc = solvers::core::ToJson(s);
  doc.update({{"min_theta_h_deg", s.min_theta_h_deg},
              {"peak_sampled", s.peak_sampled},
              {"candidates", nlohmann::json::array()}});
  for (const brdf::FitSummary& f : s.candidates) doc["candidates"].push_back(FitJson(f));
  if (s.chosen) {
    doc["chosen"] = brdf::ModelName(*s.chosen);
    doc["reason"] = s.reason;
  }
  return doc;
}

void AddTableFitJson(const brdf::TableFitSummary& t, nlohmann::json* doc) {
  (*doc)["cells"] = t.cells;
  for (std::size_t c = 0; c < t.all_cells.size(); ++c) {
    nlohmann::json& candidate = (*doc)["candidates"][c];
    candidate["all_cells_log_rms"] = t.all_cells[c].log_rms;
    candidate["all_cells_neutral_rms"] = t.all_cells[c].neutral_rms;
    candidate["reported_over_all_cells"] = t.reported_over_all_cells[c];
  }
  (*doc)["poor_fit"] = t.poor_fit;
  if (!t.warning.empty()) (*doc)["warning"] = t.warning;
  if (t.selection.chosen || t.poor_fit)
    (*doc)["worst_region"] = {{"theta_h_deg", {t.worst_theta_h_deg[0], t.worst_theta_h_deg[1]}},
                              {"theta_d_deg", {t.worst_theta_d_deg[0], t.worst_theta_d_deg[1]}},
                              {"log_rms", t.worst_log_rms}};
}

bool ModelFromJson(const nlohmann::json& doc, const std::string& name, brdf::ModelParams* params, std::string* error) {
  const nlohmann::json* spec = &doc;
  if (doc.contains("candidates")) {  // a fit report: the chosen candidate, or the one named
    const std::string wanted = !name.empty() ? name : doc.value("chosen", std::string());
    if (wanted.empty()) {
      *error = "the report chose no model (name one)";
      return false;
    }
    spec = nullptr;
    for (const nlohmann::json& c : doc["candidates"])
      if (c.value("model", std::string()) == wanted) spec = &c;
    if (!spec) {
      *error = "the report has no '" + wanted + "' fit";
      return false;
    }
  }
  if (!spec->is_object() || !spec->contains("model") || !(*spec)["model"].is_string()) {
    *error = "neither a fit report nor a model (an object with \"model\")";
    return false;
  }
  const std::optional<brdf::Model> model = brdf::ParseModel((*spec)["model"].get<std::string>());
  if (!model) {
    *error = "unknown model '" + (*spec)["model"].get<std::string>() + "'";
    return false;
  }
  brdf::ModelParams p;
  p.model = *model;
  if (!ReadVec(*spec, "diffuse", &p.diffuse, error) || !ReadVec(*spec, "specular", &p.specular, error) ||
      !ReadVec(*spec, "specular2", &p.specular2, error))
    return false;
  for (auto [key, value] : {std::pair{"shape", &p.shape}, {"fresnel_f0", &p.fresnel_f0}, {"shape2", &p.shape2},
                            {"specular_scale", &p.specular_scale}})
    if (spec->contains(key)) {
      if (!(*spec)[key].is_number()) {
        *error = std::string("'") + key + "' must be a number";
        return false;
      }
      *value = (*spec)[key].get<double>();
    }
  const bool lobe = p.model != brdf::Model::kLambertian;
  if (!p.diffuse.allFinite() || (p.diffuse.array() < 0.0).any() || !p.specular.allFinite() ||
      (p.specular.array() < 0.0).any() || !p.specular2.allFinite() || (p.specular2.array() < 0.0).any() ||
      (lobe && !(p.shape > 0.0 && std::isfinite(p.shape))) || !(p.specular_scale >= 0.0 && std::isfinite(p.specular_scale)) ||
      (brdf::HasSecondLobe(p.model) && !(p.shape2 > 0.0 && std::isfinite(p.shape2)))) {
    *error = std::string("the ") + brdf::ModelName(p.model) +
             " parameters must be finite, non-negative, and every lobe's shape positive";
    return false;
  }
  *params = p;
  return true;
}

namespace {

// One value per channel, or one for all when the channels agree (a grey camera).
std::string Channels(const Eigen::Vector3d& value, const Eigen::Vector3d& sigma) {
  char text[160];
  if (value[0] == value[1] && value[1] == value[2])
    std::snprintf(text, sizeof(text), "%.4f +- %.4f", value[0], sigma[0]);
  else
    std::snprintf(text, sizeof(text), "(%.4f, %.4f, %.4f) +- (%.4f, %.4f, %.4f)", value[0], value[1], value[2],
                  sigma[0], sigma[1], sigma[2]);
  return text;
}

}  // namespace

void PrintSelection(std::FILE* text, const brdf::SelectionSummary& s) {
  for (const brdf::FitSummary& f : s.candidates) {
    std::fprintf(text, "  %-15s %-14s BIC %12.1f  rms train %8.3f held-out %8.3f  rho_d %s",
                 brdf::ModelName(f.params.model), solvers::core::TerminationName(f.termination), f.bic,
                 f.residuals > 0 ? std::sqrt(f.cost / static_cast<double>(f.residuals)) : NAN, f.held_out_rms,
                 Channels(f.params.diffuse, f.diffuse_sigma).c_str());
    if (f.params.model != brdf::Model::kLambertian)
      std::fprintf(text, "  specular %s  shape %.4g +- %.2g", Channels(f.params.specular, f.specular_sigma).c_str(),
                   f.params.shape, f.shape_sigma);
    if (f.params.model == brdf::Model::kCookTorrance)
      std::fprintf(text, "  F0 %.4f +- %.4f", f.params.fresnel_f0, f.fresnel_f0_sigma);
    if (f.params.model == brdf::Model::kGgx)
      std::fprintf(text, "  scale %.4f +- %.4f", f.params.specular_scale, f.specular_scale_sigma);
    if (brdf::HasSecondLobe(f.params.model))
      std::fprintf(text, "  specular2 %s  shape2 %.4g +- %.2g", Channels(f.params.specular2, f.specular2_sigma).c_str(),
                   f.params.shape2, f.shape2_sigma);
    if (!f.lobe_identifiable) std::fprintf(text, "  (not identifiable)");
    if (!f.at_bound.empty()) std::fprintf(text, "  (at a bound: %s)", f.at_bound.c_str());
    if (!f.implausible.empty()) std::fprintf(text, "  (implausible: %s)", f.implausible.c_str());
    std::fprintf(text, "\n");
  }
  if (s.chosen) std::fprintf(text, "chosen: %s (%s)\n", brdf::ModelName(*s.chosen), s.reason.c_str());
  if (!s.message.empty()) std::fprintf(text, "%s\n", s.message.c_str());
}

// What the measurement found, in lines of text.
void PrintMeasurement(std::FILE* text, const BrdfMeasurement& m) {
  std::fprintf(text, "%zu samples from %d poses (%d frames, %d bracketed), %zu clipped, %d below the horizon\n",
               m.samples.size(), m.poses, m.pose_frames, m.bracketed_poses, m.clipped.size(), m.below_horizon);
  for (const ClippedPose& c : m.clipped)
    std::fprintf(text, "  clipped: light %+.1f camera %+.1f deg (theta_h %.1f deg) even at %.0f us: no sample\n",
                 c.pose.light_arm_deg, c.pose.camera_arm_deg, c.theta_h_deg, c.shortest_exposure_us);
  if (m.calibration == BrdfMeasurementOptions::Calibration::kReferenceTarget)
    std::fprintf(text, "calibration: reference target of albedo %.3f: %.5g DN per radiance per us +- %.2g %% "
                 "(a scale every f_r shares; the camera states %.5g)\n",
                 m.reference_albedo, m.dn_per_radiance_per_us, 100.0 * m.calibration_relative_sigma,
                 m.camera_dn_per_radiance_per_us);
  else
    std::fprintf(text, "calibration: the camera's stated response, %.5g DN per radiance per us (uncertainty not known)\n",
                 m.dn_per_radiance_per_us);
  if (m.mosaic != "mono") {
    const Eigen::Vector3d& k = m.channel_dn_per_radiance_per_us;
    const Eigen::Vector3d& r = m.channel_calibration_relative_sigma;
    std::fprintf(text, "colour camera (%s): K per channel R %.5g +- %.2g %%, G %.5g +- %.2g %%, B %.5g +- %.2g %% "
                 "from %d/%d/%d sites of the block; f_r per channel\n",
                 m.mosaic.c_str(), k[0], 100.0 * r[0], k[1], 100.0 * r[1], k[2], 100.0 * r[2], m.channel_sites[0],
                 m.channel_sites[1], m.channel_sites[2]);
    if (!m.color_model_path.empty())
      std::fprintf(text, "colour model %s (%s): %s\n", m.color_model_path.c_str(), m.color_model_kind.c_str(),
                   m.color_model_note.c_str());
  }
  std::fprintf(text, "noise: read %.2f DN (from the darks), shot %.4g DN^2 per DN (%s)", m.read_sigma_dn,
               m.shot_dn_per_dn, m.shot_estimated ? "estimated from the repeats" : "from the camera's e_per_dn");
  if (m.repeat_dof > 0)
    std::fprintf(text, "; repeats scatter %.2f x the propagated deviation (%d dof)", m.repeat_sigma_ratio,
                 m.repeat_dof);
  std::fprintf(text, "\n");
}

}  // namespace photorig::daemon
