#pragma once
// CSV text of the reference tables in data/, compiled in (see CMakeLists.txt).

#include <map>
#include <string_view>

namespace photorig::solvers::color::internal {

const std::map<std::string_view, std::string_view>& EmbeddedTables();

}  // namespace photorig::solvers::color::internal
