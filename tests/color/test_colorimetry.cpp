#include "photorig/solvers/color/colorimetry.h"
#include "photorig/solvers/color/chart.h"
#include "photorig/solvers/color/model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <string>

namespace photorig::solvers::color {
namespace {

struct SharmaPair {
  double l1, a1, b1, l2, a2, b2, de00;
};

// Sharma, Wu and Dalal (2005), "The CIEDE2000 color-difference formula:
// implementation notes, supplementary test data, and mathematical observations", Table 1.
constexpr SharmaPair kSharmaPairs[34] = {
    {50.0000, 2.6772, -79.7751, 50.0000, 0.0000, -82.7485, 2.0425},
    {50.0000, 3.1571, -77.2803, 50.0000, 0.0000, -82.7485, 2.8615},
    {50.0000, 2.8361, -74.0200, 50.0000, 0.0000, -82.7485, 3.4412},
    {50.0000, -1.3802, -84.2814, 50.0000, 0.0000, -82.7485, 1.0000},
    {50.0000, -1.1848, -84.8006, 50.0000, 0.0000, -82.7485, 1.0000},
    {50.0000, -0.9009, -85.5211, 50.0000, 0.0000, -82.7485, 1.0000},
    {50.0000, 0.0000, 0.0000, 50.0000, -1.0000, 2.0000, 2.3669},
    {50.0000, -1.0000, 2.0000, 50.0000, 0.0000, 0.0000, 2.3669},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0009, 7.1792},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0010, 7.1792},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0011, 7.2195},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0012, 7.2195},
    {50.0000, -0.0010, 2.4900, 50.0000, 0.0009, -2.4900, 4.8045},
    {50.0000, -0.0010, 2.4900, 50.0000, 0.0010, -2.4900, 4.8045},
    {50.0000, -0.0010, 2.4900, 50.0000, 0.0011, -2.4900, 4.7461},
    {50.0000, 2.5000, 0.0000, 50.0000, 0.0000, -2.5000, 4.3065},
    {50.0000, 2.5000, 0.0000, 73.0000, 25.0000, -18.0000, 27.1492},
    {50.0000, 2.5000, 0.0000, 61.0000, -5.0000, 29.0000, 22.8977},
    {50.0000, 2.5000, 0.0000, 56.0000, -27.0000, -3.0000, 31.9030},
    {50.0000, 2.5000, 0.0000, 58.0000, 24.0000, 15.0000, 19.4535},
    {50.0000, 2.5000, 0.0000, 50.0000, 3.1736, 0.5854, 1.0000},
    {50.0000, 2.5000, 0.0000, 50.0000, 3.2972, 0.0000, 1.0000},
    {50.0000, 2.5000, 0.0000, 50.0000, 1.8634, 0.5757, 1.0000},
    {50.0000, 2.5000, 0.0000, 50.0000, 3.2592, 0.3350, 1.0000},
    {60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644},
    {63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630},
    {61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731},
    {35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645},
    {22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373},
    {36.4612, 47.8580, 18.3852, 36.2715, 50.5065, 21.2231, 1.4146},
    {90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441},
    {90.9257, -0.5406, -0.9208, 88.6381, -0.8985, -0.7239, 1.5381},
    {6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377},
    {2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082},
};

TEST(Ciede2000, MatchesSharmaWuDalalTestData) {
  for (int i = 0; i < 34; ++i) {
    const SharmaPair& p = kSharmaPairs[i];
    const Eigen::Vector3d lab1(p.l1, p.a1, p.b1), lab2(p.l2, p.a2, p.b2);
    const double forward = Ciede2000(lab1, lab2);
    // Pair 14 sits exactly on the 180 degree hue discontinuity: rounding decides
    // which side, and both published neighbours (4.8045, 4.7461) are the formula's values.
    const double tolerance = i == 13 ? 0.06 : 1e-4;
    EXPECT_NEAR(forward, p.de00, tolerance) << "pair " << i + 1;
    EXPECT_NEAR(Ciede2000(lab2, lab1), forward, 1e-9) << "pair " << i + 1 << " is not symmetric";
  }
  EXPECT_EQ(Ciede2000({50, 10, -20}, {50, 10, -20}), 0.0);
}

TEST(Colorimetry, PerfectWhiteUnderD65IsTheD65WhitePoint) {
  const Eigen::Vector3d white = WhitePointXyz(Illuminant::kD65, WavelengthGrid(360.0, 780.0, 5.0));
  EXPECT_NEAR(white.x(), 0.95047, 2e-4);
  EXPECT_NEAR(white.y(), 1.0, 1e-12);
  EXPECT_NEAR(white.z(), 1.08883, 2e-4);
  const Eigen::Vector3d d50 = WhitePointXyz(Illuminant::kD50, WavelengthGrid(360.0, 780.0, 5.0));
  EXPECT_NEAR(XyzToXyy(d50).x(), 0.3457, 2e-4);
  EXPECT_NEAR(XyzToXyy(d50).y(), 0.3585, 2e-4);
  const Eigen::Vector3d a = WhitePointXyz(Illuminant::kA, WavelengthGrid(360.0, 780.0, 5.0));
  EXPECT_NEAR(XyzToXyy(a).x(), 0.44757, 3e-4);
  EXPECT_NEAR(XyzToXyy(a).y(), 0.40745, 3e-4);
}

TEST(Colorimetry, ConversionsRoundTrip) {
  const Eigen::Vector3d white(0.95047, 1.0, 1.08883);
  for (const Eigen::Vector3d& xyz : {Eigen::Vector3d(0.2, 0.3, 0.4), Eigen::Vector3d(0.001, 0.002, 0.003),
                                    Eigen::Vector3d(0.9, 0.8, 1.2)}) {
    EXPECT_LT((XyyToXyz(XyzToXyy(xyz)) - xyz).norm(), 1e-12);
    EXPECT_LT((LabToXyz(XyzToLab(xyz, white), white) - xyz).norm(), 1e-12);
  }
  EXPECT_LT((XyzToLab(white, white) - Eigen::Vector3d(100, 0, 0)).norm(), 1e-12);
  // The sRGB primaries' white is D65: (1, 1, 1) linear.
  EXPECT_LT((XyzD65ToLinearSrgb() * (LinearSrgbToXyzD65() * Eigen::Vector3d::Ones()) - Eigen::Vector3d::Ones()).norm(),
            1e-12);
  EXPECT_NEAR(SrgbEncode(0.5), 0.735356983, 1e-8);
  EXPECT_NEAR(SrgbEncode(0.002), 0.02584, 1e-12);
  for (double v : {0.0, 0.001, 0.0031308, 0.2, 1.0}) EXPECT_NEAR(SrgbDecode(SrgbEncode(v)), v, 1e-12);
}

TEST(Colorimetry, BradfordMatchesTheTabulatedD50ToD65Transform) {
  const Eigen::Vector3d d50 = XyyToXyz({0.34570, 0.35850, 1.0});
  const Eigen::Vector3d d65 = XyyToXyz({0.31270, 0.32900, 1.0});
  const std::optional<Eigen::Matrix3d> expected = NamedMatrix("bradford_cat_d50_to_d65");
  ASSERT_TRUE(expected);
  EXPECT_LT((BradfordAdaptation(d50, d65) - *expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((BradfordAdaptation(d50, d65) * d50 - d65).norm(), 1e-12);
}

TEST(Colorimetry, BabelColorSpectraReproduceThePublishedChartLab) {
  // The published Lab is for ICC D50; our D50 white comes from the same spectrum sum.
  const auto grid = WavelengthGrid(380.0, 730.0, 5.0);
  const ChartReference reference = ColorCheckerReference(Illuminant::kD50, grid);
  double sum = 0.0, worst = 0.0;
  for (int p = 0; p < 24; ++p) {
    const Eigen::Vector3d lab = XyzToLab(reference.xyz[static_cast<std::size_t>(p)], reference.white_xyz);
    const double de76 = (lab - ColorChecker24ReferenceLab()[static_cast<std::size_t>(p)]).norm();
    sum += de76;
    worst = std::max(worst, de76);
  }
  // Measured for this data: mean 1.36, max 2.89 (patch 15) against the post-2014 chart.
  EXPECT_LT(sum / 24.0, 1.6);
  EXPECT_LT(worst, 3.5);
  EXPECT_EQ(ColorChecker24Names()[18], "white 9.5 (.05 D)");
}

TEST(Tables, UnknownNamesAreClearErrors) {
  EXPECT_EQ(CameraSensitivity("nikon-9999"), nullptr);
  EXPECT_FALSE(CameraDescription("nikon-9999"));
  EXPECT_FALSE(ChartCaptureSpectraFor("nikon-9999", Illuminant::kD65, WavelengthGrid(400.0, 680.0, 5.0)));
  EXPECT_FALSE(NamedMatrix("no_such_matrix"));
  const SampledSpectra* nikon = CameraSensitivity("nikon-5100");
  ASSERT_NE(nikon, nullptr);
  EXPECT_EQ(nikon->channels.size(), 3u);
  EXPECT_NE(CameraDescription("nikon-5100").value_or("").find("Nikon 5100"), std::string::npos);
  EXPECT_FALSE(ParseIlluminant("F2").has_value());
  EXPECT_EQ(ParseIlluminant("D50"), Illuminant::kD50);
  EXPECT_FALSE(ModelSpec::Parse("cubic").has_value());
  EXPECT_EQ(ParseFitLoss("ciede2000"), FitLoss::kCiede2000);
  EXPECT_EQ(CameraNames().size(), 3u);
}

}  // namespace
}  // namespace photorig::solvers::color
