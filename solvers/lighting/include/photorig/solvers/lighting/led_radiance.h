#pragma once
// A near LED's output from photographs of a matte plane of known albedo on
// the sample plane, the LED's position known (a rig file, or mirror spheres).
// Pixel p sees the plane's point x, lit by the LED at P along l = (P - x) / |P - x|:
//
//   I - D = g s (rho / pi) (|P|^2 / |P - x|^2) (cos(x) / cos(0))^mu (n . l)
//
// with g the frame's DN per unit radiance (exposure, LED level and sensor),
// s the LED's irradiance at the origin relative to the nominal LED (the rig's
// `intensity`), mu its radiance profile (`cos_exponent`), cos(x) the cosine
// between the LED's axis and the line from the LED to x, and n = +z. Taking
// logarithms leaves a straight line in t = ln(cos(x) / cos(0)):
//
//   y = ln((I - D) / (g (rho / pi) (|P|^2 / |P - x|^2) (n . l))) = ln s + mu t
//
// fitted by weighted least squares (weights from the sensor's noise, by the
// delta method: Var(y) = Var(I - D) / (I - D)^2). The exponent is fitted
// only where the plane spans enough of the LED's cone to tell it: the fit
// with mu free must beat the one with the rig's mu by the Bayesian
// information criterion (Schwarz 1978), the chi-squares scaled by the free
// fit's own residual variance, so a plane whose shading the model does not
// fully follow (vignetting, a non-uniform target) does not buy exponents.

#include "photorig/solvers/camera/camera.h"
#include "photorig/solvers/core/names.h"
#include "photorig/solvers/core/summary.h"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace photorig::solvers::lighting {

// Which radiance profile the fit reports.
enum class ExponentRule {
  kKeep,    // the LED's stated cos_exponent; only the intensity is fitted
  kFit,     // always fitted
  kChoose,  // fitted where the information criterion prefers it, else kept
};
inline constexpr core::NameTable<ExponentRule, 3> kExponentRuleNames = {
    {{ExponentRule::kKeep, "keep"}, {ExponentRule::kFit, "fit"}, {ExponentRule::kChoose, "choose"}}};
inline const char* ExponentRuleName(ExponentRule rule) { return core::NameOf(kExponentRuleNames, rule); }
inline std::optional<ExponentRule> ParseExponentRule(std::string_view name) {
  return core::ParseName(kExponentRuleNames, name);
}

struct LedRadianceOptions {
  double albedo = 0.0;            // the plane's diffuse albedo, (0, 1]; no default: it sets every intensity
  double plane_height_mm = 0.0;   // z of the plane's surface (a target's thickness on the sample plane)
  ExponentRule exponent = ExponentRule::kChoose;
  // Samples below this many noise sigmas are left out: the logarithm of a
  // weak sample is biased (E ln X < ln E X) by about Var / (2 signal^2).
  double min_signal_sigmas = 20.0;
  double saturation_level_dn = std::numeric_limits<double>::infinity();  // raw values at or above: clipped
  // The plane's pixels are those above this fraction of the brightest
  // LEDs' mean image's 95th percentile, eroded by edge_margin_px (a pixel
  // at the target's edge sees part background).
  double plane_threshold_fraction = 0.3;
  int edge_margin_px = 3;
  int stride_px = 2;       // every stride_px-th pixel of every stride_px-th row enters
  int min_samples = 200;   // per LED
  // An LED whose fit leaves residuals beyond the noise of more than this
  // relative RMS is unusable: the plane is not lit as the model says (a
  // shadow, a reflection, the wrong LED position).
  double max_model_error = 0.05;
  bool IsValid(std::string* why) const;
};

// The sensor's noise in DN: Var(I - D) = read_sigma_dn^2 + shot_gain (I - D).
struct SensorNoise {
  double read_sigma_dn = 0.0;
  double shot_gain = 0.0;
};

// One LED's photograph of the plane and what is known of the LED.
struct LedPlaneFrame {
  cv::Mat signal;               // CV_32F, I - D in DN (dark subtracted)
  cv::Mat raw;                  // CV_32F raw DN, for clipping; may be empty
  double dn_per_radiance = 0.0; // g
  Eigen::Vector3d position_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis{0.0, 0.0, -1.0};  // unit, the direction it emits along
  double cos_exponent = 1.0;             // the stated profile
};

struct LedRadianceEstimate {
  bool usable = false;
  double intensity = 0.0, intensity_std = 0.0;        // s
  double cos_exponent = 0.0, cos_exponent_std = 0.0;  // mu (std 0 where kept)
  bool exponent_fitted = false;
  // BIC of the kept exponent minus that of the fitted one (> 0 favours
  // fitting); 0 under kKeep.
  double bic_gain = 0.0;
  // The RMS of y's residuals beyond the noise's share: the model's own
  // relative error per sample (vignetting, an uneven target, a misplaced LED).
  double model_error = 0.0;
  int samples = 0;
  std::string note;  // why unusable, or what was kept
};

struct LedRadianceSummary : core::Summary {
  std::vector<LedRadianceEstimate> leds;
  int usable = 0;
  int plane_pixels = 0;  // in the mask the fits sample
  cv::Mat plane_mask;    // CV_8U, 255 on the plane's pixels used
};

// Fits every frame's LED. kFailure when the plane is not found or an LED is
// unusable (its estimate says why); kInvalidInput for frames of another size
// than the camera, an LED at or below the plane, or no noise model.
LedRadianceSummary CalibrateLedRadiance(const LedRadianceOptions& options, const camera::Camera& camera,
                                        const SensorNoise& noise, const std::vector<LedPlaneFrame>& frames);

}  // namespace photorig::solvers::lighting
