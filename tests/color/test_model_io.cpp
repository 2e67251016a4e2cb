#include "photorig/solvers/color/model_io.h"

#include <gtest/gtest.h>

namespace photorig::solvers::color {
namespace {

ColorModel SampleModel() {
  ColorModel model;
  model.spec = *ModelSpec::Parse("root-poly-2");
  model.loss = FitLoss::kCiede2000;
  model.illuminant = Illuminant::kD50;
  model.white_xyz = {0.9642, 1.0, 0.8251};
  model.input_scale = 1.0 / 3000.0;
  model.coefficients = Eigen::MatrixXd::Random(6, 3);
  return model;
}

TEST(ColorModelIo, JsonAndYamlRoundTripExactly) {
  const ColorModel model = SampleModel();
  for (const std::string path : {"m.json", "m.yaml"}) {
    const ColorModel back = ParseModel(SerializeModel(model, path), path);
    EXPECT_EQ(back.spec, model.spec) << path;
    EXPECT_EQ(back.loss, model.loss);
    EXPECT_EQ(back.illuminant, model.illuminant);
    EXPECT_EQ(back.input_scale, model.input_scale);
    EXPECT_EQ((back.coefficients - model.coefficients).cwiseAbs().maxCoeff(), 0.0) << path;
    EXPECT_EQ((back.white_xyz - model.white_xyz).cwiseAbs().maxCoeff(), 0.0);
  }
}

TEST(ColorModelIo, MalformedModelsNameTheFileAndKey) {
  nlohmann::json json = ModelToJson(SampleModel());
  json["coefficients"].erase(0);
  try {
    ModelFromJson(json, "cal/model.json");
    FAIL() << "a 5-row root-poly-2 model was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cal/model.json"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("6 x 3"), std::string::npos) << e.what();
  }
  json = ModelToJson(SampleModel());
  json["coefficients"][2][1] = "x";
  EXPECT_THROW(ModelFromJson(json, "m.json"), std::invalid_argument);
  json = ModelToJson(SampleModel());
  json["model"] = "cubic";
  EXPECT_THROW(ModelFromJson(json, "m.json"), std::invalid_argument);
  EXPECT_THROW(ParseModel("{ not json", "m.json"), std::invalid_argument);
  EXPECT_THROW(ParseModel("format: other/1\n", "m.yaml"), std::invalid_argument);
}

TEST(ColorModelIo, AYamlAliasThatHoldsItselfIsRefusedNotFollowed) {
  // Found by fuzz_color_model: the alias made the YAML a cycle, read until the stack ran out.
  try {
    ParseModel("c':\n&a [<<: *a ,~ 0]\nformat: ~steps", "m.yaml");
    FAIL() << "a self-referring alias was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("m.yaml"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nested deeper than"), std::string::npos) << e.what();
  }
  std::string deep = "format: photorig-color-model/1\nextra: ";
  for (int i = 0; i < 40; ++i) deep += "[";
  for (int i = 0; i < 40; ++i) deep += "]";
  EXPECT_THROW(ParseModel(deep + "\n", "deep.yaml"), std::invalid_argument);
}

}  // namespace
}  // namespace photorig::solvers::color
