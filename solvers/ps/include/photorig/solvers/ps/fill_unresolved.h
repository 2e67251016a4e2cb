#pragma once
// Normals for the masked pixels a solve left without one (too few usable
// samples, coplanar lights, a fit rejected by its own test), from their
// neighbourhood, so that depth, meshes and relighting have no holes.
//
// The prior is smoothness: each unresolved pixel's normal is the harmonic
// interpolation (discrete Laplace equation, 4-neighbours inside the mask)
// of the solved normals around it, renormalised. A surface is smooth on the
// scale of a few pixels almost everywhere a shadow or a highlight leaves a
// pixel unresolved; at a crease the interpolation rounds it, which is why
// filled pixels are flagged (PixelFlag::kFilled) and their confidence falls
// with their distance from the data.

#include "photorig/solvers/ps/stack.h"
#include "photorig/solvers/core/summary.h"

#include <cstddef>
#include <string>

namespace photorig::solvers::ps {

struct FillOptions {
  // Unresolved pixels farther than this from every solved pixel (steps
  // between 4-neighbours inside the mask) keep their flag and no normal:
  // across a wider hole the prior is a guess, not an interpolation. A
  // highlight's core or a shadowed crevice on a dome's object spans a few
  // pixels; 16 covers holes 32 pixels wide.
  int max_distance_px = 16;
  bool IsValid(std::string* why) const;
};

// kSuccess (also when nothing needed filling), kInvalidOptions, kInvalidInput
// (a map whose planes are missing or of other sizes or types).
struct FillSummary : solvers::core::Summary {
  std::size_t pixels_filled = 0;
  // Unresolved pixels beyond max_distance_px or in a part of the mask with no
  // solved pixel: they keep their flag.
  std::size_t pixels_left = 0;
  int max_distance_px = 0;          // of the filled pixels
  double mean_confidence = 0.0;     // of the filled pixels
  std::string BriefReport() const;
};

// Fills map->normals and map->confidence of the pixels flagged kTooFewLights,
// kIllConditioned or kRejectedByModel within reach, and flags them kFilled.
// Their albedo stays NaN and their model kNone: no reflectance was measured
// there. A filled pixel's confidence is the harmonic interpolation of its
// solved neighbours' confidence divided by its distance in pixels (1 beside a
// solved pixel): the prior's error grows with the distance from the data.
FillSummary FillUnresolvedNormals(const FillOptions& options, NormalMap* map);

}  // namespace photorig::solvers::ps
