#pragma once
// The daemon reads recipes and their solve stages through the configuration
// library (rigconfig/, photorig/config/); these are the names it uses unqualified.

#include "photorig/config/recipe.h"
#include "photorig/config/solve_requests.h"
#include "photorig/daemon/rig_config.h"

namespace photorig::daemon {

using config::CaptureLimitError;
using config::CaptureLimits;
using config::CaptureStep;
using config::CaptureStepKindName;
using config::CompileSteps;
using config::GonioPose;
using config::LightCalibrationRequest;
using config::LoadRecipe;
using config::LoadRecipeText;
using config::ParseDerivative;
using config::ParseLightCalibrationRequest;
using config::ParsePhotometricStereoRequest;
using config::PhotometricStereoRequest;
using config::Recipe;
using config::RecipeRigPath;
using config::SvbrdfRequest;
using config::TomographyRequest;
using config::ValidatePhotometricStereoRequest;

}  // namespace photorig::daemon
