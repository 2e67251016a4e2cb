#pragma once
// The DiLiGenT photometric-stereo data set layout:
//   001.png .. NNN.png     16-bit RGB, one per light (names listed in filenames.txt)
//   filenames.txt          one image name per line
//   light_directions.txt   N lines "x y z" (camera frame: x right, y up, z towards the camera)
//   light_intensities.txt  N lines "r g b"
//   mask.png               object mask
//   Normal_gt.mat          ground-truth normals, variable Normal_gt (H x W x 3), if known

#include "photorig/daemon/pipelines/ps_pipeline.h"

#include <string>

namespace photorig::daemon {

// Each image becomes grey as the mean over channels of I_c * mean(L) / L_c,
// with light scale mean(L): colour-balanced, in the sensor's units, albedo
// relative to the intensities' unit; the normals are solved on it. RGB images
// are also kept as a colour stack (input.color: R, G, B frames, each channel
// scaled by its own light intensity L_c, samples at the top code clipped), so
// the albedo comes out per channel, in camera RGB. Images whose three
// channels agree everywhere (grey saved as RGB, e.g. ExportDiligent's) stay grey. Throws ConfigError naming the file and
// line of anything malformed: a missing or unreadable file, images that differ
// in size, bit depth or channels, a name listed twice, a line without exactly
// three finite numbers, a light at or below the horizon, intensities outside
// [1e-6, 1e6], a mask of another size or with no object pixel, and
// ground-truth normals that are not unit vectors over the object.
PhotometricStereoInput LoadDiligent(const std::string& directory);

// Writes a stored run in the same layout: dark-subtracted frames, directions,
// intensities, the ground-truth mask and normals when the run has them.
void ExportDiligent(const std::string& run_directory, const std::string& output_directory);

}  // namespace photorig::daemon
