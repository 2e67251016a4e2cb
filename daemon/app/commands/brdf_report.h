#pragma once
// What `photorig solve brdf` and `photorig brdf fit` report about a model
// selection: the same JSON fields and the same lines of text.

#include "photorig/solvers/brdf/fit.h"

#include <nlohmann/json.hpp>

#include <cstdio>

namespace photorig::app {

// termination, message, min_theta_h_deg, peak_sampled, candidates (each fit's
// model, parameters with deviations, BIC, held-out error, flags) and chosen.
nlohmann::json SelectionJson(const solvers::brdf::SelectionSummary& selection);

// One line per candidate, then the choice and the selection's message.
void PrintSelection(std::FILE* out, const solvers::brdf::SelectionSummary& selection);

}  // namespace photorig::app
