#pragma once
// CSV text of the reference tables in data/, compiled in (see CMakeLists.txt).

#include <map>
#include <string>
#include <string_view>

namespace photorig::solvers::color::internal {

const std::map<std::string_view, std::string_view>& EmbeddedTables();

// The tables are compiled in, so one that is missing or ragged, or lacks a
// row the library's own code names, is a broken build rather than bad
// input: says what on stderr and aborts (tables.cpp).
[[noreturn]] void BrokenTable(const std::string& what);

}  // namespace photorig::solvers::color::internal
