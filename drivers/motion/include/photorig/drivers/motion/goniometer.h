#pragma once
// Several axes of a gonioreflectometer moved under the rig's collision
// constraints: a minimum angular separation between pairs of arms (e.g. the
// light arm and the camera arm sweep the same circle and must never meet).
// A multi-axis move runs one axis at a time, in an order whose every
// intermediate configuration (and every point swept on the way) keeps the
// constraints; if no order does, nothing moves and the error names the pair.
// Any failure stops every axis.

#include "photorig/drivers/motion.h"

#include <functional>
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
  // Homes every axis. Refused, before anything moves, when the axes at their
  // homes (AxisLimits::home_deg) would violate a constraint. When every axis
  // knows its position, homing runs in an order whose sweeps keep clear (as
  // MoveTo); after power-on or a fault the positions are not trusted and the
  // axes home in the order they were given, which the rig's configuration
  // must make safe (list first the arm whose way home is always clear).
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
  // An order of the axes in `targets` whose sweeps from `positions` all keep
  // clear (written to `order`); otherwise the last reason found.
  std::string SafeOrder(const std::map<std::string, double>& positions, const std::map<std::string, double>& targets,
                        std::vector<std::string>* order) const;
  // Runs step on each axis in order; the first failure stops every axis.
  Status RunInOrder(const std::vector<std::string>& order, const std::function<Status(Motion*)>& step);

  std::vector<Motion*> axes_;
  std::vector<SeparationConstraint> constraints_;
};

}  // namespace photorig::drivers
