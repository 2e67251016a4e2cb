#pragma once
// The one check every configuration-error test makes: loading throws a
// ConfigError whose message starts with file:line:column, names the key (when
// given) and says what is wrong.

#include "photorig/config/yaml_node.h"

#include <gtest/gtest.h>

#include <string>

namespace photorig::testing {

template <typename Load>
void ExpectConfigErrorAt(Load load, const std::string& path, int line, int column, const std::string& fragment,
                         const std::string& key = "") {
  try {
    load();
    ADD_FAILURE() << "no error from " << path;
  } catch (const config::ConfigError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.column(), column) << e.what();
    if (!key.empty()) {
      EXPECT_EQ(e.key(), key) << e.what();
    }
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind(path + ":" + std::to_string(line) + ":" + std::to_string(column), 0), 0u)
        << e.what();
  }
}

}  // namespace photorig::testing
