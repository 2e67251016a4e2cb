#include "photorig/solvers/brdf/models.h"

#include <gtest/gtest.h>

#include <cmath>

namespace photorig::solvers::brdf {
namespace {

Eigen::Vector3d Incidence(double theta_deg) {
  const double t = theta_deg * M_PI / 180.0;
  return {std::sin(t), 0.0, std::cos(t)};
}

TEST(Models, NamesParseBack) {
  for (Model m : {Model::kLambertian, Model::kBlinnPhong, Model::kGgx}) EXPECT_EQ(ParseModel(ModelName(m)), m);
  EXPECT_FALSE(ParseModel("phong").has_value());
}

TEST(Models, LambertianAlbedoIsRhoD) {
  ModelParams p;
  p.diffuse = {1.0, 0.5, 0.25};
  for (double theta : {0.0, 45.0, 80.0}) {
    const Eigen::Vector3d albedo = DirectionalAlbedo(p, Incidence(theta), 128);
    EXPECT_NEAR(albedo[0], 1.0, 1e-4);
    EXPECT_NEAR(albedo[1], 0.5, 1e-4);
    EXPECT_NEAR(albedo[2], 0.25, 1e-4);
  }
}

TEST(Models, BlinnPhongLobeReflectsItsWeightAtNormalIncidenceAndNoMoreElsewhere) {
  // Giesen's normalisation makes the albedo at normal incidence exactly k_s.
  for (double exponent : {1.0, 10.0, 100.0}) {
    ModelParams p;
    p.model = Model::kBlinnPhong;
    p.specular = Eigen::Vector3d::Ones();
    p.shape = exponent;
    EXPECT_NEAR(DirectionalAlbedo(p, Incidence(0.0), 320)[0], 1.0, 0.01) << "e = " << exponent;
    for (double theta : {30.0, 60.0, 80.0})
      EXPECT_LE(DirectionalAlbedo(p, Incidence(theta), 320)[0], 1.0) << "e = " << exponent << ", " << theta;
  }
}

TEST(Models, GgxWithFullFresnelReflectsAtMostEverything) {
  // F0 = 1 reflects all light that reaches a facet; single-scattering Smith
  // loses what the facets shadow (much at high roughness), never gains, and
  // loses almost nothing for a smooth surface at normal incidence.
  for (double roughness : {0.2, 0.5, 0.9}) {
    ModelParams p;
    p.model = Model::kGgx;
    p.specular = Eigen::Vector3d::Ones();
    p.shape = roughness;
    for (double theta : {0.0, 30.0, 60.0, 80.0}) {
      const double albedo = DirectionalAlbedo(p, Incidence(theta), 320)[0];
      EXPECT_LE(albedo, 1.0) << "a = " << roughness << ", " << theta;
      if (roughness == 0.2 && theta == 0.0) {
        EXPECT_GT(albedo, 0.9);
      }
    }
  }
}

TEST(Models, ZeroBelowTheHorizonAndReciprocal) {
  ModelParams p;
  p.model = Model::kGgx;
  p.diffuse = {0.3, 0.3, 0.3};
  p.specular = {0.5, 0.5, 0.5};
  p.shape = 0.3;
  const Eigen::Vector3d wi = Eigen::Vector3d(0.3, -0.2, 0.9).normalized(), wo = Eigen::Vector3d(-0.5, 0.1, 0.6).normalized();
  EXPECT_EQ(Evaluate(p, wi, Eigen::Vector3d(0.0, 0.6, -0.8)), Eigen::Vector3d::Zero());
  EXPECT_LT((Evaluate(p, wi, wo) - Evaluate(p, wo, wi)).norm(), 1e-12);
}

}  // namespace
}  // namespace photorig::solvers::brdf
