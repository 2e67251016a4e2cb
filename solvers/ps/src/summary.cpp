#include "photorig/solvers/ps/summary.h"

#include <cstdio>

namespace photorig::solvers::ps {

std::string SolverSummary::BriefReport() const {
  char text[512];
  std::snprintf(text, sizeof(text),
                "%s: %s, %zu/%zu pixels solved (%zu by a simpler model, "
                "%zu too few lights, %zu ill-conditioned, %zu rejected), %d lights, cond %.3g, %.1f ms%s%s",
                method.c_str(), solvers::core::TerminationName(termination),
                pixels_solved, pixels_total - pixels_outside_mask, pixels_fell_back, pixels_too_few_lights,
                pixels_ill_conditioned, pixels_rejected_by_model, light_count, condition_number,
                total_ms, message.empty() ? "" : ": ", message.c_str());
  return text;
}

}  // namespace photorig::solvers::ps
