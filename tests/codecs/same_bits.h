#pragma once
// The codecs' tests compare images exactly: same type, same size and the same
// bytes in every row (for floats the same bits, NaN payloads and -0 included).
#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <cstring>

namespace photorig::solvers::codecs::test_support {

inline ::testing::AssertionResult SameBits(const cv::Mat& actual, const cv::Mat& expected) {
  if (actual.type() != expected.type() || actual.size() != expected.size())
    return ::testing::AssertionFailure() << "type " << actual.type() << " " << actual.cols << " x " << actual.rows
                                         << ", expected type " << expected.type() << " " << expected.cols << " x "
                                         << expected.rows;
  const std::size_t row_bytes = actual.cols * actual.elemSize();
  for (int r = 0; r < actual.rows; ++r)
    if (std::memcmp(actual.ptr(r), expected.ptr(r), row_bytes) != 0)
      return ::testing::AssertionFailure() << "row " << r << " differs";
  return ::testing::AssertionSuccess();
}

}  // namespace photorig::solvers::codecs::test_support
