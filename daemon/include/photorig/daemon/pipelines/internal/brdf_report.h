#pragma once
// What `photorig solve brdf`, a recipe's brdf stage and `photorig brdf fit`
// report about a measurement and a model selection: the same JSON fields and
// the same lines of text.

#include "photorig/solvers/brdf/fit.h"
#include "photorig/solvers/brdf/table_fit.h"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <string>

namespace photorig::daemon {

struct BrdfMeasurement;

// termination, message, min_theta_h_deg, peak_sampled, candidates (each fit's
// model, parameters with deviations, BIC, training and held-out RMS, flags:
// lobe_identifiable, at_bound, normal_albedo, implausible), chosen and
// the reason for it.
nlohmann::json SelectionJson(const solvers::brdf::SelectionSummary& selection);

// A table fit's findings beside SelectionJson(fit.selection) in `doc`: each
// candidate's errors over all cells, cells, poor_fit, warning, worst_region.
void AddTableFitJson(const solvers::brdf::TableFitSummary& fit, nlohmann::json* doc);

// One line per candidate, then the choice with its reason and the selection's message.
void PrintSelection(std::FILE* out, const solvers::brdf::SelectionSummary& selection);

// A model from a fit report (SelectionJson: the chosen candidate, or the one
// named by `name`) or from a model spec (one candidate's fields: "model",
// "diffuse", "specular", "shape", "fresnel_f0", "specular2", "shape2",
// "specular_scale"; absent ones zero, specular_scale 1). False, saying why in `error`, for anything else.
bool ModelFromJson(const nlohmann::json& doc, const std::string& name, solvers::brdf::ModelParams* params,
                   std::string* error);

// What a gonioreflectometer measurement found (samples, clipped poses, the
// calibration, colour channels, noise), in lines of text.
void PrintMeasurement(std::FILE* out, const BrdfMeasurement& measurement);

}  // namespace photorig::daemon
