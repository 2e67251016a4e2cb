#pragma once
// Joint refinement of normals and reflectance.
//
// Photometric stereo's normals come from a model without the materials'
// lobes (or with a per-pixel one fitted to few samples), so inside a glossy
// paint's highlights they carry errors the sharp lobe then magnifies into
// poor fits. The refinement alternates: with the materials, lobes and
// albedos fixed, each fitted pixel's normal moves to minimise its weighted
// residual (Levenberg-Marquardt over two tangent-plane angles, the albedos
// eliminated in closed form at every step); then FitReflectance runs again
// with the new normals, choosing the materials and lobes afresh.

#include "photorig/solvers/core/progress.h"
#include "photorig/solvers/reflectance/fit.h"
#include "photorig/solvers/core/summary.h"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace photorig::solvers::reflectance {

struct NormalRefinementOptions {
  ReflectanceOptions fit;
  // Alternations (normals, then reflectance). Default 2.
  int rounds = 2;
  // A pixel whose normal would move further than this is left where it was
  // and counted in pixels_held: a move that large is a fit escaping into a
  // wrong minimum (a mixed pixel fitted with one paint's lobe), not a
  // correction. Default 10 degrees.
  double max_change_deg = 10.0;
  // The alternation stops when the median move of a round falls below this. Default 0.02 degrees.
  double converged_deg = 0.02;
  // Normals fitted pixel by pixel to every light can be noisier than the
  // ones given (photometric stereo's over many lights), and a lower
  // chi-square does not say which are nearer the truth. So the refined
  // normals are kept only when their fit predicts held-out lights better
  // (per-material RMSE, EvaluateHeldOutLights over `held_out_lights`
  // stratified lights, on the pixels both fits resolved); otherwise the
  // given normals and their fit are returned. false: the refined ones are
  // returned unjudged. Default true, 4 lights.
  bool keep_better = true;
  int held_out_lights = 4;
  core::ProgressCallback progress;  // "normals" per round, then the fit's own stages
  bool IsValid(std::string* why) const;
};

struct NormalRefinementSummary : core::Summary {
  int rounds = 0;                      // alternations made
  int pixels_refined = 0;              // normals moved in the last round
  int pixels_held = 0;                 // left in place in the last round (max_change_deg, or no descent)
  std::vector<double> median_change_deg;  // per round, over the refined pixels
  std::vector<double> p95_change_deg;
  double reduced_chi_square_before = 0.0;  // of the fit with the given normals
  double reduced_chi_square_after = 0.0;   // of the fit returned
  double normals_ms = 0.0;  // in the per-pixel normal steps, over the rounds (the rest: the fits)
  // With keep_better: the per-material held-out RMSE (image units) of the
  // fits on the given and on the refined normals, and which were returned.
  double held_out_rmse_given = 0.0;
  double held_out_rmse_refined = 0.0;
  double judge_ms = 0.0;    // in that comparison
  bool kept_refined = true;
  ReflectanceSummary reflectance;          // the final fit's summary
};

// Fits the reflectance with `normals`, then alternates as above.
// *refined_normals (CV_32FC3) holds the final normals (the given ones where
// no reflectance was fitted, and everywhere when keep_better kept them),
// *maps the fit on them. Fails as
// FitReflectance does when the first fit fails.
NormalRefinementSummary RefineNormalsAndReflectance(const NormalRefinementOptions& options,
                                                    const ReflectanceStack& stack, const cv::Mat& normals,
                                                    const cv::Mat& mask, cv::Mat* refined_normals,
                                                    ReflectanceMaps* maps);
// The same with the first fit (FitReflectance with options.fit on this
// stack, `normals` and `mask`) already made, so it is not made again.
NormalRefinementSummary RefineNormalsAndReflectance(const NormalRefinementOptions& options,
                                                    const ReflectanceStack& stack, const cv::Mat& normals,
                                                    const cv::Mat& mask, const ReflectanceMaps& first,
                                                    const ReflectanceSummary& first_summary, cv::Mat* refined_normals,
                                                    ReflectanceMaps* maps);

}  // namespace photorig::solvers::reflectance
