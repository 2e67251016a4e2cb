#include "photorig/sim/brdf.h"
#include "photorig/sim/scene.h"
#include "photorig/solvers/brdf/merl.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <random>

namespace photorig::sim {
namespace {

using Eigen::Vector3d;

const Vector3d kNormal = Vector3d::UnitZ();

double BlinnPhong(double rho_d, double rho_s, double exponent, const Vector3d& wi, const Vector3d& wo,
                  const Vector3d& n = kNormal) {
  const double nh = n.dot((wi + wo).normalized());
  return rho_d / M_PI + rho_s * (exponent + 2) / (2 * M_PI) * std::pow(std::max(0.0, nh), exponent);
}

// A MERL table of Blinn-Phong (rho_d 0.4, rho_s 0.1, e 30) in R, and twice and
// three times it in G and B, as the simulator reads a measured material.
std::shared_ptr<const solvers::brdf::MeasuredBrdf> BlinnPhongTable() {
  static const auto table = std::make_shared<const solvers::brdf::MerlTable>(
      solvers::brdf::MerlTable::FromFunction([](const solvers::brdf::DirectionPair& d) {
        return std::optional<Vector3d>(Vector3d(1, 2, 3) * BlinnPhong(0.4, 0.1, 30.0, d.wi, d.wo));
      }));
  return std::make_shared<const solvers::brdf::MeasuredBrdf>(
      [](const Vector3d& wi, const Vector3d& wo) { return table->Evaluate(wi, wo); });
}

Vector3d FromAngles(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

// Directional albedo a(w_o) = integral f cos(theta_i) dw_i by cosine-weighted
// sampling (estimate: pi * mean f); also returns the standard error.
double Albedo(const Brdf& brdf, const BrdfParams& p, const Vector3d& wo, double* standard_error) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const int n = 200000;
  double sum = 0.0, sum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double u1 = u(rng), u2 = u(rng);
    const Vector3d wi = FromAngles(std::asin(std::sqrt(u1)), 2 * M_PI * u2);
    const double f = M_PI * brdf.Eval(kNormal, wi, wo, p);
    sum += f;
    sum2 += f * f;
  }
  const double mean = sum / n;
  *standard_error = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
  return mean;
}

struct Case {
  Brdf::Model model;
  BrdfParams params;
};

std::vector<Case> EnergyConservingCases() {
  return {{Brdf::Model::kLambertian, {1.0f, 0.0f, 0.0f, 0.0f}},
          // albedo + 4 rho_s <= 1: the bound Scene::IsValid enforces.
          {Brdf::Model::kBlinnPhong, {0.6f, 0.1f, 20.0f, 0.0f}},
          {Brdf::Model::kBlinnPhong, {0.0f, 0.25f, 200.0f, 0.0f}},
          {Brdf::Model::kGgx, {1.0f, 0.0f, 0.05f, 0.04f}},
          {Brdf::Model::kGgx, {1.0f, 0.0f, 0.5f, 0.04f}},
          {Brdf::Model::kGgx, {0.8f, 0.0f, 0.3f, 0.9f}}};
}

TEST(Brdf, LambertianWhiteFurnaceIntegratesToOne) {
  const auto brdf = MakeBrdf(Brdf::Model::kLambertian);
  double se;
  EXPECT_NEAR(Albedo(*brdf, {1.0f, 0, 0, 0}, FromAngles(0.7, 0.3), &se), 1.0, 1e-12);
}

TEST(Brdf, WhiteFurnaceAlbedoNeverExceedsOne) {
  for (const Case& c : EnergyConservingCases()) {
    const auto brdf = MakeBrdf(c.model);
    for (double theta_o_deg : {0.0, 30.0, 60.0, 80.0, 89.0}) {
      double se;
      const double a = Albedo(*brdf, c.params, FromAngles(theta_o_deg * M_PI / 180, 0.4), &se);
      EXPECT_LE(a, 1.0 + 4 * se) << Brdf::ModelName(c.model) << " at theta_o " << theta_o_deg;
      EXPECT_GT(a, 0.0);
    }
  }
}

// The documented limit: at normal view the (e + 2) / (2 pi) lobe reflects
// close to 4 rho_s for large e, which is why IsValid asks albedo + 4 rho_s <= 1.
TEST(Brdf, BlinnPhongAlbedoApproachesFourRhoSAtNormalView) {
  const auto brdf = MakeBrdf(Brdf::Model::kBlinnPhong);
  double se;
  const double a = Albedo(*brdf, {0.0f, 1.0f, 1000.0f, 0.0f}, kNormal, &se);
  EXPECT_GT(a, 3.8);
  EXPECT_LE(a, 4.0 + 4 * se);
}

// (e + 2) / (2 pi) cos^e(theta) integrates cos-weighted to 1 over the
// hemisphere about the lobe's peak, for any e.
TEST(Brdf, BlinnPhongLobeIsNormalisedAboutItsPeak) {
  for (double e : {1.0, 10.0, 100.0}) {
    // integral_0^{pi/2} (e+2)/(2 pi) cos^e t cos t sin t 2 pi dt by the midpoint rule.
    const int n = 200000;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
      const double t = (i + 0.5) * (M_PI / 2) / n;
      sum += (e + 2) / (2 * M_PI) * std::pow(std::cos(t), e) * std::cos(t) * std::sin(t) * 2 * M_PI;
    }
    EXPECT_NEAR(sum * (M_PI / 2) / n, 1.0, 1e-6) << "e = " << e;
    // And the model's specular lobe is that function of n.h.
    const auto brdf = MakeBrdf(Brdf::Model::kBlinnPhong);
    const Vector3d wi = FromAngles(0.5, 0.0), wo = FromAngles(0.3, M_PI);
    const double nh = kNormal.dot((wi + wo).normalized());
    EXPECT_NEAR(brdf->Eval(kNormal, wi, wo, {0.0f, 1.0f, float(e), 0.0f}), (e + 2) / (2 * M_PI) * std::pow(nh, e), 1e-9);
  }
}

TEST(Brdf, HelmholtzReciprocity) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> theta(0.0, 1.5), phi(0.0, 2 * M_PI);
  for (const Case& c : EnergyConservingCases()) {
    const auto brdf = MakeBrdf(c.model);
    for (int i = 0; i < 1000; ++i) {
      const Vector3d wi = FromAngles(theta(rng), phi(rng)), wo = FromAngles(theta(rng), phi(rng));
      EXPECT_NEAR(brdf->Eval(kNormal, wi, wo, c.params), brdf->Eval(kNormal, wo, wi, c.params), 1e-9);
    }
  }
  // Swapping the directions moves phi_d by pi, which the table folds back;
  // only rounding at a bin edge may differ.
  const auto tabulated = MakeBrdf(Brdf::Model::kTabulated, BlinnPhongTable());
  int mismatches = 0;
  for (int i = 0; i < 1000; ++i) {
    const Vector3d wi = FromAngles(theta(rng), phi(rng)), wo = FromAngles(theta(rng), phi(rng));
    mismatches += std::abs(tabulated->Eval(kNormal, wi, wo, {}) - tabulated->Eval(kNormal, wo, wi, {})) > 1e-6;
  }
  EXPECT_LE(mismatches, 5);
}

TEST(Brdf, MirrorReflectsAboutTheNormal) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 100; ++i) {
    const Vector3d n = Vector3d(u(rng), u(rng), 1.5).normalized();
    const Vector3d wo = Vector3d(u(rng), u(rng), 1.0).normalized();
    const Vector3d r = MirrorDirection(n, wo);
    EXPECT_NEAR((r - (2 * n.dot(wo) * n - wo)).norm(), 0.0, 1e-12);
    EXPECT_NEAR(r.norm(), 1.0, 1e-12);
    EXPECT_NEAR(r.dot(n), wo.dot(n), 1e-12);             // equal angles
    EXPECT_NEAR(r.cross(wo).dot(n), 0.0, 1e-12);          // coplanar with n and w_o
  }
  const auto mirror = MakeBrdf(Brdf::Model::kMirror);
  EXPECT_TRUE(mirror->IsDelta());
  EXPECT_EQ(mirror->Eval(kNormal, kNormal, kNormal, {0, 0.9f, 0, 0}), 0.0);
  EXPECT_FLOAT_EQ(mirror->DeltaReflectance({0, 0.9f, 0, 0}), 0.9f);
}

TEST(Brdf, GgxMatchesTheDocumentedFormula) {
  const auto ggx = MakeBrdf(Brdf::Model::kGgx);
  const Vector3d wi = FromAngles(0.6, 0.2), wo = FromAngles(0.4, 2.5);
  const double a = 0.35, f0 = 0.05, rho = 0.5;
  const Vector3d h = (wi + wo).normalized();
  const double nh = h.z(), ni = wi.z(), no = wo.z();
  const double d = a * a / (M_PI * std::pow(nh * nh * (a * a - 1) + 1, 2));
  auto g1 = [a](double c) { return 2 * c / (c + std::sqrt(a * a + (1 - a * a) * c * c)); };
  auto f = [f0](double c) { return f0 + (1 - f0) * std::pow(1 - c, 5); };
  const double expected = d * g1(ni) * g1(no) * f(wi.dot(h)) / (4 * ni * no) +
                          rho / M_PI * (1 - f(ni)) * (1 - f(no)) / (1 - f0);
  EXPECT_NEAR(ggx->Eval(kNormal, wi, wo, {float(rho), 0, float(a), float(f0)}), expected, 1e-6);
}

TEST(TabulatedBrdf, AMeasuredTableMatchesTheFunctionItWasMadeFromChannelByChannel) {
  const auto table = BlinnPhongTable();
  const auto grey = MakeBrdf(Brdf::Model::kTabulated, table);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> theta(0.0, 1.4), phi(0.0, 2 * M_PI);
  for (int i = 0; i < 500; ++i) {
    const Vector3d wi = FromAngles(theta(rng), phi(rng)), wo = FromAngles(theta(rng), phi(rng));
    const double exact = BlinnPhong(0.4, 0.1, 30.0, wi, wo);
    for (int channel = 0; channel < 3; ++channel)
      EXPECT_NEAR(MakeBrdf(Brdf::Model::kTabulated, table, channel)->Eval(kNormal, wi, wo, {}), (channel + 1) * exact,
                  (channel + 1) * (0.03 * exact + 0.01));
    // A grey camera sees the mean of the channels.
    EXPECT_NEAR(grey->Eval(kNormal, wi, wo, {}), 2 * exact, 2 * (0.03 * exact + 0.01));
  }
  // Below the horizon nothing is reflected; about a tilted normal the table is read in its frame.
  EXPECT_EQ(grey->Eval(kNormal, FromAngles(1.7, 0.0), FromAngles(0.3, 1.0), {}), 0.0);
  const Vector3d tilted = FromAngles(0.4, 0.7);
  for (int i = 0; i < 200; ++i) {
    const Vector3d wi = FromAngles(theta(rng), phi(rng)), wo = FromAngles(theta(rng), phi(rng));
    if (tilted.dot(wi) <= 0.05 || tilted.dot(wo) <= 0.05) continue;
    const double exact = BlinnPhong(0.4, 0.1, 30.0, wi, wo, tilted);
    EXPECT_NEAR(grey->Eval(tilted, wi, wo, {}), 2 * exact, 2 * (0.03 * exact + 0.01));
  }
}

TEST(TabulatedBrdf, IsRefusedWithoutATableOrWithABadChannel) {
  Material material;
  material.model = Brdf::Model::kTabulated;
  std::string why;
  EXPECT_FALSE(material.IsValid(&why));
  EXPECT_NE(why.find("needs a table"), std::string::npos) << why;
  EXPECT_THROW(MakeBrdf(Brdf::Model::kTabulated), std::invalid_argument);
  EXPECT_THROW(MakeBrdf(Brdf::Model::kTabulated, BlinnPhongTable(), 3), std::invalid_argument);
  material.table = BlinnPhongTable();
  EXPECT_TRUE(material.IsValid(&why)) << why;
}

}  // namespace
}  // namespace photorig::sim
