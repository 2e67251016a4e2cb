#pragma once
// Photometric stereo on a stored run: frames on disk -> solver -> results.
//   results/ps/normals.tiff   float (x, y, z), NaN where unsolved
//   results/ps/normals.png    8-bit view, RGB = (n + 1) / 2
//   results/ps/albedo.tiff    float; albedo.png 8-bit view
//   results/ps/mask.png       255 where a normal was solved
//   results/ps/flags.png      per-pixel PixelFlag code
//   results/ps/angular_error.tiff   degrees, when ground truth exists
//   results/ps/report.json    timings, counts, metrics

#include "photorig/daemon/recipe.h"

#include <nlohmann/json.hpp>

#include <string>

namespace photorig::daemon {

// Throws std::runtime_error naming the file for unreadable or inconsistent
// runs. A solver that cannot produce a result is not an exception: the report
// says so (termination FAILURE and the reason) and is written all the same.
nlohmann::json SolvePhotometricStereoRun(const std::string& run_directory, const PhotometricStereoRequest& request,
                                         const std::string& output_directory);

}  // namespace photorig::daemon
