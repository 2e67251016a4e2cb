#include "photorig/daemon/capture/internal/device_makers.h"

#if PHOTORIG_HAVE_SIM_GIGE
#include "photorig/sim/gige/gige_camera.h"
#endif

namespace photorig::daemon {

#if PHOTORIG_HAVE_DRIVERS_ARAVIS
std::unique_ptr<drivers::Camera> MakeAravisCamera(const DeviceContext& context) {
  const config::CameraConfig& camera = context.rig.camera;
  const config::AravisOptions& options = *camera.aravis;
#if PHOTORIG_HAVE_SIM_GIGE
  if (options.sim_gige)
    return std::make_unique<sim::AravisCameraOnGigeFake>(camera.id, options.camera, context.world, *options.sim_gige);
#endif
  return std::make_unique<drivers::AravisCamera>(camera.id, options.camera);
}
#endif

#if PHOTORIG_HAVE_DRIVERS_V4L2
std::unique_ptr<drivers::Camera> MakeV4l2Camera(const DeviceContext& context) {
  return std::make_unique<drivers::V4l2Camera>(context.rig.camera.id, *context.rig.camera.v4l2);
}
#endif

}  // namespace photorig::daemon
