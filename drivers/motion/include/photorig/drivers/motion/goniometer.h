#pragma once
// Several axes of a gonioreflectometer moved under the rig's collision
// constraints: a minimum angular separation between pairs of arms (e.g. the
// light arm and the camera arm sweep the same circle and must never meet).
// A multi-axis move runs one axis at a time, in an order whose every
// intermediate configuration (and every point swept on the way) keeps the
// constraints; if no order does, nothing moves and the error names the pair.
// Any failure stops every axis.

#include "photorig/drivers/motion.h"

#include <map>
#include <string>
#include <vector>

namespace photorig::drivers {

struct SeparationConstraint {
  std::string axis_a;
  std::string axis_b;
  double min_deg = 0.0;  // |position(a) - position(b)| must stay >= min_deg
};

class Goniometer {
 public:
  // The axes are borrowed and must outlive the Goniometer.
  Goniometer(std::vector<Motion*> axes, std::vector<SeparationConstraint> constraints);

  Status Validate() const;  // constraint names refer to axes
  Status HomeAll();
  // Targets by axis id; axes not named stay where they are.
  Status MoveTo(const std::map<std::string, double>& targets_deg, const MotionProfile& profile = {});
  Status StopAll();
  Status CloseAll();
  // The first violated constraint for a configuration, or "" if none.
  std::string CheckConfiguration(const std::map<std::string, double>& positions_deg) const;
  Motion* axis(const std::string& id) const;

 private:
  // Empty if moving `moving` from `from` to `to` with the others at `positions` is safe.
  std::string CheckSweep(const std::map<std::string, double>& positions, const std::string& moving, double from,
                         double to) const;

  std::vector<Motion*> axes_;
  std::vector<SeparationConstraint> constraints_;
};

}  // namespace photorig::drivers
