// Demosaicing within regions and the raw sites' vote on the regions' edges:
// against OpenCV's bilinear demosaic where there is one region, and against
// the exact colours of two flat paints where there are two.
#include "photorig/solvers/color/apply.h"
#include "photorig/solvers/color/region_demosaic.h"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <string>

namespace photorig::testing {
namespace {

// Output channel (B = 0, G = 1, R = 2) of an RGGB site.
int RggbChannel(int y, int x) { return (y & 1) == 0 ? ((x & 1) == 0 ? 2 : 1) : ((x & 1) == 0 ? 1 : 0); }

// An RGGB raw of flat paints: pixel (y, x) shows paint label(y, x), whose
// (B, G, R) values are paints[label], scaled by `shade(y, x)`.
template <typename Label, typename Shade>
cv::Mat PaintedRaw(int rows, int cols, const std::vector<std::array<float, 3>>& paints, Label label, Shade shade) {
  cv::Mat raw(rows, cols, CV_16U);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x)
      raw.at<std::uint16_t>(y, x) =
          static_cast<std::uint16_t>(paints[label(y, x)][RggbChannel(y, x)] * shade(y, x) + 0.5f);
  return raw;
}

TEST(RegionDemosaic, OneRegionIsOpenCvsBilinearAwayFromTheBorder) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> value(0, 4095);
  cv::Mat raw(40, 52, CV_16U);
  for (int i = 0; i < static_cast<int>(raw.total()); ++i) raw.ptr<std::uint16_t>()[i] = static_cast<std::uint16_t>(value(rng));
  cv::Mat ours, opencv;
  ASSERT_TRUE(solvers::color::DemosaicWithinRegions(raw, "RGGB", cv::Mat::zeros(raw.size(), CV_8U), &ours).IsSolutionUsable());
  ASSERT_TRUE(solvers::color::Demosaic(raw, "RGGB", &opencv).IsSolutionUsable());
  ASSERT_EQ(ours.type(), CV_32FC3);
  // OpenCV rounds its means to the raw's depth: agreement within half a code.
  double worst = 0.0;
  for (int y = 2; y < raw.rows - 2; ++y)
    for (int x = 2; x < raw.cols - 2; ++x)
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, static_cast<double>(std::abs(ours.at<cv::Vec3f>(y, x)[c] - opencv.at<cv::Vec3w>(y, x)[c])));
  EXPECT_LE(worst, 0.5 + 1e-3);
  // Unlabelled pixels are interpolated the same way.
  cv::Mat unlabelled;
  ASSERT_TRUE(solvers::color::DemosaicWithinRegions(raw, "RGGB", cv::Mat(raw.size(), CV_8U, cv::Scalar(solvers::color::kNoRegion)),
                                           &unlabelled)
                  .IsSolutionUsable());
  EXPECT_EQ(cv::norm(unlabelled, ours, cv::NORM_INF), 0.0);
}

TEST(RegionDemosaic, TwoPaintsKeepTheirOwnColoursAcrossTheEdge) {
  const std::vector<std::array<float, 3>> paints = {{{900.f, 700.f, 300.f}}, {{150.f, 650.f, 1800.f}}};
  const int rows = 24, cols = 30, edge = 13;  // an odd column: the edge cuts between R and G sites
  auto label = [&](int, int x) { return x < edge ? 0 : 1; };
  const cv::Mat raw = PaintedRaw(rows, cols, paints, label, [](int, int) { return 1.0f; });
  cv::Mat regions(rows, cols, CV_8U);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) regions.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(label(y, x));
  cv::Mat within, bilinear;
  ASSERT_TRUE(solvers::color::DemosaicWithinRegions(raw, "RGGB", regions, &within).IsSolutionUsable());
  ASSERT_TRUE(solvers::color::Demosaic(raw, "RGGB", &bilinear).IsSolutionUsable());
  double worst_within = 0.0, worst_bilinear = 0.0;
  for (int y = 0; y < rows; ++y)
    for (int x = edge - 2; x <= edge + 1; ++x)
      for (int c = 0; c < 3; ++c) {
        const float truth = paints[label(y, x)][c];
        worst_within = std::max(worst_within, static_cast<double>(std::abs(within.at<cv::Vec3f>(y, x)[c] - truth)));
        worst_bilinear = std::max(worst_bilinear, static_cast<double>(std::abs(bilinear.at<cv::Vec3w>(y, x)[c] - truth)));
      }
  EXPECT_LE(worst_within, 0.5);  // the paints' values were rounded to codes
  EXPECT_GT(worst_bilinear, 200.0);  // the blend the bilinear demosaic makes
}

// Labels one column off the true edge, as a fit of blended pixels leaves
// them: the sites put the pixels back on their paint, also when a sharp
// highlight crosses the window in some frames and the frames are shaded.
TEST(RegionDemosaic, TheRawSitesMoveAnEdgeLabelledOneColumnOff) {
  const std::vector<std::array<float, 3>> paints = {{{900.f, 700.f, 300.f}}, {{150.f, 500.f, 1800.f}}};
  const int rows = 20, cols = 28, edge = 14;
  auto truth = [&](int, int x) { return x < edge ? 0 : 1; };
  cv::Mat regions(rows, cols, CV_8U);
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) regions.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(x < edge + 1 ? 0 : 1);
  // The off-object corner stays out of the vote.
  regions.at<std::uint8_t>(0, 0) = solvers::color::kNoRegion;
  solvers::color::RegionEdgeVote vote("RGGB", regions, {});
  ASSERT_TRUE(vote.status().IsSolutionUsable()) << vote.status().message;
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 2.0f);
  for (int frame = 0; frame < 12; ++frame) {
    const float slope = 0.02f * static_cast<float>(frame % 4);
    cv::Mat raw = PaintedRaw(rows, cols, paints, truth, [&](int y, int x) {
      const float r2 = static_cast<float>((x - edge) * (x - edge) + (y - 10) * (y - 10));
      // A highlight 6 px wide (sigma), as on the recipe's sphere; one of 3 px
      // centred on the edge outvotes the paint at its centre pixel.
      const float highlight = frame % 5 == 0 ? 3.0f * std::exp(-0.5f * r2 / 36.0f) : 0.0f;
      return 0.6f + slope * static_cast<float>(x) / cols + highlight;
    });
    cv::Mat values;
    raw.convertTo(values, CV_32F);
    for (int i = 0; i < static_cast<int>(values.total()); ++i) values.ptr<float>()[i] += noise(rng);
    ASSERT_TRUE(vote.Add(values).IsSolutionUsable());
  }
  int changed = 0;
  const cv::Mat settled = vote.Regions(&changed);
  EXPECT_EQ(changed, rows);  // the whole mislabelled column
  for (int y = 0; y < rows; ++y)
    for (int x = 1; x < cols; ++x) EXPECT_EQ(settled.at<std::uint8_t>(y, x), truth(y, x)) << y << ", " << x;
  EXPECT_EQ(settled.at<std::uint8_t>(0, 0), solvers::color::kNoRegion);
}

TEST(RegionDemosaic, BadInputIsRefusedNotGuessed) {
  const cv::Mat raw = cv::Mat::zeros(8, 8, CV_16U);
  cv::Mat out;
  EXPECT_FALSE(solvers::color::DemosaicWithinRegions(raw, "RGBG", cv::Mat::zeros(8, 8, CV_8U), &out).IsSolutionUsable());
  EXPECT_FALSE(solvers::color::DemosaicWithinRegions(raw, "RGGB", cv::Mat::zeros(8, 9, CV_8U), &out).IsSolutionUsable());
  EXPECT_FALSE(solvers::color::DemosaicWithinRegions(cv::Mat::zeros(8, 8, CV_16UC3), "RGGB", cv::Mat::zeros(8, 8, CV_8U), &out)
                   .IsSolutionUsable());
  solvers::color::RegionEdgeVote vote("RGGB", cv::Mat::zeros(8, 8, CV_8U), {});
  EXPECT_FALSE(vote.Add(cv::Mat::zeros(8, 9, CV_16U)).IsSolutionUsable());
}

TEST(RegionDemosaic, InvalidVoteOptionsAreRefusedNamingTheField) {
  const cv::Mat labels = cv::Mat::zeros(8, 8, CV_8U);
  const auto refused = [&labels](const solvers::color::RegionEdgeVote::Options& options, const std::string& field) {
    std::string why;
    EXPECT_FALSE(options.IsValid(&why));
    EXPECT_NE(why.find(field), std::string::npos) << why;
    const solvers::color::RegionEdgeVote vote("RGGB", labels, options);
    EXPECT_EQ(vote.status().termination, solvers::core::Termination::kInvalidOptions);
    EXPECT_NE(vote.status().message.find(field), std::string::npos) << vote.status().message;
  };
  refused({.floor_dn = 0.0}, "floor_dn");
  refused({.switch_ratio = 1.5}, "switch_ratio");
  refused({.min_difference = -0.01}, "min_difference");
  EXPECT_TRUE(solvers::color::RegionEdgeVote::Options{}.IsValid(nullptr));
}

}  // namespace
}  // namespace photorig::testing
