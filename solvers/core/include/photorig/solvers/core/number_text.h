#pragma once
// A number as messages and reports write it: printf's %g to a given number
// of significant digits (17 round-trips any double).

#include <cstdio>
#include <string>

namespace photorig::solvers::core {

inline std::string NumberText(double value, int significant_digits) {
  char text[32];
  std::snprintf(text, sizeof text, "%.*g", significant_digits, value);
  return text;
}

}  // namespace photorig::solvers::core
