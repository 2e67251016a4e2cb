#include "ps_report.h"

#include <cstdio>

namespace photorig::app {

void PrintPhotometricStereoSummary(const nlohmann::json& report) {
  std::printf("photometric stereo (%s): %s, %zu pixels solved, %.1f ms solve\n",
              report["method"].get<std::string>().c_str(), report["termination"].get<std::string>().c_str(),
              report["pixels"]["solved"].get<std::size_t>(), report["timings_ms"]["solve"].get<double>());
  if (!report["message"].get<std::string>().empty())
    std::printf("  solver says: %s\n", report["message"].get<std::string>().c_str());
  if (report.contains("ground_truth")) {
    const nlohmann::json& gt = report["ground_truth"];
    std::printf("  vs ground truth: mean %.3f deg, median %.3f deg, <5 deg %.1f%%, <10 deg %.1f%%, <15 deg %.1f%%, "
                "%zu of %zu pixels unresolved\n",
                gt["mean_angular_error_deg"].get<double>(), gt["median_angular_error_deg"].get<double>(),
                gt["percent_under_5deg"].get<double>(), gt["percent_under_10deg"].get<double>(),
                gt["percent_under_15deg"].get<double>(), gt["pixels_unresolved"].get<std::size_t>(),
                gt["pixels_with_truth"].get<std::size_t>());
  }
}

}  // namespace photorig::app
