#pragma once
// Devices and step lists shared by the sequencer and fault-injection tests.

#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/sim/devices.h"

#include <string>
#include <vector>

namespace photorig::testing {

// A simulated dome that records the LED levels at every close, so a test can
// check that each exit path left the dome dark.
class WatchedDome : public sim::SimLightDome {
 public:
  using SimLightDome::SimLightDome;
  std::vector<std::vector<double>> levels_at_close;

 protected:
  Status DoClose() override {
    levels_at_close.push_back(DoReadBack().value().levels);
    return SimLightDome::DoClose();
  }
};

// One dark frame, then one frame per light, at 1 ms exposure.
inline std::vector<config::CaptureStep> DarkThenEachLight(int lights) {
  std::vector<config::CaptureStep> steps;
  for (int i = -1; i < lights; ++i) {
    config::CaptureStep step;
    step.index = i + 1;
    step.kind = i < 0 ? config::CaptureStep::Kind::kDark : config::CaptureStep::Kind::kLight;
    step.led = i;
    step.label = "step" + std::to_string(i + 1);
    step.pattern = std::make_shared<const drivers::LightPattern>(i < 0 ? drivers::LightPattern::AllOff(lights)
                                                                 : drivers::LightPattern::Single(lights, i, 1.0));
    step.exposure_us = 1000;
    steps.push_back(step);
  }
  return steps;
}

}  // namespace photorig::testing
