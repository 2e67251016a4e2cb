// V4L2 driver paths that need no capture device: bad nodes give clear errors
// naming the device. Capture itself runs against the kernel's vivid driver in
// a VM (see docs/cameras.md).

#include "photorig/drivers/v4l2/v4l2_camera.h"

#include <gtest/gtest.h>

namespace photorig {
namespace {

TEST(V4l2Camera, MissingAndNonVideoNodesAreUnavailableAndNamed) {
  for (const char* path : {"/dev/video-photorig-missing", "/dev/null"}) {
    drivers::V4l2CameraOptions options;
    options.device = path;
    drivers::V4l2Camera camera("cam", options);
    const Status status = camera.Open();
    EXPECT_EQ(status.code(), StatusCode::kUnavailable) << path;
    EXPECT_NE(status.message().find(path), std::string::npos) << status.message();
    EXPECT_EQ(camera.state(), drivers::Camera::State::kClosed);
  }
}

TEST(V4l2Camera, OptionsAreValidated) {
  drivers::V4l2CameraOptions options;
  std::string why;
  EXPECT_TRUE(options.IsValid(&why));
  options.buffer_count = 1;
  EXPECT_FALSE(options.IsValid(&why));
  EXPECT_NE(why.find("buffer_count"), std::string::npos);
  drivers::V4l2Camera camera("cam", options);
  EXPECT_EQ(camera.Open().code(), StatusCode::kInvalidArgument);
}

TEST(V4l2Camera, DiscoveryListsOnlyCaptureNodes) {
  for (const auto& info : drivers::DiscoverV4l2Cameras()) {
    EXPECT_EQ(info.driver, "v4l2");
    EXPECT_EQ(info.id.rfind("/dev/video", 0), 0u) << info.id;
  }
}

}  // namespace
}  // namespace photorig
