// Step 5's test of whether any region could be glossy, against the
// labelling of every region that ShareLobes does when it could.
#include "lobe_sharing.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <random>
#include <vector>

namespace photorig::solvers::ps {
namespace {

using internal::AnyRegionCouldBeGlossy;
using internal::GlossyPixel;

constexpr std::uint8_t kSolved = static_cast<std::uint8_t>(PixelFlag::kSolved);
constexpr std::uint8_t kUnsolved = static_cast<std::uint8_t>(PixelFlag::kOutsideMask);

// ShareLobes' own rule over a full labelling: a region is glossy with 16 or
// more of `glossy` in it and at least `fraction` of its area.
bool LabelledAnswer(const cv::Mat& flags, const std::vector<GlossyPixel>& glossy, double fraction) {
  cv::Mat labels, stats, centroids;
  const int regions = cv::connectedComponentsWithStats(flags == kSolved, labels, stats, centroids, 8, CV_32S);
  std::vector<std::size_t> in_region(regions, 0);
  for (const GlossyPixel& g : glossy) ++in_region[labels.ptr<int>()[g.pixel]];
  for (int r = 1; r < regions; ++r)
    if (in_region[r] >= 16 && in_region[r] >= fraction * stats.at<int>(r, cv::CC_STAT_AREA)) return true;
  return false;
}

std::vector<GlossyPixel> GlossyAt(const std::vector<int>& pixels) {
  std::vector<GlossyPixel> glossy;
  for (int p : pixels) glossy.push_back({p, 0.3f, 50.0f});
  return glossy;
}

TEST(AnyRegionCouldBeGlossy, AFewGlossyPixelsOnALargeMatteRegionAreNotEnough) {
  cv::Mat flags(200, 200, CV_8U, cv::Scalar(kSolved));
  std::vector<int> pixels;
  for (int i = 0; i < 98; ++i) pixels.push_back(i * 397 % (200 * 200));
  // 98 glossy pixels of 40,000: 0.25 %, under the 5 % a glossy region needs.
  EXPECT_FALSE(AnyRegionCouldBeGlossy(flags, GlossyAt(pixels), 0.05));
  EXPECT_FALSE(LabelledAnswer(flags, GlossyAt(pixels), 0.05));
  // The same pixels are glossy enough where the rule asks for 0.2 %.
  EXPECT_TRUE(AnyRegionCouldBeGlossy(flags, GlossyAt(pixels), 0.002));
}

TEST(AnyRegionCouldBeGlossy, ASmallIslandCountsOnItsOwnArea) {
  // A 20 x 20 island (400 pixels) apart from a large region: 20 glossy
  // pixels in it are 5 % of it; 19 are not, and neither are 15 at 1 %.
  cv::Mat flags(100, 100, CV_8U, cv::Scalar(kUnsolved));
  flags(cv::Rect(0, 0, 60, 100)).setTo(kSolved);
  flags(cv::Rect(70, 10, 20, 20)).setTo(kSolved);
  std::vector<int> island;
  for (int i = 0; i < 20; ++i) island.push_back((10 + i) * 100 + 70 + i);
  EXPECT_TRUE(AnyRegionCouldBeGlossy(flags, GlossyAt(island), 0.05));
  island.pop_back();
  EXPECT_FALSE(AnyRegionCouldBeGlossy(flags, GlossyAt(island), 0.05));
  island.resize(15);
  EXPECT_FALSE(AnyRegionCouldBeGlossy(flags, GlossyAt(island), 0.01));
}

TEST(AnyRegionCouldBeGlossy, AgreesWithTheLabellingOfEveryRegion) {
  std::mt19937 rng(7);
  int glossy_maps = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int rows = 24 + static_cast<int>(rng() % 60), cols = 24 + static_cast<int>(rng() % 60);
    cv::Mat flags(rows, cols, CV_8U, cv::Scalar(kUnsolved));
    // Discs of solved pixels, some touching (8-connected through corners too).
    const int discs = 1 + static_cast<int>(rng() % 6);
    for (int d = 0; d < discs; ++d)
      cv::circle(flags, {static_cast<int>(rng() % cols), static_cast<int>(rng() % rows)},
                 1 + static_cast<int>(rng() % 14), cv::Scalar(kSolved), cv::FILLED);
    // Glossy pixels clustered around a few centres, some off the solved
    // pixels (ShareLobes counts those nowhere), and some listed twice.
    std::vector<int> pixels;
    const int count = static_cast<int>(rng() % 120);
    const int cx = static_cast<int>(rng() % cols), cy = static_cast<int>(rng() % rows);
    std::normal_distribution<double> spread(0.0, 1.0 + rng() % 10);
    for (int i = 0; i < count; ++i) {
      const int x = std::clamp(cx + static_cast<int>(spread(rng)), 0, cols - 1);
      const int y = std::clamp(cy + static_cast<int>(spread(rng)), 0, rows - 1);
      pixels.push_back(y * cols + x);
      if (rng() % 10 == 0) pixels.push_back(y * cols + x);
    }
    const double fraction = std::array{0.01, 0.05, 0.2, 1.0}[rng() % 4];
    const std::vector<GlossyPixel> glossy = GlossyAt(pixels);
    const bool expected = LabelledAnswer(flags, glossy, fraction);
    glossy_maps += expected;
    ASSERT_EQ(AnyRegionCouldBeGlossy(flags, glossy, fraction), expected) << "trial " << trial;
  }
  // Both answers were exercised.
  EXPECT_GT(glossy_maps, 30);
  EXPECT_LT(glossy_maps, 270);
}

}  // namespace
}  // namespace photorig::solvers::ps
