#pragma once
// Keyword options that name an enum value: parsed through the solver's own
// name table, so Python accepts exactly the names the CLI and YAML accept.

#include "photorig/solvers/core/names.h"

#include <pybind11/pybind11.h>

#include <string>

namespace photorig::python {

// The value `name` stands for; ValueError listing the choices otherwise.
template <typename Enum, std::size_t N>
Enum ParseChoice(const solvers::core::NameTable<Enum, N>& table, const std::string& name, const char* option) {
  if (const auto value = solvers::core::ParseName(table, name)) return *value;
  throw pybind11::value_error(std::string(option) + " must be " + solvers::core::NamesInProse(table) + ", not \"" +
                              name + "\"");
}

}  // namespace photorig::python
