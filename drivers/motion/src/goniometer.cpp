#include "photorig/drivers/motion/goniometer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

namespace photorig::drivers {
namespace {

std::string Describe(const SeparationConstraint& c, double separation) {
  char text[160];
  std::snprintf(text, sizeof(text), "%s and %s would be %.3f deg apart (minimum %.3f deg)", c.axis_a.c_str(),
                c.axis_b.c_str(), separation, c.min_deg);
  return text;
}

}  // namespace

Goniometer::Goniometer(std::vector<Motion*> axes, std::vector<SeparationConstraint> constraints)
    : axes_(std::move(axes)), constraints_(std::move(constraints)) {}

Motion* Goniometer::axis(const std::string& id) const {
  for (Motion* axis : axes_)
    if (axis->id() == id) return axis;
  return nullptr;
}

Status Goniometer::Validate() const {
  for (const SeparationConstraint& c : constraints_) {
    for (const std::string* name : {&c.axis_a, &c.axis_b})
      if (!axis(*name)) return {StatusCode::kInvalidArgument, "collision constraint names unknown axis '" + *name + "'"};
    if (!(c.min_deg >= 0)) return {StatusCode::kInvalidArgument, "collision constraint min_deg must be >= 0"};
  }
  return Status::Ok();
}

std::string Goniometer::CheckConfiguration(const std::map<std::string, double>& positions) const {
  for (const SeparationConstraint& c : constraints_) {
    const double separation = std::abs(positions.at(c.axis_a) - positions.at(c.axis_b));
    if (separation < c.min_deg) return Describe(c, separation);
  }
  return {};
}

std::string Goniometer::CheckSweep(const std::map<std::string, double>& positions, const std::string& moving,
                                   double from, double to) const {
  const double low = std::min(from, to), high = std::max(from, to);
  for (const SeparationConstraint& c : constraints_) {
    if (c.axis_a != moving && c.axis_b != moving) continue;
    const double other = positions.at(c.axis_a == moving ? c.axis_b : c.axis_a);
    const double start_gap = std::abs(from - other);
    if (start_gap < c.min_deg) {
      // Already too close (e.g. both homed to 0): only moving straight away is allowed.
      const bool crosses = other > low && other < high;
      if (crosses || std::abs(to - other) <= start_gap) return Describe(c, std::min(start_gap, std::abs(to - other)));
      continue;
    }
    // Closest point of the swept interval to the fixed arm.
    const double closest = std::clamp(other, low, high);
    if (std::abs(closest - other) < c.min_deg) return Describe(c, std::abs(closest - other));
  }
  return {};
}

std::string Goniometer::SafeOrder(const std::map<std::string, double>& positions,
                                  const std::map<std::string, double>& targets, std::vector<std::string>* order) const {
  // Few axes: try every order, take the first whose sweeps all keep clear.
  order->clear();
  for (const auto& [id, target] : targets) order->push_back(id);
  std::sort(order->begin(), order->end());
  std::string last_why;
  do {
    std::map<std::string, double> at = positions;
    std::string why;
    for (const std::string& id : *order) {
      why = CheckSweep(at, id, at[id], targets.at(id));
      if (!why.empty()) break;
      at[id] = targets.at(id);
    }
    if (why.empty()) return {};
    last_why = why;
  } while (std::next_permutation(order->begin(), order->end()));
  return last_why;
}

Status Goniometer::RunInOrder(const std::vector<std::string>& order, const std::function<Status(Motion*)>& step) {
  for (const std::string& id : order) {
    Status status = step(axis(id));
    if (!status.ok()) {
      (void)StopAll();
      return status;
    }
  }
  return Status::Ok();
}

Status Goniometer::HomeAll() {
  std::map<std::string, double> homes, positions;
  bool positions_known = true;
  for (Motion* axis : axes_) {
    homes[axis->id()] = axis->limits().home_deg;
    if (axis->state() != Motion::State::kIdle) {
      positions_known = false;  // never homed, or faulted: the drive's count is not trusted
      continue;
    }
    Result<AxisStatus> polled = axis->Poll();
    if (!polled.ok()) return polled.status();
    positions[axis->id()] = polled->position_deg;
  }
  if (std::string why = CheckConfiguration(homes); !why.empty())
    return {StatusCode::kInvalidArgument, "goniometer: refused to home: at their homes " + why};
  std::vector<std::string> order;
  if (positions_known) {
    if (std::string why = SafeOrder(positions, homes, &order); !why.empty())
      return {StatusCode::kInvalidArgument, "goniometer: refused to home: no collision-free order: " + why};
  } else {
    for (Motion* axis : axes_) order.push_back(axis->id());
  }
  return RunInOrder(order, [](Motion* axis) { return axis->Home(); });
}

Status Goniometer::MoveTo(const std::map<std::string, double>& targets, const MotionProfile& profile) {
  std::map<std::string, double> positions;
  for (Motion* axis : axes_) {
    Result<AxisStatus> polled = axis->Poll();
    if (!polled.ok()) return polled.status();
    positions[axis->id()] = polled->position_deg;
  }
  for (const auto& [id, target] : targets) {
    Motion* moving = axis(id);
    if (!moving) return {StatusCode::kInvalidArgument, "goniometer: no axis '" + id + "'"};
    if (!moving->limits().Contains(target))
      return {StatusCode::kInvalidArgument, "goniometer: axis " + id + " target outside its soft limits"};
  }
  std::map<std::string, double> final_positions = positions;
  for (const auto& [id, target] : targets) final_positions[id] = target;
  if (std::string why = CheckConfiguration(final_positions); !why.empty())
    return {StatusCode::kInvalidArgument, "goniometer: refused: " + why};
  std::vector<std::string> order;
  if (std::string why = SafeOrder(positions, targets, &order); !why.empty())
    return {StatusCode::kInvalidArgument, "goniometer: refused: no collision-free order: " + why};
  return RunInOrder(order, [&](Motion* axis) { return axis->MoveTo(targets.at(axis->id()), profile); });
}

Status Goniometer::StopAll() {
  Status first;
  for (Motion* axis : axes_) {
    if (axis->state() == Motion::State::kClosed) continue;
    Status status = axis->Stop();
    if (first.ok() && !status.ok()) first = status;
  }
  return first;
}

Status Goniometer::CloseAll() {
  Status first;
  for (Motion* axis : axes_) {
    Status status = axis->Close();
    if (first.ok() && !status.ok()) first = status;
  }
  return first;
}

}  // namespace photorig::drivers
