// V4L2 driver paths that need no capture device: bad nodes give clear errors
// naming the device. Capture itself runs against the kernel's vivid driver in
// a VM (see docs/cameras.md).

#include "photorig/drivers/v4l2/v4l2_camera.h"
#include "../daemon/test_support.h"

#include <gtest/gtest.h>

#include <filesystem>

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

// A fake /dev: discovery must try only video* nodes, leave out those that do
// not answer VIDIOC_QUERYCAP as a capture device, and list a node it cannot
// open with the reason rather than drop it silently.
TEST(V4l2Camera, DiscoveryListsOnlyCaptureNodes) {
  photorig::testing::TempDir dev;
  dev.Write("video0", "not a device");                                        // QUERYCAP fails: ENOTTY
  std::filesystem::create_symlink("/dev/null", dev.path() / "video1");        // a character device, not V4L2
  std::filesystem::create_symlink(dev.path() / "gone", dev.path() / "video7"); // cannot be opened
  std::filesystem::create_symlink(dev.path() / "gone", dev.path() / "media0"); // not a video node: never tried
  std::filesystem::create_symlink(dev.path() / "gone", dev.path() / "v4l-subdev0");
  const std::vector<drivers::CameraInfo> found = drivers::DiscoverV4l2Cameras(dev.path().string());
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].id, (dev.path() / "video7").string());
  EXPECT_EQ(found[0].driver, "v4l2");
  EXPECT_NE(found[0].error.find("cannot open: No such file or directory"), std::string::npos) << found[0].error;

  EXPECT_TRUE(drivers::DiscoverV4l2Cameras((dev.path() / "absent").string()).empty());
}

// The same on this machine's /dev, where there is something to find.
TEST(V4l2Camera, DiscoveryOnThisMachineNamesEachNode) {
  bool any_video_node = false;
  for (const auto& entry : std::filesystem::directory_iterator("/dev"))
    any_video_node = any_video_node || entry.path().filename().string().rfind("video", 0) == 0;
  if (!any_video_node)
    GTEST_SKIP() << "no /dev/video* here; the fake-/dev test and the vivid VM test (v4l2_vivid_vm) cover discovery";
  for (const auto& info : drivers::DiscoverV4l2Cameras()) {
    EXPECT_EQ(info.driver, "v4l2");
    EXPECT_EQ(info.id.rfind("/dev/video", 0), 0u) << info.id;
    // A listed node either opened and answered as a capture device, or says why it could not be opened.
    EXPECT_TRUE(!info.error.empty() || !info.vendor.empty()) << info.id;
  }
}

}  // namespace
}  // namespace photorig
