#include "photorig/daemon/io/lens_json.h"

namespace photorig::daemon {

nlohmann::json PinholeLensJson(const solvers::camera::PinholeLens& lens) {
  return {{"fx_px", lens.fx_px}, {"fy_px", lens.fy_px},           {"cx_px", lens.cx_px},
          {"cy_px", lens.cy_px}, {"distortion", lens.distortion}, {"distance_mm", lens.distance_mm}};
}

solvers::camera::PinholeLens PinholeLensFromJson(const nlohmann::json& lens) {
  solvers::camera::PinholeLens pinhole;
  pinhole.fx_px = lens.at("fx_px").get<double>();
  pinhole.fy_px = lens.at("fy_px").get<double>();
  pinhole.cx_px = lens.at("cx_px").get<double>();
  pinhole.cy_px = lens.at("cy_px").get<double>();
  pinhole.distortion = lens.at("distortion").get<std::array<double, 5>>();
  pinhole.distance_mm = lens.at("distance_mm").get<double>();
  return pinhole;
}

}  // namespace photorig::daemon
