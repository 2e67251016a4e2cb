// photorig devices [--no-details]: the cameras this machine can see
// (GenICam through Aravis, V4L2 capture nodes) and their key features; a
// camera module left out of the build finds nothing.

#include "../command.h"
#include "../command_output.h"
#include "photorig/config/modules.h"
#include "photorig/drivers/camera.h"
#if PHOTORIG_HAVE_DRIVERS_ARAVIS
#include "photorig/drivers/aravis/aravis_camera.h"
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
#include "photorig/drivers/v4l2/v4l2_camera.h"
#endif

#include <nlohmann/json.hpp>

#include <cstdio>
#include <memory>

namespace photorig::app {
namespace {

struct Options {
  bool no_details = false;
};

std::string Formats(const std::vector<std::string>& formats) {
  std::string out;
  for (const auto& f : formats) out += (out.empty() ? "" : " ") + f;
  return out.empty() ? "-" : out;
}

int Execute(const Options& options) {
  std::vector<drivers::CameraInfo> cameras;
#if PHOTORIG_HAVE_DRIVERS_ARAVIS
  cameras = drivers::DiscoverAravisCameras(!options.no_details);
#endif
#if PHOTORIG_HAVE_DRIVERS_V4L2
  for (auto& camera : drivers::DiscoverV4l2Cameras()) cameras.push_back(std::move(camera));
#endif
  nlohmann::json list = nlohmann::json::array();
  for (const auto& c : cameras)
    list.push_back({{"driver", c.driver}, {"id", c.id}, {"vendor", c.vendor}, {"model", c.model},
                    {"serial", c.serial}, {"address", c.address}, {"sensor_width", c.sensor_width},
                    {"sensor_height", c.sensor_height}, {"pixel_formats", c.pixel_formats},
                    {"exposure_min_us", c.exposure_min_us}, {"exposure_max_us", c.exposure_max_us},
                    {"error", c.error}});
  ResultFields()["cameras"] = list;
  if (cameras.empty()) {
    std::printf("no cameras found (GenICam over GigE Vision/USB3 Vision, V4L2 /dev/video*)\n");
    return 0;
  }
  for (const auto& c : cameras) {
    std::printf("%-7s %s\n", c.driver.c_str(), c.id.c_str());
    std::printf("        model    %s %s%s%s\n", c.vendor.c_str(), c.model.c_str(), c.serial.empty() ? "" : ", serial ",
                c.serial.c_str());
    if (!c.address.empty()) std::printf("        address  %s\n", c.address.c_str());
    if (c.sensor_width > 0) std::printf("        sensor   %d x %d\n", c.sensor_width, c.sensor_height);
    if (!c.pixel_formats.empty()) std::printf("        formats  %s\n", Formats(c.pixel_formats).c_str());
    if (c.exposure_max_us > 0)
      std::printf("        exposure %.0f .. %.0f us\n", c.exposure_min_us, c.exposure_max_us);
    if (!c.error.empty()) std::printf("        error    %s\n", c.error.c_str());
  }
  return 0;
}

CLI::App* Setup(CLI::App& app, Options* options) {
  CLI::App* sub = app.add_subcommand("devices", "list the cameras this machine can see (Aravis, V4L2)");
  sub->add_flag("--no-details", options->no_details, "do not open GenICam cameras to read sensor size and formats");
  return sub;
}

const bool registered = RegisterCommand<Options, Setup, Execute>();

}  // namespace
}  // namespace photorig::app
